//! A uniform grid over the image axes (and time, for animations) with an
//! exact k-nearest search: the block around the query's cell from a
//! [`Tile`], then ring by ring while the block cannot decide.
//!
//! Why a grid: within a neighbourhood the joint space is very anisotropic
//! (the image extent is far larger than the colour extent), which a generic
//! k-d tree splits badly, and σ < 1 only ever needs neighbours within a few
//! cells. Colour is not indexed: points sharing a cell are scanned.
//!
//! Exactness: cell sides are powers of two, so a point's cell is computed
//! exactly and the faces of a block of cells are exact f64 values. A point
//! outside the block differs from the query by at least the face distance g
//! along one axis; rounding is monotone, so its computed distance is at least
//! `sqrt(g * g)` computed the same way. That is the search's `bound`.

use super::tile::{Entry, Tile};
use super::{Found, NeighbourIndex, offer_suffix};
use crate::density::sigma::{Goal, KBest, Sum, Verdict, judge};
use crate::joint::dist2;

/// Radius in cells of the block a [`Tile`] gathers: 3 × 3 cells, or
/// 3 × 3 × 3 for animations (why not 5 × 5: docs/BENCHMARKS.md, "The
/// tile's radius").
const TILE_RADIUS: usize = 1;

/// Upper limit on the number of cells; the cell side doubles until it fits.
const MAX_CELLS: usize = 1 << 22;

pub struct Grid<const D: usize> {
    /// Number of gridded axes: x, y, and t for an animation (D = 6).
    axes: usize,
    side: [f64; 3],
    inv: [f64; 3],
    dims: [usize; 3],
    cells: Vec<Vec<Entry<D>>>,
    /// The id of each cell's last point: rechecks find the cells that
    /// changed without touching the others' lists.
    newest: Vec<Option<u32>>,
    /// Every point by id, unless [`Grid::reserve`] dropped it (then the
    /// cells hold the only copy).
    arena: Vec<[f32; D]>,
    keep_arena: bool,
    /// Points inserted.
    len: usize,
}

// Axis loops index several parallel arrays (side, dims, cell coordinates).
#[allow(clippy::needless_range_loop)]
impl<const D: usize> Grid<D> {
    /// A grid covering joint coordinates `[0, extent[a])` on each gridded
    /// axis a (x, y, then t when D = 6).
    pub fn new(extent: [f64; 3]) -> Grid<D> {
        // One joint unit (σ_image pixels): σ < 1 mostly needs ring 0 and 1.
        // Measured on the benchmark dump: sides 0.5 and 2 are slower.
        Grid::with_side(extent, 0)
    }

    /// A grid whose cells are 2^`log2_side` joint units on a side (or
    /// larger, to stay within the cell limit): smaller cells for denser
    /// point sets.
    pub fn with_side(extent: [f64; 3], log2_side: i32) -> Grid<D> {
        let axes = if D == 6 { 3 } else { 2 };
        // Coordinates are f32, clamped to the finite range (docs/filter.md,
        // F4): no extent goes beyond it, so doubling the side ends.
        let extent = extent.map(|e| {
            if e.is_finite() {
                e.clamp(0.0, f32::MAX as f64)
            } else {
                f32::MAX as f64
            }
        });
        let mut side = [2f64.powi(log2_side.clamp(-30, 30)); 3];
        let dims_for = |side: &[f64; 3]| {
            let mut d = [1usize; 3];
            for a in 0..axes {
                // Far above MAX_CELLS, and far below usize::MAX.
                d[a] = (extent[a] / side[a]).ceil().clamp(1.0, 1e15) as usize;
            }
            d
        };
        let cells = |d: &[usize; 3]| d.iter().fold(1usize, |n, &x| n.saturating_mul(x));
        let mut dims = dims_for(&side);
        while cells(&dims) > MAX_CELLS {
            let a = (0..axes).max_by_key(|&a| dims[a]).unwrap();
            side[a] *= 2.0;
            dims = dims_for(&side);
        }
        let inv = side.map(|s| 1.0 / s);
        let n = dims.iter().product();
        Grid {
            axes,
            side,
            inv,
            dims,
            cells: (0..n).map(|_| Vec::new()).collect(),
            newest: vec![None; n],
            arena: Vec::new(),
            keep_arena: true,
            len: 0,
        }
    }

    /// The cell a point with `q`'s image (and time) coordinates falls in:
    /// colour coordinates do not matter.
    pub fn cell(&self, q: &[f32; D]) -> usize {
        self.flat(self.cell_of(q))
    }

    /// For a grid built once and then only searched: each cell's list
    /// sized to exactly `counts[cell]` points (no growth slack), and no
    /// arena, so a point is stored once. `point` is then unavailable and
    /// the search never rechecks; the points must be inserted next.
    pub fn reserve(&mut self, counts: &[u32]) {
        assert_eq!(counts.len(), self.cells.len());
        assert_eq!(self.len, 0, "reserve before inserting");
        for (cell, &n) in self.cells.iter_mut().zip(counts) {
            cell.reserve_exact(n as usize);
        }
        self.keep_arena = false;
    }

    /// Cells in the grid.
    pub fn cell_count(&self) -> usize {
        self.cells.len()
    }

    #[inline]
    fn axis_value(q: &[f32; D], a: usize) -> f64 {
        q[a] as f64
    }

    #[inline]
    fn cell_of(&self, q: &[f32; D]) -> [usize; 3] {
        let mut c = [0usize; 3];
        for a in 0..self.axes {
            // Multiplying by a power of two is exact, so floor is exact.
            let v = (Self::axis_value(q, a) * self.inv[a]).floor();
            c[a] = if v <= 0.0 {
                0
            } else {
                (v as usize).min(self.dims[a] - 1)
            };
        }
        c
    }

    #[inline]
    fn flat(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    /// Lower bound on the distance of any point outside the block of cells
    /// within Chebyshev distance `r` of `centre`; +∞ if the block covers the
    /// grid.
    fn bound(&self, q: &[f32; D], centre: [usize; 3], r: usize) -> f64 {
        let mut b = f64::INFINITY;
        for a in 0..self.axes {
            let v = Self::axis_value(q, a);
            if centre[a] > r {
                let face = (centre[a] - r) as f64 * self.side[a];
                let g = v - face;
                b = b.min((g * g).sqrt());
            }
            if centre[a] + r + 1 < self.dims[a] {
                let face = (centre[a] + r + 1) as f64 * self.side[a];
                let g = face - v;
                b = b.min((g * g).sqrt());
            }
        }
        b
    }

    /// True when the block of radius r covers every cell.
    fn covers(&self, centre: [usize; 3], r: usize) -> bool {
        (0..self.axes).all(|a| centre[a] <= r && centre[a] + r + 1 >= self.dims[a])
    }

    /// Number of cells on ring r (an upper estimate, ignoring clipping).
    fn ring_cells(&self, r: usize) -> usize {
        let w = 2 * r + 1;
        if self.axes == 3 {
            w * w * w - (w - 2) * (w - 2) * (w - 2)
        } else {
            w * w - (w - 2) * (w - 2)
        }
    }

    /// Calls `visit(cell, flat index)` on every cell at Chebyshev distance
    /// exactly `r` from `centre`, clipped to the grid.
    #[inline]
    fn for_ring(&self, centre: [usize; 3], r: usize, mut visit: impl FnMut([usize; 3], usize)) {
        let lo = |a: usize| centre[a].saturating_sub(r);
        let hi = |a: usize| {
            if a < self.axes {
                (centre[a] + r).min(self.dims[a] - 1)
            } else {
                0
            }
        };
        let (x0, x1, y0, y1, t0, t1) = (lo(0), hi(0), lo(1), hi(1), lo(2), hi(2));
        for t in t0..=t1 {
            let dt = t.abs_diff(centre[2]);
            for y in y0..=y1 {
                let dy = y.abs_diff(centre[1]).max(dt);
                let row = (t * self.dims[1] + y) * self.dims[0];
                if dy == r {
                    for x in x0..=x1 {
                        visit([x, y, t], row + x);
                    }
                } else {
                    // Interior rows: only the two end cells lie on the ring.
                    if centre[0] >= r {
                        let x = centre[0] - r;
                        visit([x, y, t], row + x);
                    }
                    if r > 0 && centre[0] + r < self.dims[0] {
                        let x = centre[0] + r;
                        visit([x, y, t], row + x);
                    }
                }
            }
        }
    }

    /// Lower bound on the squared distance from `q` to any point of cell
    /// `c`: the computed squared distance of any point there is at least
    /// this (see the module doc; the colour terms only add).
    #[inline]
    fn cell_bound2(&self, q: &[f32; D], c: [usize; 3]) -> f64 {
        let mut s = 0.0f64;
        for a in 0..self.axes {
            let v = Self::axis_value(q, a);
            let lo = c[a] as f64 * self.side[a];
            let g = if v < lo {
                lo - v
            } else {
                let hi = (c[a] + 1) as f64 * self.side[a];
                if v >= hi && c[a] + 1 < self.dims[a] {
                    v - hi
                } else {
                    0.0
                }
            };
            s += g * g;
        }
        s
    }

    /// Offers the points of one cell.
    #[inline]
    fn scan(&self, cell: usize, q: &[f32; D], exclude: Option<u32>, kb: &mut KBest) {
        for e in &self.cells[cell] {
            if Some(e.id) != exclude {
                kb.push(dist2(&e.p, q), e.id);
            }
        }
    }

    fn brute_force(&self, q: &[f32; D], exclude: Option<u32>, goal: Goal, kb: &mut KBest) -> Found {
        kb.clear();
        if self.keep_arena {
            for (p, id) in self.arena.iter().zip(0u32..) {
                if Some(id) != exclude {
                    kb.push(dist2(p, q), id);
                }
            }
        } else {
            // The k smallest distances are the same whatever the order.
            for e in self.cells.iter().flatten() {
                if Some(e.id) != exclude {
                    kb.push(dist2(&e.p, q), e.id);
                }
            }
        }
        let verdict = judge(kb, f64::INFINITY, goal).expect("a complete search always decides");
        Found {
            verdict,
            bound: f64::INFINITY,
            reach: u32::MAX,
        }
    }
}

impl<const D: usize> NeighbourIndex<D> for Grid<D> {
    type Scratch = Tile<D>;

    fn insert(&mut self, p: [f32; D]) -> u32 {
        let id = u32::try_from(self.len).expect("more than 2^32 stored samples");
        let c = self.flat(self.cell_of(&p));
        self.cells[c].push(Entry { p, id });
        self.newest[c] = Some(id);
        if self.keep_arena {
            self.arena.push(p);
        }
        self.len += 1;
        id
    }

    fn len(&self) -> usize {
        self.len
    }

    fn point(&self, id: u32) -> &[f32; D] {
        debug_assert!(self.keep_arena, "a reserved grid keeps no arena");
        &self.arena[id as usize]
    }

    fn locality(&self, q: &[f32; D]) -> u32 {
        // At most MAX_CELLS cells, so the index fits.
        self.flat(self.cell_of(q)) as u32
    }

    fn search(
        &self,
        q: &[f32; D],
        exclude: Option<u32>,
        goal: Goal,
        kb: &mut KBest,
        tile: &mut Tile<D>,
    ) -> Found {
        let centre = self.cell_of(q);
        // The block of radius TILE_RADIUS settles almost every search.
        let mut r = TILE_RADIUS;
        let key = (self.flat(centre), self.len);
        if !tile.holds(key) {
            // At most 3 × 3 cells for stills, 3 × 3 × 3 for animations.
            let mut block: [&[Entry<D>]; 27] = [&[]; 27];
            let mut len = 0;
            for rr in 0..=r {
                self.for_ring(centre, rr, |_, flat| {
                    block[len] = &self.cells[flat];
                    len += 1;
                });
            }
            tile.fill(key, &block[..len]);
        }
        // Unless it accepts at once, `judge` below takes the block's bound.
        if tile.nearest(q, exclude, kb, goal == Goal::Decide) == Sum::BelowK {
            return Found {
                verdict: Verdict::Accept,
                bound: 0.0,
                reach: r as u32,
            };
        }
        // Least lower bound of the cells skipped because they could not
        // hold a point nearer than the current k-th.
        let mut skipped = f64::INFINITY;
        loop {
            let bound = if self.covers(centre, r) {
                skipped
            } else {
                self.bound(q, centre, r).min(skipped)
            };
            if let Some(verdict) = judge(kb, bound, goal) {
                return Found {
                    verdict,
                    bound,
                    reach: r as u32,
                };
            }
            r += 1;
            if self.ring_cells(r) > self.len + 64 {
                // Wide, sparse searches: scanning every point is cheaper.
                return self.brute_force(q, exclude, goal, kb);
            }
            self.for_ring(centre, r, |c, flat| {
                if self.cells[flat].is_empty() {
                    return;
                }
                let lb2 = self.cell_bound2(q, c);
                if lb2 >= kb.worst2() {
                    skipped = skipped.min(lb2.sqrt());
                } else {
                    self.scan(flat, q, exclude, kb);
                }
            });
        }
    }

    fn recheck(
        &self,
        q: &[f32; D],
        first_new: u32,
        prev: Found,
        goal: Goal,
        kb: &mut KBest,
        tile: &mut Tile<D>,
    ) -> Found {
        debug_assert!(self.keep_arena, "a reserved grid is not rechecked");
        let new = self.len - first_new as usize;
        let before = kb.version();
        if new > 0 {
            if prev.bound == f64::INFINITY || new <= 8 {
                offer_suffix(&self.arena, first_new, q, kb);
            } else {
                // The new points are the tails of the cells' lists.
                let centre = self.cell_of(q);
                for r in 0..=prev.reach as usize {
                    if r > 0 && self.bound(q, centre, r - 1) >= kb.worst() {
                        break;
                    }
                    self.for_ring(centre, r, |c, flat| {
                        if self.newest[flat].is_none_or(|id| id < first_new)
                            || self.cell_bound2(q, c) >= kb.worst2()
                        {
                            return;
                        }
                        let cell = &self.cells[flat];
                        for e in cell.iter().rev().take_while(|e| e.id >= first_new) {
                            kb.offer(dist2(&e.p, q), e.id);
                        }
                    });
                }
            }
        }
        if kb.version() == before {
            // Nothing nearer arrived: the earlier verdict stands.
            return prev;
        }
        match judge(kb, prev.bound, goal) {
            Some(verdict) => Found { verdict, ..prev },
            None => self.search(q, None, goal, kb, tile),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Clusters and lone points far apart (so that some searches fall back
    /// to scanning every point): a reserved grid, which keeps no arena and
    /// scans its cells instead, gives every verdict and σ the usual grid
    /// gives, for both goals.
    #[test]
    fn a_reserved_grid_searches_like_a_growing_one() {
        let mut seed = 1u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut points: Vec<[f32; 5]> = Vec::new();
        for c in 0..6 {
            let (cx, cy) = (40.0 * c as f32, 7.0 * c as f32);
            for _ in 0..40 {
                points.push([cx + next(), cy + next(), next(), next(), next()]);
            }
        }
        for i in 0..5 {
            points.push([250.0 * next(), 250.0 * next(), 9.0 * i as f32, 0.0, 0.0]);
        }
        let extent = [256.0, 256.0, 1.0];
        let mut growing = Grid::<5>::with_side(extent, -1);
        let mut reserved = Grid::<5>::with_side(extent, -1);
        let mut counts = vec![0u32; reserved.cell_count()];
        for p in &points {
            counts[reserved.cell(p)] += 1;
        }
        reserved.reserve(&counts);
        for p in &points {
            assert_eq!(growing.insert(*p), reserved.insert(*p));
        }
        assert_eq!(reserved.len(), points.len());
        for k in [1, 4, 12] {
            for goal in [Goal::Decide, Goal::Exact] {
                for (id, p) in points.iter().enumerate() {
                    let id = Some(id as u32);
                    let (mut a, mut b) = (KBest::new(k), KBest::new(k));
                    let (mut ta, mut tb) = (Tile::default(), Tile::default());
                    let va = growing.search(p, id, goal, &mut a, &mut ta).verdict;
                    let vb = reserved.search(p, id, goal, &mut b, &mut tb).verdict;
                    assert_eq!(va, vb, "point {id:?}, k {k}, {goal:?}");
                }
            }
        }
    }
}
