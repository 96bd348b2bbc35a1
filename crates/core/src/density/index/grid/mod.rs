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

mod packed;

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
    cells: Cells<D>,
    /// The id of each cell's last point: rechecks find the cells that
    /// changed without touching the others' lists (growing grids only).
    newest: Vec<Option<u32>>,
    /// Every point by id (growing grids only: a packed grid's cells hold
    /// the only copy).
    arena: Vec<[f32; D]>,
    /// Points inserted.
    len: usize,
}

/// Where a grid keeps its points.
enum Cells<const D: usize> {
    /// A list per cell, growing as points are inserted.
    Lists(Vec<Vec<Entry<D>>>),
    /// Every cell's points in one array, cell after cell:
    /// `entries[starts[c]..starts[c + 1]]` ([`Grid::packed`]).
    Packed {
        entries: Vec<Entry<D>>,
        starts: Vec<usize>,
    },
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
        let mut grid = Grid::empty(extent, log2_side);
        let n = grid.cell_count();
        grid.cells = Cells::Lists((0..n).map(|_| Vec::new()).collect());
        grid.newest = vec![None; n];
        grid
    }

    /// The cells of [`Grid::with_side`], with no storage yet.
    fn empty(extent: [f64; 3], log2_side: i32) -> Grid<D> {
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
        Grid {
            axes,
            side,
            inv,
            dims,
            cells: Cells::Lists(Vec::new()),
            newest: Vec::new(),
            arena: Vec::new(),
            len: 0,
        }
    }

    /// The cell a point with `q`'s image (and time) coordinates falls in:
    /// colour coordinates do not matter.
    pub fn cell(&self, q: &[f32; D]) -> usize {
        self.flat(self.cell_of(q))
    }

    /// The points of cell `flat`.
    #[inline]
    fn points(&self, flat: usize) -> &[Entry<D>] {
        match &self.cells {
            Cells::Lists(lists) => &lists[flat],
            Cells::Packed { entries, starts } => &entries[starts[flat]..starts[flat + 1]],
        }
    }

    fn is_packed(&self) -> bool {
        matches!(self.cells, Cells::Packed { .. })
    }

    /// Cells in the grid.
    pub fn cell_count(&self) -> usize {
        self.dims.iter().product()
    }

    #[inline]
    fn axis_value(q: &[f32; D], a: usize) -> f64 {
        q[a] as f64
    }

    #[inline]
    fn cell_of(&self, q: &[f32; D]) -> [usize; 3] {
        let mut c = [0usize; 3];
        for a in 0..self.axes {
            // Multiplying by a power of two is exact, so the cell is
            // exact; truncating a positive value is its floor (without
            // SSE4.1 `floor` is a call, not an instruction).
            let v = Self::axis_value(q, a) * self.inv[a];
            c[a] = if v > 0.0 {
                (v as usize).min(self.dims[a] - 1)
            } else {
                0
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

    /// Offers the points of one cell with ids below `before` (a cell lists
    /// its points in id order).
    #[inline]
    fn scan(&self, cell: usize, q: &[f32; D], exclude: Option<u32>, before: u32, kb: &mut KBest) {
        for e in self.points(cell).iter().take_while(|e| e.id < before) {
            if Some(e.id) != exclude {
                kb.push(dist2(&e.p, q), e.id);
            }
        }
    }

    /// The search of [`NeighbourIndex::search`] among the points with ids
    /// below `before` (all of them when it is |T|): a smaller T is searched
    /// from a tile of the block in id order, of which it is a prefix.
    fn search_among(
        &self,
        q: &[f32; D],
        exclude: Option<u32>,
        before: u32,
        goal: Goal,
        kb: &mut KBest,
        tile: &mut Tile<D>,
    ) -> Found {
        let centre = self.cell_of(q);
        // The block of radius TILE_RADIUS settles almost every search.
        let mut r = TILE_RADIUS;
        let key = (self.flat(centre), self.len);
        let all = before as usize >= self.len;
        debug_assert!(all || (exclude.is_none() && goal == Goal::Exact));
        let held = if all {
            tile.holds(key)
        } else {
            tile.holds_by_id(key)
        };
        if !held {
            // At most 3 × 3 cells for stills, 3 × 3 × 3 for animations.
            let mut block: [&[Entry<D>]; 27] = [&[]; 27];
            let mut len = 0;
            for rr in 0..=r {
                self.for_ring(centre, rr, |_, flat| {
                    block[len] = self.points(flat);
                    len += 1;
                });
            }
            if all {
                tile.fill(key, &block[..len]);
            } else {
                tile.fill_by_id(key, &block[..len]);
            }
        }
        // Unless it accepts at once, `judge` below takes the block's bound.
        if !all {
            tile.nearest_before(q, before, kb);
        } else if tile.nearest(q, exclude, kb, goal == Goal::Decide) == Sum::BelowK {
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
            if self.ring_cells(r) > before as usize + 64 {
                // Wide, sparse searches: scanning every point is cheaper.
                return self.brute_force(q, exclude, before, goal, kb);
            }
            self.for_ring(centre, r, |c, flat| {
                if self.points(flat).is_empty() {
                    return;
                }
                let lb2 = self.cell_bound2(q, c);
                if lb2 >= kb.worst2() {
                    skipped = skipped.min(lb2.sqrt());
                } else {
                    self.scan(flat, q, exclude, before, kb);
                }
            });
        }
    }

    fn brute_force(
        &self,
        q: &[f32; D],
        exclude: Option<u32>,
        before: u32,
        goal: Goal,
        kb: &mut KBest,
    ) -> Found {
        kb.clear();
        match &self.cells {
            Cells::Lists(_) => {
                for (p, id) in self.arena[..before as usize].iter().zip(0u32..) {
                    if Some(id) != exclude {
                        kb.push(dist2(p, q), id);
                    }
                }
            }
            // The k smallest distances are the same whatever the order.
            Cells::Packed { entries, .. } => {
                for e in entries {
                    if Some(e.id) != exclude && e.id < before {
                        kb.push(dist2(&e.p, q), e.id);
                    }
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
        let Cells::Lists(lists) = &mut self.cells else {
            panic!("a packed grid is built whole");
        };
        lists[c].push(Entry { p, id });
        self.newest[c] = Some(id);
        self.arena.push(p);
        self.len += 1;
        id
    }

    fn len(&self) -> usize {
        self.len
    }

    fn point(&self, id: u32) -> &[f32; D] {
        debug_assert!(!self.is_packed(), "a packed grid keeps no arena");
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
        self.search_among(q, exclude, self.len as u32, goal, kb, tile)
    }

    fn search_before(
        &self,
        q: &[f32; D],
        before: u32,
        kb: &mut KBest,
        tile: &mut Tile<D>,
    ) -> Found {
        self.search_among(q, None, before, Goal::Exact, kb, tile)
    }

    fn recheck(
        &self,
        q: &[f32; D],
        first_new: u32,
        prev: Found,
        kb: &mut KBest,
        tile: &mut Tile<D>,
    ) -> Found {
        debug_assert!(!self.is_packed(), "a packed grid is not rechecked");
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
                        let cell = self.points(flat);
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
        match judge(kb, prev.bound, Goal::Decide) {
            Some(verdict) => Found { verdict, ..prev },
            None => self.search(q, None, Goal::Decide, kb, tile),
        }
    }
}
