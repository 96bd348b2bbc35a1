//! The exact σ of the samples accepted while streaming that a replay is
//! asked for ([`ExactSigma`]), found once streaming is done.
//!
//! A sample accepted while streaming was decided against the T it met:
//! every point stored before it, which are the ids below the number of
//! samples stored before its record. Its σ against those is the same
//! whenever it is searched. Searched after the replay rather than in its
//! in-order pass, the σ map's samples leave that sequential pass deciding
//! only, and the searches of one cell share one gathered block, in any
//! dump order (docs/filter.md §2). A stored sample's σ is its final
//! pass's, which the final pass finds.

use crate::par::prelude::*;

use super::index::NeighbourIndex;
use super::sigma::KBest;
use super::{Decision, ExactSigma, Sigmas};
use crate::dump::Record;
use crate::joint::JointSpace;

/// Searches per round at most: they are sorted by cell, so that the
/// searches of one cell share a gathered block (at 8 a pixel, a round
/// holds about 9 of each 3 × 3-pixel cell of a 512 × 512 film), and their
/// memory (about 100 bytes each while the round is gathered) is bounded by
/// it.
const ROUND: usize = 1 << 18;

/// Records per parallel job of the gathering.
const BLOCK: usize = 1 << 14;

/// One search: a sample and the T it met.
#[derive(Clone, Copy)]
struct Query<const D: usize> {
    /// The index's locality key of `p` << 32 | the number of points stored
    /// before the record.
    key: u64,
    rec: u64,
    p: [f32; D],
}

/// Sets, in `sigma`, the exact σ of every record `exact` wants that
/// `decisions` says was accepted while streaming, against the points of
/// `index` (the final T) stored before it; `stored_at` is the record of
/// every stored point, by id.
#[allow(clippy::too_many_arguments)]
pub(super) fn sigma_of_accepted<const D: usize, I: NeighbourIndex<D>>(
    records: &[Record],
    space: &JointSpace,
    k: usize,
    index: &I,
    stored_at: &[u64],
    decisions: &[u8],
    exact: ExactSigma,
    sigma: &mut Sigmas,
) {
    // A round of records holds about ROUND wanted ones.
    let round = ROUND * exact.share().unwrap_or(1) as usize;
    for start in (0..records.len()).step_by(round) {
        let end = (start + round).min(records.len());
        let gather = |first: usize| {
            let mut queries = Vec::new();
            // Points stored before the block's first record, then counted on.
            let mut before = stored_at.partition_point(|&r| r < first as u64);
            exact.for_each_wanted(first..(first + BLOCK).min(end), |rec| {
                if decisions[rec] != Decision::AcceptedStreaming as u8 {
                    return;
                }
                while stored_at.get(before).is_some_and(|&r| r < rec as u64) {
                    before += 1;
                }
                let p = space.point::<D>(&records[rec]);
                queries.push(Query {
                    key: (index.locality(&p) as u64) << 32 | before as u64,
                    rec: rec as u64,
                    p,
                });
            });
            queries
        };
        let blocks: Vec<Vec<Query<D>>> = (start..end)
            .step_by(BLOCK)
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(gather)
            .collect();
        let mut queries = blocks.concat();
        // Neighbours in a row, so that a worker's gathered block serves
        // the searches of its cell.
        queries.par_sort_unstable_by_key(|q| q.key);
        let found: Vec<f64> = queries
            .par_iter()
            .map_init(
                || (KBest::new(k), I::Scratch::default()),
                |(kb, scratch), q| {
                    let before = q.key as u32;
                    let found = index.search_before(&q.p, before, kb, scratch);
                    found.verdict.sigma().expect("an exact search finds σ")
                },
            )
            .collect();
        for (q, s) in queries.iter().zip(found) {
            sigma.set(q.rec as usize, s);
        }
    }
}
