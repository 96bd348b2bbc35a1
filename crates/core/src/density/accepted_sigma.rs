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

/// Searches per round: they are sorted by cell, so that the searches of
/// one cell share a gathered block. Half a search a pixel of the film
/// (`pixels`) gives each 3 × 3-pixel cell about 4 a round at 8 σ a pixel
/// (the most the report asks for); at 2^18 a round a 1080p film's cells got about one, and its
/// searches took 1.8× as long (docs/BENCHMARKS.md, "A production frame").
/// At least 2^18, and at most 2^21, which bounds their memory (about 100
/// bytes each while the round is gathered).
fn round(pixels: usize) -> usize {
    (pixels / 2).clamp(1 << 18, 1 << 21)
}

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

/// What the searches read: the dump, the replay's decisions and the
/// record of every stored point, by id (`stored_at`).
pub(super) struct Accepted<'a> {
    pub(super) records: &'a [Record],
    pub(super) space: &'a JointSpace,
    pub(super) k: usize,
    pub(super) stored_at: &'a [u64],
    pub(super) decisions: &'a [u8],
    pub(super) exact: ExactSigma,
}

impl Accepted<'_> {
    /// Sets, in `sigma`, the exact σ of every record `exact` wants that
    /// was accepted while streaming, against the points of `index` (the
    /// final T) stored before it, on a film of `pixels` pixels (all frames).
    pub(super) fn find_sigma<const D: usize, I: NeighbourIndex<D>>(
        &self,
        index: &I,
        sigma: &mut Sigmas,
        pixels: usize,
    ) {
        self.find_in_rounds(index, sigma, round(pixels), BLOCK)
    }

    /// [`Accepted::find_sigma`] in rounds of about `round` searches,
    /// gathered in jobs of `block` records.
    fn find_in_rounds<const D: usize, I: NeighbourIndex<D>>(
        &self,
        index: &I,
        sigma: &mut Sigmas,
        round: usize,
        block: usize,
    ) {
        let n = self.records.len();
        // A round of records holds about `round` wanted ones.
        let round = round * self.exact.share().unwrap_or(1) as usize;
        for start in (0..n).step_by(round) {
            let end = (start + round).min(n);
            let blocks: Vec<Vec<Query<D>>> = (start..end)
                .step_by(block)
                .collect::<Vec<_>>()
                .into_par_iter()
                .map(|first| self.gather(index, first..(first + block).min(end)))
                .collect();
            let mut queries = blocks.concat();
            // Neighbours in a row, so that a worker's gathered block serves
            // the searches of its cell.
            queries.par_sort_unstable_by_key(|q| q.key);
            let found: Vec<f64> = queries
                .par_iter()
                .map_init(
                    || (KBest::new(self.k), I::Scratch::default()),
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

    /// The searches of the records of `recs` that are wanted and were
    /// accepted while streaming.
    fn gather<const D: usize, I: NeighbourIndex<D>>(
        &self,
        index: &I,
        recs: std::ops::Range<usize>,
    ) -> Vec<Query<D>> {
        let mut queries = Vec::new();
        // Points stored before the first record, then counted on.
        let mut before = self.stored_at.partition_point(|&r| r < recs.start as u64);
        self.exact.for_each_wanted(recs, |rec| {
            if self.decisions[rec] != Decision::AcceptedStreaming as u8 {
                return;
            }
            while self.stored_at.get(before).is_some_and(|&r| r < rec as u64) {
                before += 1;
            }
            let p = self.space.point::<D>(&self.records[rec]);
            queries.push(Query {
                key: (index.locality(&p) as u64) << 32 | before as u64,
                rec: rec as u64,
                p,
            });
        });
        queries
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Half a search a pixel, within 2^18 and 2^21.
    #[test]
    fn rounds_follow_the_film_within_their_bounds() {
        assert_eq!(round(0), 1 << 18);
        assert_eq!(round(960 * 540), 1 << 18);
        assert_eq!(round(1920 * 1080), 1920 * 1080 / 2);
        assert_eq!(round(1 << 26), 1 << 21);
    }
    use crate::density::index::grid::Grid;
    use crate::density::index::kdtree::KdTree;
    use crate::density::{Strata, plain};
    use crate::dump::Order;
    use crate::synth::SynthParams;

    /// In rounds and gathering jobs of any size, on either index, for every
    /// sample or one in n of each pixel's, the σ found after the replay are
    /// the plain replay's, for exactly the picked samples it accepted
    /// while streaming.
    #[test]
    fn sigma_after_the_replay_is_the_plain_replays_in_any_rounds() {
        for order in [Order::PixelMajor, Order::PassMajor] {
            let synth = SynthParams {
                width: 9,
                height: 7,
                spp: 16,
                order,
                firefly_fraction: 0.05,
                ..SynthParams::default()
            };
            let (h, records): (_, Vec<Record>) = (synth.header(), synth.records().collect());
            let space = JointSpace::DEFAULT.with_white(0.5);
            let k = 4;
            let plain = plain::replay(&records, &h, &space, k);
            let want = plain.sigma.as_ref().unwrap().to_dense(records.len());
            let accepted = |r: usize| plain.decisions[r] == Decision::AcceptedStreaming as u8;
            let stored_at: Vec<u64> = (0..records.len() as u64)
                .filter(|&r| {
                    let d = plain.decisions[r as usize];
                    d == Decision::AcceptedFinal as u8 || d == Decision::Rejected as u8
                })
                .collect();
            let t: Vec<[f32; 5]> = stored_at
                .iter()
                .map(|&r| space.point::<5>(&records[r as usize]))
                .collect();
            let (mut grid, mut tree) = (Grid::<5>::new(space.extent(&h)), KdTree::<5>::default());
            for &p in &t {
                grid.insert(p);
                tree.insert(p);
            }
            let strata = ExactSigma::Strata(Strata::new(&h, 4).unwrap());
            for exact in [ExactSigma::All, strata] {
                let picked = (0..records.len()).filter(|&r| accepted(r) && exact.wants(r));
                let picked: Vec<usize> = picked.collect();
                assert!(picked.len() > 100, "{order}: {} picked", picked.len());
                let run = Accepted {
                    records: &records,
                    space: &space,
                    k,
                    stored_at: &stored_at,
                    decisions: &plain.decisions,
                    exact,
                };
                for (round, block) in [(round(h.pixels()), BLOCK), (5, 3), (1, 1), (17, 64)] {
                    let mut on_grid = Sigmas::new(exact, records.len());
                    run.find_in_rounds(&grid, &mut on_grid, round, block);
                    let mut on_tree = Sigmas::new(exact, records.len());
                    run.find_in_rounds(&tree, &mut on_tree, round, block);
                    for sig in [&mut on_grid, &mut on_tree] {
                        sig.finish();
                        let got: Vec<(usize, f64)> = sig.kept().filter(|p| !p.1.is_nan()).collect();
                        let wanted: Vec<(usize, f64)> =
                            picked.iter().map(|&r| (r, want[r])).collect();
                        assert_eq!(got, wanted, "{order} {exact:?} round {round} block {block}");
                    }
                }
            }
        }
    }
}
