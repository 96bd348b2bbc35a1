//! The cells of a grid over the image (and time) axes and lightness that
//! list the F6a queries whose reach touches them ([`super::streamed`]),
//! and the test that spares most samples of the dump their colour
//! transform: whether a sample's cell may list a query, from its pixel and
//! its luminance alone.

use super::streamed::Query;
use crate::dump::{Header, Record};
use crate::joint::JointSpace;
use crate::joint::lab::luminance;

/// Upper limit on the cells of the grid of queries; the side doubles
/// until it fits.
const MAX_CELLS: usize = 1 << 20;

/// Relative slack of a query's reach in [`QueryCells`]: rounding moves a
/// coordinate by about 10⁻¹⁶ of its size.
const REACH_SLACK: f64 = 1e-9;

/// A pixel that a cell border crosses, in [`QueryCells::pixel_cells`].
const STRADDLES: u32 = u32::MAX;

/// Relative slack of a luminance where the lightness cell changes in
/// [`QueryCells::may_list`]: the colour transform rounds within about
/// 10⁻¹⁵ of its value.
const LUMINANCE_SLACK: f64 = 1e-9;

/// The queries listed by the cells of a grid that they reach: over the
/// image axes, time for animations, and the first colour axis (lightness),
/// which separates a firefly from the samples around it. Most samples'
/// cells list no query; [`QueryCells::may_list`] tells from a sample's
/// position and luminance, without its colour transform.
pub(super) struct QueryCells {
    /// The coordinates gridded: x, y (t), the first colour coordinate.
    coords: Vec<usize>,
    origin: [f64; 4],
    side: [f64; 4],
    dims: [usize; 4],
    lists: Vec<Vec<u32>>,
    /// One bit a cell: whether its list has a query (small enough to stay
    /// in cache where the lists do not).
    occupied: Vec<u64>,
    /// [`QueryCells::pixel_cells`].
    pixel_cells: [Vec<u32>; 3],
    /// The luminances where the lightness cell changes, bracketed:
    /// `cuts[i]` holds every luminance whose lightness coordinate's cell
    /// can be on either side of cell `i + 1`'s lower border.
    cuts: Vec<(f64, f64)>,
}

impl QueryCells {
    pub(super) fn new<const D: usize>(
        header: &Header,
        space: &JointSpace,
        queries: &[Query<D>],
    ) -> QueryCells {
        let extent = space.extent(header);
        let axes = D - 3;
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
            occupied: Vec::new(),
            pixel_cells: Default::default(),
            cuts: Vec::new(),
        };
        cells.pixel_cells = cells.pixel_cells::<D>(space, header);
        cells.cuts = (1..dims[axes])
            .map(|i| cells.luminance_cut(space, axes, i))
            .collect();
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
        cells.occupied = vec![0; cells.lists.len().div_ceil(64)];
        for (c, list) in cells.lists.iter().enumerate() {
            if !list.is_empty() {
                cells.occupied[c / 64] |= 1 << (c % 64);
            }
        }
        cells
    }

    /// The cell of coordinate `v` along gridded axis `a`, clamped to the
    /// grid.
    fn index(&self, v: f64, a: usize) -> usize {
        // Truncating a positive value is its floor.
        let c = (v - self.origin[a]) / self.side[a];
        if c > 0.0 {
            (c as usize).min(self.dims[a] - 1)
        } else {
            0
        }
    }

    /// The least luminance whose lightness coordinate lies in cell `i` of
    /// axis `a` or beyond, bracketed by a margin far above the rounding of
    /// the colour transform: the lightness coordinate never decreases
    /// with luminance (it rounds monotone functions), so a luminance below
    /// the bracket is in a cell before `i` and one above it in `i` or
    /// after. Found by bisection over the f64 values in order.
    fn luminance_cut(&self, space: &JointSpace, a: usize, i: usize) -> (f64, f64) {
        let cell = |y: f64| self.index(space.lightness_coord(y) as f64, a);
        // f64 values as u64 keys in the values' order.
        let key = |y: f64| {
            let b = y.to_bits();
            if b >> 63 == 1 { !b } else { b | 1 << 63 }
        };
        let value = |k: u64| {
            if k >> 63 == 1 {
                f64::from_bits(k & !(1 << 63))
            } else {
                f64::from_bits(!k)
            }
        };
        let (mut lo, mut hi) = (key(-f64::MAX), key(f64::MAX));
        if cell(value(lo)) >= i {
            return (f64::NEG_INFINITY, f64::NEG_INFINITY);
        }
        if cell(value(hi)) < i {
            return (f64::INFINITY, f64::INFINITY);
        }
        // cell(lo) < i ≤ cell(hi)
        while hi - lo > 1 {
            let mid = lo + (hi - lo) / 2;
            if cell(value(mid)) >= i {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let t = value(hi);
        let margin = LUMINANCE_SLACK * t.abs() + f64::MIN_POSITIVE;
        (t - margin, t + margin)
    }

    /// Each pixel's cell (column, row or frame) along the gridded image
    /// (and time) axes, or [`STRADDLES`] where a cell border crosses the
    /// pixel. The coordinate never decreases along an axis (it rounds
    /// monotone functions), so the pixel's first and last values' cells
    /// bound every value's.
    fn pixel_cells<const D: usize>(&self, space: &JointSpace, header: &Header) -> [Vec<u32>; 3] {
        let counts = [header.width, header.height, header.frames];
        std::array::from_fn(|a| {
            if a >= D - 3 {
                return Vec::new();
            }
            let cell = |v: f32| {
                let mut at = [0.0f32; 3];
                at[a] = v;
                let r = Record::new(at[0], at[1], at[2], [0.0; 3]);
                self.index(space.image_point::<D>(&r)[a] as f64, a)
            };
            // Pixels past 2²⁴ are not exact in f32: not in the table, left
            // to the exact cell.
            (0..counts[a].min(1 << 24))
                .map(|i| {
                    let last = f32::from_bits(((i + 1) as f32).to_bits() - 1);
                    match (cell(i as f32), cell(last)) {
                        (lo, hi) if lo == hi => lo as u32,
                        _ => STRADDLES,
                    }
                })
                .collect()
        })
    }

    /// Whether the cell of valid record `r`'s point may list a query,
    /// from its image (and time) cell and its luminance, without its
    /// colour transform: false only when [`QueryCells::at`] of its point
    /// is empty.
    #[inline]
    pub(super) fn may_list<const D: usize>(&self, space: &JointSpace, r: &Record) -> bool {
        let axes = D - 3;
        let mut c = [0usize; 4];
        let at = [r.x, r.y, r.t];
        for a in 0..axes {
            // A valid record's value is in 0..count, so truncating is its
            // pixel.
            let table = self.pixel_cells[a].get(at[a] as usize).copied();
            c[a] = match table.unwrap_or(STRADDLES) {
                STRADDLES => self.index(space.image_point::<D>(r)[a] as f64, a),
                cell => cell as usize,
            };
        }
        let y = luminance([r.r as f64, r.g as f64, r.b as f64]);
        let d = &self.dims;
        self.lightness_cells(y).any(|l| {
            c[axes] = l;
            let flat = ((c[3] * d[2] + c[2]) * d[1] + c[1]) * d[0] + c[0];
            self.occupied[flat / 64] & (1 << (flat % 64)) != 0
        })
    }

    /// The lightness cells a colour of luminance `y` may lie in (usually
    /// one). A luminance at or above a cut's upper end is certainly at
    /// or beyond the cell after it: every luminance from the cut on is,
    /// and the margin only covers rounding that is not monotone. One
    /// below its lower end is certainly before it.
    fn lightness_cells(&self, y: f64) -> std::ops::RangeInclusive<usize> {
        let first = self.cuts.partition_point(|&(_, above)| above <= y);
        let last = self.cuts.partition_point(|&(below, _)| below <= y);
        first..=last
    }

    /// The queries listed in the cell of `p`.
    pub(super) fn at<const D: usize>(&self, p: &[f32; D]) -> &[u32] {
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
    use crate::dump::Order;
    use crate::joint::dist2;

    /// Every point within a query's reach (by the canonical distance) is
    /// offered to it: points on the reach's surface along each axis, on
    /// cell borders and at random inside, for reaches from none to
    /// unbounded, smaller and larger than a cell.
    #[test]
    fn a_point_within_the_reach_finds_its_query_in_its_cell() {
        let mut uniform = crate::synth::test_units(7);
        // 40 × 30 joint units at σ_image = 3.
        let header = Header::still(120, 90, 4, Order::PassMajor);
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
        let cells = QueryCells::new(&header, &JointSpace::DEFAULT, &queries);
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

    /// A record the gate passes over lists no query in its cell, and the
    /// gate passes over most records whose cell lists none: in each colour
    /// space and white, for stills and animations, with cell borders on
    /// and inside pixels, with records from dark and negative to far
    /// above the white.
    #[test]
    fn the_luminance_gate_passes_over_only_cells_without_queries() {
        use crate::joint::ColorSpace;
        let mut uniform = crate::synth::test_units(5);
        let header = Header {
            frames: 3,
            ..Header::still(60, 40, 16, Order::PassMajor)
        };
        let record = |u: &mut dyn FnMut() -> f64| {
            let scale = [0.01, 1.0, 1.0, 40.0, 3e4][(u() * 5.0) as usize];
            let mut c = || ((u() * 1.1 - 0.1) * scale) as f32;
            let (r, g, b) = (c(), c(), c());
            crate::dump::Record::new(
                (u() * 60.0) as f32,
                (u() * 40.0) as f32,
                (u() * 2.999) as f32,
                [r, g, b],
            )
        };
        let (mut gated, mut empty) = (0, 0);
        for color in [ColorSpace::Cielab, ColorSpace::Loglab, ColorSpace::Logluv] {
            // σ_image 2.7 and σ_time 1.5 put cell borders inside pixels
            // and frames.
            for (white, sigma_image, sigma_time) in [(1.0, 3.0, 2.0), (7.5, 2.7, 1.5)] {
                let space = JointSpace {
                    color,
                    white,
                    sigma_image,
                    sigma_time,
                    ..JointSpace::DEFAULT
                };
                let sources: Vec<Record> = (0..80).map(|_| record(&mut uniform)).collect();
                let queries5 = queries_at::<5>(&space, &sources[..40]);
                let queries6 = queries_at::<6>(&space, &sources[40..]);
                let cells5 = QueryCells::new(&header, &space, &queries5);
                let cells6 = QueryCells::new(&header, &space, &queries6);
                for _ in 0..4000 {
                    let r = record(&mut uniform);
                    for (listed, may) in [
                        (
                            !cells5.at(&space.point::<5>(&r)).is_empty(),
                            cells5.may_list::<5>(&space, &r),
                        ),
                        (
                            !cells6.at(&space.point::<6>(&r)).is_empty(),
                            cells6.may_list::<6>(&space, &r),
                        ),
                    ] {
                        assert!(
                            may || !listed,
                            "{color:?} white {white}: {r:?} gated but listed"
                        );
                        if !listed {
                            empty += 1;
                            gated += usize::from(!may);
                        }
                    }
                }
            }
        }
        assert!(
            gated * 10 > empty * 9,
            "gated {gated} of {empty} empty cells"
        );
    }

    /// Queries at the points of `records`, with squared reaches from
    /// below a cell's to above it.
    fn queries_at<const D: usize>(space: &JointSpace, records: &[Record]) -> Vec<Query<D>> {
        records
            .iter()
            .enumerate()
            .map(|(i, r)| Query {
                rec: usize::MAX,
                p: space.point::<D>(r),
                reach2: [0.05, 0.4, 2.0][i % 3],
            })
            .collect()
    }

    /// At and around every lightness cut, in each colour space, the
    /// cells a luminance may lie in hold the cell its lightness is in:
    /// at the cut's ends, one f64 step beyond them, and at the luminance
    /// the bisection found.
    #[test]
    fn the_lightness_cells_hold_the_cell_at_every_cut() {
        use crate::joint::ColorSpace;
        let header = Header::still(30, 20, 4, Order::PassMajor);
        let step = |y: f64, up: bool| {
            let next = if up { y.next_up() } else { y.next_down() };
            if next.is_finite() { next } else { y }
        };
        let mut checked = 0;
        for color in [ColorSpace::Cielab, ColorSpace::Loglab, ColorSpace::Logluv] {
            for white in [1.0, 0.3] {
                let space = JointSpace {
                    color,
                    white,
                    ..JointSpace::DEFAULT
                };
                // Queries from dark to far above the white, so that the
                // lightness axis has many cells.
                let queries: Vec<Query<5>> = [-0.5, 0.0, 0.02, 0.5, 3.0, 40.0, 900.0, 2e4]
                    .iter()
                    .map(|&v| Query {
                        rec: 0,
                        p: space.point::<5>(&Record::new(5.0, 5.0, 0.0, [v; 3])),
                        reach2: 0.3,
                    })
                    .collect();
                let cells = QueryCells::new(&header, &space, &queries);
                assert!(
                    cells.cuts.len() >= 8,
                    "{color:?}: {} cuts",
                    cells.cuts.len()
                );
                for &(below, above) in &cells.cuts {
                    let mid = below + (above - below) / 2.0;
                    for y in [
                        below,
                        above,
                        mid,
                        step(below, false),
                        step(above, true),
                        step(mid, true),
                    ] {
                        if !y.is_finite() {
                            continue;
                        }
                        let cell = cells.index(space.lightness_coord(y) as f64, 2);
                        assert!(
                            cells.lightness_cells(y).contains(&cell),
                            "{color:?} white {white}: luminance {y} in cell {cell}, not in {:?}",
                            cells.lightness_cells(y)
                        );
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 200, "{checked}");
    }
}
