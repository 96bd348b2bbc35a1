//! F6a in memory proportional to T: the stored samples to judge are the
//! queries. Each query's k nearest among all samples lie within its k-th
//! nearest distance in T (T minus itself is part of every sample but
//! itself), found by one exact search in a grid over T. The dump is then
//! read once, in parallel jobs: every valid sample is offered to the
//! queries whose reach its cell lies in. Each job keeps its own k nearest
//! per query; their union's k smallest, the same whatever the split, give
//! the canonical σ. Nothing is kept per sample of the dump.

use crate::density::index::NeighbourIndex;
use crate::density::index::grid::Grid;
use crate::density::sigma::{Goal, KBest};
use crate::density::{ExactSigma, FilterResult};
use crate::dump::{Header, Order, Record, Validity};
use crate::joint::{JointSpace, dist2};
use crate::par::prelude::*;

use super::query_cells::QueryCells;

/// Parallel jobs of the pass over the dump, per thread: each keeps the k
/// nearest of every query, so their number, not the dump's size, sets the
/// memory of the pass.
const JOBS_PER_THREAD: usize = 2;

/// Samples near a query in the dump's order, on either side of it, that
/// bound its reach ([`PixelMates`]): up to 64 others, most of a 64-spp
/// pixel.
const MATES_PER_SIDE: usize = 32;

/// Below [`super::GRID_SAMPLES`] the streamed pass is taken only where
/// its queries are at most this share of the valid samples (checked before
/// anything is built for it)…
pub(super) const SPARSE_QUERIES: f64 = 1e-3;

/// … and where its distance tests, estimated from every
/// [`ESTIMATE_STRIDE`]-th record, are at most this many a valid sample.
/// The grid computes every sample's joint point instead; on 33 dumps
/// (three renderers, 16–256 spp) the two broke even at about 4–5 tests a
/// sample (docs/BENCHMARKS.md, "F6a's final pass").
pub(super) const SPARSE_TESTS: f64 = 3.0;

/// Records apart in the estimate of the distance tests.
const ESTIMATE_STRIDE: usize = 61;

/// F6a's pass streamed past the stored samples. With `sparse_only`, it
/// gives up, and returns false, where its queries are not sparse
/// ([`SPARSE_QUERIES`], [`SPARSE_TESTS`]) and the grid would be faster;
/// else it judges them and returns true.
pub(super) fn against_all<const D: usize>(
    records: &[Record],
    header: &Header,
    space: &JointSpace,
    k: usize,
    exact: ExactSigma,
    result: &mut FilterResult,
    sparse_only: bool,
) -> bool {
    let extent = space.extent(header);
    let valid = result.counts.valid.max(1) as f64;
    // T: the samples the paper's replay stored, which its final pass judged.
    let stored: Vec<usize> = (0..records.len())
        .filter(|&i| super::stored(result, i))
        .collect();
    let asked_count = stored
        .iter()
        .filter(|&&i| super::needs_search(result, exact, i))
        .count();
    if sparse_only && asked_count as f64 > SPARSE_QUERIES * valid {
        return false;
    }
    let mut t_index = Grid::<D>::new(extent);
    let ids: Vec<u32> = stored
        .iter()
        .map(|&i| t_index.insert(space.point::<D>(&records[i])))
        .collect();
    let asked: Vec<(usize, u32)> = stored
        .iter()
        .zip(&ids)
        .filter(|&(&i, _)| super::needs_search(result, exact, i))
        .map(|(&i, &id)| (i, id))
        .collect();
    // Each query's reach: T minus itself is part of every sample but
    // itself, so its k nearest among all lie within its k-th nearest
    // distance in T. A query that only decides needs no point farther
    // than k: k neighbours closer than that are its k nearest, and fewer
    // reject it (σ ≥ 1). Any k other samples bound the reach too: those
    // of the query's own pixel are most often far nearer than T's, for
    // a query whose σ is wanted (an ordinary sample, most of them); a
    // query that only decides is an isolated sample, no nearer its
    // pixel's samples (docs/BENCHMARKS.md).
    let mates = PixelMates::new(records, header, space);
    let queries: Vec<Query<D>> = asked
        .par_iter()
        .map_init(
            || (KBest::new(k), KBest::new(k), Default::default()),
            |(kb, near, scratch), &(rec, id)| {
                let p = *t_index.point(id);
                t_index.search(&p, Some(id), Goal::Exact, kb, scratch);
                let mut reach2 = kb.worst2();
                if exact.wants(rec) {
                    mates.nearest(rec, &p, near);
                    reach2 = reach2.min(near.worst2());
                } else {
                    reach2 = reach2.min((k * k) as f64);
                }
                Query { rec, p, reach2 }
            },
        )
        .collect();
    drop(t_index);
    // Every valid sample offered to the queries whose reach it may be in,
    // found through a grid over the image (and time) axes where each query
    // is listed in every cell its reach touches.
    let cells = QueryCells::new(header, space, &queries);
    // A valid sample's point and the queries its cell lists, for a sample
    // whose cell may list any.
    let offered = |r: &Record| {
        let listed = r.validity(header) == Validity::Valid && cells.may_list::<D>(space, r);
        listed.then(|| {
            let p = space.point::<D>(r);
            (p, cells.at(&p))
        })
    };
    if sparse_only {
        let tests: usize = (0..records.len())
            .into_par_iter()
            .step_by(ESTIMATE_STRIDE)
            .map(|i| offered(&records[i]).map_or(0, |(_, qs)| qs.len()))
            .sum();
        if (tests * ESTIMATE_STRIDE) as f64 > SPARSE_TESTS * valid {
            return false;
        }
    }
    let jobs = JOBS_PER_THREAD * crate::par::current_num_threads();
    let per_job = records.len().div_ceil(jobs).max(1);
    let partial: Vec<Vec<KBest>> = records
        .par_chunks(per_job)
        .enumerate()
        .map(|(c, chunk)| {
            let mut kbs = vec![KBest::new(k); queries.len()];
            for (j, r) in chunk.iter().enumerate() {
                let Some((p, listed)) = offered(r) else {
                    continue;
                };
                let rec = c * per_job + j;
                for &q in listed {
                    let query = &queries[q as usize];
                    if query.rec == rec {
                        continue;
                    }
                    let d2 = dist2(&p, &query.p);
                    if d2 <= query.reach2 {
                        kbs[q as usize].push(d2, u32::MAX);
                    }
                }
            }
            kbs
        })
        .collect();
    // The k smallest of the union, whatever the split: the same bits for
    // any thread count.
    let verdicts: Vec<f64> = (0..queries.len())
        .map(|q| {
            let mut kb = KBest::new(k);
            for part in &partial {
                for &d2 in part[q].as_slice() {
                    kb.push(d2, u32::MAX);
                }
            }
            kb.sort();
            kb.sigma()
        })
        .collect();
    for (query, &sigma) in queries.iter().zip(&verdicts) {
        super::record(result, exact, query.rec, sigma < 1.0, Some(sigma));
    }
    true
}

/// The records near a record in the dump's declared order: a pass apart
/// in pass-major order (its pixel's samples), adjacent otherwise (its
/// pixel's and, past them, its neighbours'). The order only makes them
/// near; any valid samples bound a reach.
struct PixelMates<'a> {
    records: &'a [Record],
    header: &'a Header,
    space: &'a JointSpace,
    /// Records between two samples of one pixel.
    stride: usize,
    /// Mates looked at on each side of a record.
    reach: usize,
}

impl<'a> PixelMates<'a> {
    fn new(records: &'a [Record], header: &'a Header, space: &'a JointSpace) -> Self {
        let stride = match header.order {
            Order::PassMajor => header.pixels().max(1),
            Order::PixelMajor | Order::Unspecified => 1,
        };
        PixelMates {
            records,
            header,
            space,
            stride,
            reach: (header.spp as usize).clamp(1, MATES_PER_SIDE),
        }
    }

    /// Sets `kb` to the k nearest to `p`, record `rec`'s point, among its
    /// valid mates.
    fn nearest<const D: usize>(&self, rec: usize, p: &[f32; D], kb: &mut KBest) {
        kb.clear();
        let below = (1..=self.reach).filter_map(|j| rec.checked_sub(j * self.stride));
        let above = (1..=self.reach).map(|j| rec + j * self.stride);
        for m in below.chain(above) {
            match self.records.get(m) {
                Some(r) if r.validity(self.header) == Validity::Valid => {
                    kb.push(dist2(&self.space.point::<D>(r), p), u32::MAX)
                }
                _ => {}
            }
        }
    }
}

/// A stored sample to judge against every sample: its record, its point,
/// and the squared distance within which its k nearest lie.
pub(super) struct Query<const D: usize> {
    pub(super) rec: usize,
    pub(super) p: [f32; D],
    pub(super) reach2: f64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::density::{IndexKind, ReplayOptions, run};
    use crate::progress::Silent;
    use crate::synth::SynthParams;

    /// With `sparse_only`, a smooth field with a few fireflies is judged
    /// here; one with many, and one whose few fireflies' reaches cover
    /// most of a small film (below the queries' share, above the tests'),
    /// are left to the grid untouched.
    #[test]
    fn sparse_only_takes_few_queries_and_leaves_many() {
        let cases = [
            (160, 120, 8, 0.00005, true),
            (160, 120, 8, 0.01, false),
            (48, 40, 32, 0.0005, false),
        ];
        for (width, height, spp, fireflies, takes) in cases {
            let p = SynthParams {
                width,
                height,
                spp,
                firefly_fraction: fireflies,
                order: Order::PassMajor,
                seed: 5,
                ..SynthParams::default()
            };
            let (h, recs): (Header, Vec<Record>) = (p.header(), p.records().collect());
            // The shipped joint space and k.
            let (space, k) = (JointSpace::DEFAULT, 8);
            let options = ReplayOptions::default();
            let mut r = run(&recs, &h, &space, k, IndexKind::Grid, &options, &Silent);
            let (decisions, counts) = (r.decisions.clone(), r.counts.clone());
            assert!(
                counts.rejected > 0,
                "fireflies {fireflies}: nothing to judge"
            );
            let mut by_grid = r.clone();
            let none = ExactSigma::None;
            super::super::grid::against_all::<5>(&recs, &h, &space, k, none, &mut by_grid);
            let took = against_all::<5>(&recs, &h, &space, k, none, &mut r, true);
            // Either way, the grid's verdicts.
            if took {
                assert!(r.decisions == by_grid.decisions && r.counts == by_grid.counts);
                assert_ne!(r.decisions, decisions, "F6a changed no verdict");
            }
            let share = counts.rejected as f64 / counts.valid as f64;
            assert_eq!(
                took, takes,
                "{width} × {height}, fireflies {fireflies}: {counts:?}"
            );
            if width == 48 {
                assert!(
                    share <= SPARSE_QUERIES,
                    "queries {share}: the tests must decide"
                );
            }
            if !took {
                assert!(r.decisions == decisions && r.counts == counts);
            }
        }
    }
}
