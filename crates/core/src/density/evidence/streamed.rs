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

pub(super) fn against_all<const D: usize>(
    records: &[Record],
    header: &Header,
    space: &JointSpace,
    k: usize,
    exact: ExactSigma,
    result: &mut FilterResult,
) {
    let extent = space.extent(header);
    // T: the samples the paper's replay stored, which its final pass judged.
    let stored: Vec<usize> = (0..records.len())
        .filter(|&i| super::stored(result, i))
        .collect();
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
    let jobs = JOBS_PER_THREAD * crate::par::current_num_threads();
    let per_job = records.len().div_ceil(jobs).max(1);
    let partial: Vec<Vec<KBest>> = records
        .par_chunks(per_job)
        .enumerate()
        .map(|(c, chunk)| {
            let mut kbs = vec![KBest::new(k); queries.len()];
            for (j, r) in chunk.iter().enumerate() {
                if r.validity(header) != Validity::Valid || !cells.may_list::<D>(space, r) {
                    continue;
                }
                let rec = c * per_job + j;
                let p = space.point::<D>(r);
                for &q in cells.at(&p) {
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
