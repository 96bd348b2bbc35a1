//! The path-density filter (docs/filter.md): a replay of the dump in file
//! order that accepts a sample when the mean distance σ to its k nearest
//! stored samples is below 1 and stores it otherwise, then a final pass
//! that accepts each stored sample whose σ against the others is below 1.
//!
//! [`plain`] is that algorithm as written, one sample at a time: the
//! specification. [`run`] is the same replay made fast and parallel, with
//! the same bytes for any thread count: `schedule` overlaps a parallel
//! search of each batch (`batch`, accelerated by `seeds`) with the
//! in-order decisions (`in_order`), balanced by `deferral`; the σ the
//! report wants of samples accepted while streaming are found after it
//! (`accepted_sigma`).

mod accepted_sigma;
mod batch;
mod deferral;
pub mod evidence;
mod exact;
mod in_order;
pub mod index;
mod kbest;
mod kept;
pub mod plain;
mod schedule;
mod seeds;
pub mod sigma;
mod sigma_map;

pub use exact::{ExactSigma, MAP_SEARCHES, MAP_SHARE, Strata};
pub use index::IndexKind;
pub use kept::Sigmas;
pub use sigma_map::sigma_map;

use index::grid::Grid;
use index::kdtree::KdTree;

use crate::dump::{Header, InvalidCounts, Record};
use crate::joint::JointSpace;
use crate::progress::Progress;

/// The fate of one record, as written by `--decisions` (one byte each).
#[repr(u8)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Decision {
    Invalid = 0,
    AcceptedStreaming = 1,
    AcceptedFinal = 2,
    Rejected = 3,
}

impl Decision {
    /// True for samples splatted into the filtered image.
    pub fn accepted(byte: u8) -> bool {
        byte == Decision::AcceptedStreaming as u8 || byte == Decision::AcceptedFinal as u8
    }
}

/// Which samples the final pass judges a stored sample against
/// (docs/filter.md §2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FinalPass {
    /// The other stored samples, T \ {s}: the paper's step 3.
    #[default]
    Stored,
    /// Every valid sample but s (F6a, [`evidence`]).
    All,
}

crate::names::named!(FinalPass, "final pass", { Stored => "stored", All => "all" });

/// How the replay runs. None of these change a decision.
#[derive(Clone, Debug)]
pub struct ReplayOptions {
    /// Which samples' exact σ to compute (for the σ map).
    pub exact_sigma: ExactSigma,
    /// Samples per parallel batch.
    pub batch: usize,
    /// The share of searches left to the in-order pass (see `deferral::Deferral`);
    /// `None` adapts it to balance the threads.
    pub deferral: Option<f64>,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        ReplayOptions {
            exact_sigma: ExactSigma::None,
            batch: 4096,
            deferral: None,
        }
    }
}

/// The filter's parameters and how to run it, as the replay uses them.
struct Params<'a> {
    k: usize,
    space: &'a JointSpace,
    exact_sigma: ExactSigma,
    batch: usize,
    deferral: Option<f64>,
}

#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct FilterCounts {
    pub records: u64,
    pub valid: u64,
    pub invalid: InvalidCounts,
    pub accepted_streaming: u64,
    pub accepted_final: u64,
    pub rejected: u64,
    /// |T| at the end of the replay.
    pub stored: u64,
}

#[derive(Clone)]
pub struct FilterResult {
    /// One [`Decision`] byte per record, in file order.
    pub decisions: Vec<u8>,
    /// With `exact_sigma`: the σ that decided each record it asks for.
    pub sigma: Option<Sigmas>,
    pub counts: FilterCounts,
    /// The streaming pass, with the search of the σ its accepted samples
    /// are asked for ([`ExactSigma`]), which follows it.
    pub streaming_seconds: f64,
    pub final_seconds: f64,
}

/// Runs the filter (k nearest neighbours in the joint space `space`) over
/// `records` on the current rayon pool.
pub fn run(
    records: &[Record],
    header: &Header,
    space: &JointSpace,
    k: usize,
    index: IndexKind,
    options: &ReplayOptions,
    progress: &dyn Progress,
) -> FilterResult {
    assert!(k >= 1, "k must be at least 1");
    let params = &Params {
        k,
        space,
        exact_sigma: options.exact_sigma,
        batch: options.batch,
        deferral: options.deferral,
    };
    let extent = space.extent(header);
    match (header.animated(), index) {
        (false, IndexKind::Grid) => {
            schedule::replay::<5, _>(records, header, params, || Grid::new(extent), progress)
        }
        (true, IndexKind::Grid) => {
            schedule::replay::<6, _>(records, header, params, || Grid::new(extent), progress)
        }
        (false, IndexKind::Kdtree) => {
            schedule::replay::<5, _>(records, header, params, KdTree::default, progress)
        }
        (true, IndexKind::Kdtree) => {
            schedule::replay::<6, _>(records, header, params, KdTree::default, progress)
        }
    }
}
