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

/// Parallel jobs of the pass over the dump, per thread: each keeps the k
/// nearest of every query, so their number, not the dump's size, sets the
/// memory of the pass.
const JOBS_PER_THREAD: usize = 2;

/// Upper limit on the cells of the grid of queries; the side doubles
/// until it fits.
const MAX_CELLS: usize = 1 << 20;

/// Samples near a query in the dump's order, on either side of it, that
/// bound its reach ([`PixelMates`]): up to 64 others, most of a 64-spp
/// pixel.
const MATES_PER_SIDE: usize = 32;

/// Relative slack of a query's reach in [`QueryCells`]: rounding moves a
/// coordinate by about 10⁻¹⁶ of its size.
const REACH_SLACK: f64 = 1e-9;

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
    let cells = QueryCells::new(extent, D - 3, &queries);
    let jobs = JOBS_PER_THREAD * crate::par::current_num_threads();
    let per_job = records.len().div_ceil(jobs).max(1);
    let partial: Vec<Vec<KBest>> = records
        .par_chunks(per_job)
        .enumerate()
        .map(|(c, chunk)| {
            let mut kbs = vec![KBest::new(k); queries.len()];
            for (j, r) in chunk.iter().enumerate() {
                if r.validity(header) != Validity::Valid {
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
struct Query<const D: usize> {
    rec: usize,
    p: [f32; D],
    reach2: f64,
}

/// The queries listed by the cells of a grid that they reach: over the
/// image axes, time for animations, and the first colour axis (lightness),
/// which separates a firefly from the samples around it.
struct QueryCells {
    /// The coordinates gridded: x, y (t), the first colour coordinate.
    coords: Vec<usize>,
    origin: [f64; 4],
    side: [f64; 4],
    dims: [usize; 4],
    lists: Vec<Vec<u32>>,
}

impl QueryCells {
    fn new<const D: usize>(extent: [f64; 3], axes: usize, queries: &[Query<D>]) -> QueryCells {
        let mut coords: Vec<usize> = (0..axes).collect();
        coords.push(D - 3);
        let n = coords.len();
        let (mut origin, mut end) = ([0.0f64; 4], [0.0f64; 4]);
        end[..axes].copy_from_slice(&extent[..axes]);
        // The colour axis spans the queries' reach (a sample beyond it is
        // clamped to the last cell, still beyond every reach).
        let (lo, hi) = queries
            .iter()
            .map(|q| (q.p[D - 3] as f64, q.reach2.sqrt()))
            .filter(|(_, r)| r.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (v, r)| {
                (lo.min(v - r), hi.max(v + r))
            });
        (origin[axes], end[axes]) = if lo < hi { (lo, hi) } else { (0.0, 1.0) };
        let mut side = [1.0f64; 4];
        let dims_for = |side: &[f64; 4]| {
            let mut d = [1usize; 4];
            for a in 0..n {
                d[a] = ((end[a] - origin[a]) / side[a]).ceil().clamp(1.0, 1e15) as usize;
            }
            d
        };
        let mut dims = dims_for(&side);
        while dims.iter().fold(1usize, |m, &x| m.saturating_mul(x)) > MAX_CELLS {
            let a = (0..n).max_by_key(|&a| dims[a]).expect("an axis");
            side[a] *= 2.0;
            dims = dims_for(&side);
        }
        let mut cells = QueryCells {
            coords,
            origin,
            side,
            dims,
            lists: vec![Vec::new(); dims.iter().product()],
        };
        for (q, query) in queries.iter().enumerate() {
            // The cells the reach covers, its ends widened by a slack far
            // above the rounding of the square root, of v ± reach and of
            // `dist2`: a point with dist2 ≤ reach2 lies within the ends on
            // every axis, and `index` never decreases, so its cell is
            // listed.
            let reach = query.reach2.sqrt();
            let (mut lo, mut hi) = ([0usize; 4], [0usize; 4]);
            for (a, &j) in cells.coords.iter().enumerate() {
                let v = query.p[j] as f64;
                let slack = REACH_SLACK * (1.0 + v.abs() + reach);
                lo[a] = cells.index(v - reach - slack, a);
                hi[a] = cells.index(v + reach + slack, a);
            }
            for w in lo[3]..=hi[3] {
                for z in lo[2]..=hi[2] {
                    for y in lo[1]..=hi[1] {
                        for x in lo[0]..=hi[0] {
                            let c = ((w * dims[2] + z) * dims[1] + y) * dims[0] + x;
                            cells.lists[c].push(q as u32);
                        }
                    }
                }
            }
        }
        cells
    }

    /// The cell of coordinate `v` along gridded axis `a`, clamped to the
    /// grid.
    fn index(&self, v: f64, a: usize) -> usize {
        let c = ((v - self.origin[a]) / self.side[a]).floor();
        if c.is_nan() || c <= 0.0 {
            0
        } else {
            (c as usize).min(self.dims[a] - 1)
        }
    }

    /// The queries listed in the cell of `p`.
    fn at<const D: usize>(&self, p: &[f32; D]) -> &[u32] {
        let mut c = [0usize; 4];
        for (a, &j) in self.coords.iter().enumerate() {
            c[a] = self.index(p[j] as f64, a);
        }
        let d = &self.dims;
        &self.lists[((c[3] * d[2] + c[2]) * d[1] + c[1]) * d[0] + c[0]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every point within a query's reach (by the canonical distance) is
    /// offered to it: points on the reach's surface along each axis, on
    /// cell borders and at random inside, for reaches from none to
    /// unbounded, smaller and larger than a cell.
    #[test]
    fn a_point_within_the_reach_finds_its_query_in_its_cell() {
        let mut state = 7u64;
        let mut uniform = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let extent = [40.0, 30.0, 1.0];
        let queries: Vec<Query<5>> = (0..300)
            .map(|i| {
                let p = [
                    (uniform() * 40.0) as f32,
                    (uniform() * 30.0) as f32,
                    (uniform() * 4.0 - 1.0) as f32,
                    (uniform() - 0.5) as f32,
                    (uniform() - 0.5) as f32,
                ];
                let reach = match i % 6 {
                    4 => 0.0,
                    5 => f64::INFINITY,
                    j => [0.01, 0.5, 1.0, 2.7][j] * (0.5 + uniform()),
                };
                Query {
                    rec: i,
                    p,
                    reach2: reach * reach,
                }
            })
            .collect();
        let cells = QueryCells::new(extent, 2, &queries);
        let mut checked = 0;
        for (q, query) in queries.iter().enumerate() {
            let reach = query.reach2.sqrt();
            let mut points = Vec::new();
            for axis in 0..5 {
                for sign in [-1.0, 1.0] {
                    // On the surface, and just inside it in f32.
                    for shrink in [1.0, 1.0 - 1e-6] {
                        let mut p = query.p;
                        p[axis] = (query.p[axis] as f64 + sign * reach * shrink) as f32;
                        points.push(p);
                    }
                }
            }
            for _ in 0..50 {
                let mut p = query.p;
                for c in p.iter_mut() {
                    let r = reach.min(50.0);
                    *c = (*c as f64 + (uniform() * 2.0 - 1.0) * r / 2.2) as f32;
                }
                points.push(p);
                // The cell borders nearest it (the side is 1 here).
                let mut b = query.p;
                b[0] = b[0].round();
                b[1] = b[1].floor();
                points.push(b);
            }
            for p in points {
                if dist2(&p, &query.p) <= query.reach2 {
                    checked += 1;
                    assert!(
                        cells.at(&p).contains(&(q as u32)),
                        "query {q} at {:?}, reach {reach}: {p:?} not offered",
                        query.p
                    );
                }
            }
        }
        assert!(checked > 300 * 50, "{checked}");
    }
}
