//! The final pass against every sample (docs/filter.md §2, F6a): an
//! alternative to the paper's step 3 for offline use.
//!
//! The paper's replay stores only the samples it cannot accept yet, and its
//! final pass judges each stored sample against the other stored ones.
//! Samples accepted while streaming never count as neighbours again. A small
//! consistent feature — a highlight one pixel wide — is first met by an
//! empty neighbourhood, so its first k samples are stored, its later ones
//! are accepted against those, and in the final pass each stored one sees
//! fewer than k others of its kind and is rejected: the feature loses the
//! samples it began with. Offline, the whole dump is at hand, so here a
//! stored sample is judged against every valid sample but itself. The
//! streaming decisions are the paper's; only the stored samples' final
//! verdicts change, and never from accepted to rejected: T ∪ accepted ⊇ T,
//! and a larger set can only lower σ.
//!
//! Two ways to find a stored sample's k nearest among every sample, with
//! the same results: a grid over every valid sample ([`grid`]: fast, 24
//! bytes a sample), or the stored samples as queries and the dump read
//! past them once ([`streamed`]: memory proportional to T, slower where
//! the queries are many or reach far). [`AllSamples::for_dump`] picks, up to
//! [`GRID_SAMPLES`] valid samples, the streamed pass where its queries are
//! few and near few samples, and the grid elsewhere; streamed beyond.

mod grid;
mod query_cells;
mod streamed;

use super::{Decision, ExactSigma, FilterResult};
use crate::dump::{Header, Record};
use crate::joint::JointSpace;

/// The largest dump (valid samples) whose final pass builds a grid over
/// every sample: about 400 MB of it (docs/BENCHMARKS.md, "The default run").
pub const GRID_SAMPLES: u64 = 1 << 24;

/// How F6a finds a stored sample's k nearest among every sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AllSamples {
    /// A grid over every valid sample.
    Grid,
    /// The stored samples as queries, the dump read past them once.
    Streamed,
    /// Streamed where its queries are sparse (a few distance tests a
    /// sample, [`streamed::SPARSE_TESTS`]), else the grid.
    Sparse,
}

impl AllSamples {
    /// Up to [`GRID_SAMPLES`] valid samples the streamed pass where its
    /// queries are sparse and the grid elsewhere; streamed beyond.
    pub fn for_dump(valid: u64) -> AllSamples {
        if valid <= GRID_SAMPLES {
            AllSamples::Sparse
        } else {
            AllSamples::Streamed
        }
    }
}

/// Re-decides `result`'s stored samples against every valid sample but
/// themselves; σ of those `exact` asks for is updated (`result` keeps σ
/// when `exact` asks for any).
pub fn final_pass_against_all(
    records: &[Record],
    header: &Header,
    space: &JointSpace,
    k: usize,
    exact: ExactSigma,
    result: &mut FilterResult,
) {
    let how = AllSamples::for_dump(result.counts.valid);
    final_pass_against_all_with(records, header, space, k, exact, result, how)
}

/// [`final_pass_against_all`] the way `how` says.
pub fn final_pass_against_all_with(
    records: &[Record],
    header: &Header,
    space: &JointSpace,
    k: usize,
    exact: ExactSigma,
    result: &mut FilterResult,
    how: AllSamples,
) {
    let t = std::time::Instant::now();
    let sparse_only = how == AllSamples::Sparse;
    let streamed = how != AllSamples::Grid
        && if header.animated() {
            streamed::against_all::<6>(records, header, space, k, exact, result, sparse_only)
        } else {
            streamed::against_all::<5>(records, header, space, k, exact, result, sparse_only)
        };
    if !streamed {
        if header.animated() {
            grid::against_all::<6>(records, header, space, k, exact, result)
        } else {
            grid::against_all::<5>(records, header, space, k, exact, result)
        }
    }
    if let Some(s) = result.sigma.as_mut() {
        s.finish();
    }
    result.final_seconds += t.elapsed().as_secs_f64();
}

/// Whether the paper's replay stored record `i` (T): what F6a re-decides.
fn stored(result: &FilterResult, i: usize) -> bool {
    let d = result.decisions[i];
    d == Decision::AcceptedFinal as u8 || d == Decision::Rejected as u8
}

/// Whether stored record `i` needs a search: a sample the paper's final
/// pass accepted is accepted here too (a larger set only lowers σ), so
/// only its wanted σ would need one.
fn needs_search(result: &FilterResult, exact: ExactSigma, i: usize) -> bool {
    result.decisions[i] == Decision::Rejected as u8 || exact.wants(i)
}

/// Records F6a's verdict on stored record `i` (accepted or not, and its σ
/// when `exact` wants it), keeping the counts.
fn record(
    result: &mut FilterResult,
    exact: ExactSigma,
    i: usize,
    accepted: bool,
    sigma: Option<f64>,
) {
    let counts = &mut result.counts;
    if result.decisions[i] == Decision::AcceptedFinal as u8 {
        counts.accepted_final -= 1;
    } else {
        counts.rejected -= 1;
    }
    if let (Some(sig), Some(s), true) = (result.sigma.as_mut(), sigma, exact.wants(i)) {
        sig.set(i, s);
    }
    if accepted {
        result.decisions[i] = Decision::AcceptedFinal as u8;
        counts.accepted_final += 1;
    } else {
        result.decisions[i] = Decision::Rejected as u8;
        counts.rejected += 1;
    }
}
