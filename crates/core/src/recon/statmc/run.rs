//! statmc's window over the film, a block of rows by a run of columns
//! at a time: each offset of the window for the whole block (its patch
//! terms made once), the pairs decided four at a time in vector registers
//! where the CPU has them.

#[cfg(target_arch = "x86_64")]
use super::avx2;
use super::fields::{Fields, patch_passes};
use super::welch::{Kernel, MARGIN, TINY};
use super::{PATCH, RADIUS};
use crate::dump::Header;
use crate::par::prelude::*;

/// The mean of its window's compatible pixels of each pixel `out` holds,
/// from pixel `first` (whole rows) on.
pub(super) fn window(
    fields: &Fields,
    kernel: &Kernel,
    h: &Header,
    first: usize,
    out: &mut [[f64; 3]],
) {
    let (w, ht) = (h.width as usize, h.height as usize);
    // Whole rows only: a block of none would never end.
    debug_assert!(out.is_empty() || (out.len().is_multiple_of(w) && first.is_multiple_of(w)));
    out.par_chunks_mut((w * BLOCK).max(1))
        .enumerate()
        .for_each(|(b, out)| {
            let mut row = first / w.max(1) + b * BLOCK;
            let mut out = out;
            while !out.is_empty() {
                // The block's rows of one frame.
                let (base, y) = ((row / ht) * w * ht, row % ht);
                let rows = (ht - y).min(out.len() / w);
                let (mine, rest) = out.split_at_mut(rows * w);
                for x in (0..w).step_by(RUN) {
                    let xs = x..(x + RUN).min(w);
                    let run = Run {
                        w,
                        ht,
                        base,
                        ys: y..y + rows,
                        xs: xs.clone(),
                    };
                    let mut block = vec![[0.0; 3]; rows * xs.len()];
                    window_run(fields, kernel, &run, &mut block);
                    for (r, values) in block.chunks(xs.len()).enumerate() {
                        mine[r * w + xs.start..r * w + xs.end].copy_from_slice(values);
                    }
                }
                (out, row) = (rest, row + rows);
            }
        });
}

/// The mean of its window's compatible pixels at each of `pixels`
/// (ascending), in their order: each pixel's the same bits as
/// [`window`]'s, whatever the run it is taken in. The pixels are taken
/// tile by tile ([`BLOCK`] rows of a frame by [`RUN`] columns): a tile's
/// as one block over the rows and columns they span, or as runs of each
/// row (pixels [`GAP`] or fewer apart in one run, the pixels between them
/// made and dropped), whichever makes less work ([`Run::cost`]).
pub(super) fn window_at(
    fields: &Fields,
    kernel: &Kernel,
    h: &Header,
    pixels: &[usize],
) -> Vec<[f64; 3]> {
    let (w, ht) = (h.width as usize, h.height as usize);
    let tile_of = |px: usize| {
        let (frame, i) = (px / (w * ht), px % (w * ht));
        (frame, i / w / BLOCK, i % w / RUN)
    };
    // The pixels' places, tile by tile (ascending within a tile).
    let mut order: Vec<usize> = (0..pixels.len()).collect();
    order.sort_by_key(|&i| tile_of(pixels[i]));
    let tiles: Vec<&[usize]> = order
        .chunk_by(|&a, &b| tile_of(pixels[a]) == tile_of(pixels[b]))
        .collect();
    let given: Vec<Vec<(usize, [f64; 3])>> = tiles
        .into_par_iter()
        .map(|places| {
            let at: Vec<usize> = places.iter().map(|&i| pixels[i]).collect();
            let mut values = Vec::with_capacity(at.len());
            let mut next = at.iter();
            for (run, count) in plan(&at, w, ht) {
                let mut all = vec![[0.0; 3]; run.ys.len() * run.xs.len()];
                window_run(fields, kernel, &run, &mut all);
                for &px in next.by_ref().take(count) {
                    let (y, x) = (px % (w * ht) / w, px % w);
                    values.push(all[(y - run.ys.start) * run.xs.len() + x - run.xs.start]);
                }
            }
            places.iter().copied().zip(values).collect()
        })
        .collect();
    let mut out = vec![[0.0; 3]; pixels.len()];
    for (i, value) in given.into_iter().flatten() {
        out[i] = value;
    }
    out
}

/// How [`window_at`] takes one tile's `pixels` (ascending): one block
/// over the rows and columns they span, or runs of one row each
/// ([`runs_of`]), whichever costs less; each run with how many of the
/// pixels it gives, in their order.
fn plan(pixels: &[usize], w: usize, ht: usize) -> Vec<(Run, usize)> {
    let runs = runs_of(pixels, w, ht);
    let block = Run::spanning(pixels, w, ht);
    if block.cost() <= runs.iter().map(|(run, _)| run.cost()).sum::<usize>() {
        vec![(block, pixels.len())]
    } else {
        runs
    }
}

/// The runs of one row each that take `pixels` (ascending, in one frame):
/// pixels of a row [`GAP`] or fewer apart share a run; each with how many
/// of the pixels it gives.
fn runs_of(pixels: &[usize], w: usize, ht: usize) -> Vec<(Run, usize)> {
    debug_assert!(
        pixels.windows(2).all(|p| p[0] < p[1]),
        "ascending, once each"
    );
    let mut runs: Vec<(Run, usize)> = Vec::new();
    for &px in pixels {
        let (row, x) = (px / w, px % w);
        if let Some((run, count)) = runs.last_mut()
            && run.base + run.ys.start * w == row * w
            && x - run.xs.end < GAP
        {
            run.xs.end = x + 1;
            *count += 1;
            continue;
        }
        let (base, y) = ((row / ht) * w * ht, row % ht);
        let (ys, xs) = (y..y + 1, x..x + 1);
        runs.push((
            Run {
                w,
                ht,
                base,
                ys,
                xs,
            },
            1,
        ));
    }
    runs
}

/// Pixels of a row this far apart or nearer are taken in one run of
/// [`window_at`]: each run starts (2R + 1)² offsets, which costs about
/// as much as this many pixels more of the run.
const GAP: usize = 32;

/// Pixels per run of a row that the window takes at once: the run's
/// fields and its neighbours' stay in the core's cache over the window's
/// (2R + 1)² offsets.
const RUN: usize = 256;

/// Rows [`window`] takes at once: the patch test's terms of an offset
/// are made once for the block's rows and the two beside them, where a
/// row alone makes three rows of them.
const BLOCK: usize = 8;

/// Pixels `xs` of rows `ys` of the frame whose first pixel is `base`, on
/// a w × ht film.
struct Run {
    w: usize,
    ht: usize,
    base: usize,
    ys: std::ops::Range<usize>,
    xs: std::ops::Range<usize>,
}

impl Run {
    /// The rows and columns `pixels` (of one frame, not empty) span.
    fn spanning(pixels: &[usize], w: usize, ht: usize) -> Run {
        let base = pixels[0] / (w * ht) * w * ht;
        let span = |at: &dyn Fn(usize) -> usize| {
            let (lo, hi) = pixels.iter().fold((usize::MAX, 0), |(lo, hi), &px| {
                (lo.min(at(px)), hi.max(at(px) + 1))
            });
            lo..hi
        };
        let (ys, xs) = (span(&|px| (px - base) / w), span(&|px| px % w));
        Run {
            w,
            ht,
            base,
            ys,
            xs,
        }
    }

    /// The run's work, in patch terms an offset: the terms of its rows
    /// and the two beside them, and its pairs, each about three terms.
    fn cost(&self) -> usize {
        let (rows, len) = (self.ys.len(), self.xs.len());
        (rows + 2) * (len + 2) + 3 * rows * len
    }
}

/// The output of the pixels of `run`, into `out` (row by row): each
/// pixel's mean of its compatible neighbours, weighted by sample count,
/// the spatial Gaussian and the features' weight where there is a guide.
/// The window is taken offset by offset in its order (row by row, left to
/// right), each offset for the whole run, so each pixel's sums add the
/// same terms in the same order as a loop over its own window; a
/// neighbour left out adds 0, which changes no sum (a sum that starts at
/// +0 is never −0, and a mean is finite).
fn window_run(f: &Fields, k: &Kernel, run: &Run, out: &mut [[f64; 3]]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked just above).
        return unsafe { window_run_avx2(f, k, run, out) };
    }
    window_run_portable(f, k, run, out)
}

/// [`window_run`] compiled for AVX2: the same code and the same
/// arithmetic (no fused multiply-add), in wider vectors.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn window_run_avx2(f: &Fields, k: &Kernel, run: &Run, out: &mut [[f64; 3]]) {
    window_run_portable(f, k, run, out)
}

#[inline(always)]
fn window_run_portable(f: &Fields, k: &Kernel, run: &Run, out: &mut [[f64; 3]]) {
    let Run {
        w,
        ht,
        base,
        ref ys,
        ref xs,
    } = *run;
    let rows = ys.len();
    let mut sum = vec![[[0.0f64; RUN]; 3]; rows];
    let mut weight = vec![[0.0f64; RUN]; rows];
    let mut weights = [0.0f64; RUN];
    let mut patches = Patches::new(rows);
    let r = RADIUS as isize;
    for dy in -r..=r {
        let wy = k.spatial[dy.unsigned_abs()];
        for dx in -r..=r {
            let ws = wy * k.spatial[dx.unsigned_abs()];
            // The run's pixels whose neighbour at x + dx is on the film.
            let lo = xs.start.max((-dx).max(0) as usize);
            let hi = xs.end.min((w as isize - dx).clamp(0, w as isize) as usize);
            if lo >= hi {
                continue;
            }
            let slots = lo - xs.start..hi - xs.start;
            let offset = Offset {
                w,
                ht,
                base,
                dy,
                dx,
            };
            patches.make(f, &offset, ys.clone(), lo..hi);
            for (row, y) in ys.clone().enumerate() {
                let Some(ny) = y.checked_add_signed(dy).filter(|&ny| ny < ht) else {
                    continue;
                };
                let p = base + y * w + lo;
                let q = (base + ny * w + lo).wrapping_add_signed(dx);
                let run = &mut weights[slots.clone()];
                if pair_weights(f, k, &Pairs { ws, p, q }, run) {
                    for (i, wq) in run.iter_mut().enumerate() {
                        let same = f.n[p + i] >= 2 && f.compatible(p + i, q + i, k);
                        *wq = ws * f.n[q + i] as f64 * f64::from(u8::from(same));
                    }
                }
                patches.test(f, k, &offset, row, (p, q), run);
                if let Some(features) = &f.features {
                    features.weigh(p, q, run);
                }
                for (sum, mean) in sum[row].iter_mut().zip(&f.mean) {
                    let m = &mean[q..q + run.len()];
                    for ((s, wq), m) in sum[slots.clone()].iter_mut().zip(&*run).zip(m) {
                        *s += wq * m;
                    }
                }
                for (s, wq) in weight[row][slots.clone()].iter_mut().zip(&*run) {
                    *s += wq;
                }
            }
        }
    }
    for (row, y) in ys.clone().enumerate() {
        let p = base + y * w + xs.start;
        let out = &mut out[row * xs.len()..(row + 1) * xs.len()];
        for (i, out) in out.iter_mut().enumerate() {
            let n = f.n[p + i];
            if n >= 2 {
                // p is always compatible with itself.
                *out = std::array::from_fn(|c| sum[row][c][i] / weight[row][i]);
            } else if n == 1 {
                *out = std::array::from_fn(|c| f.mean[c][p + i]);
            }
        }
    }
}

/// One offset (dy, dx) of the window, on a w × ht film whose frame starts
/// at pixel `base`.
#[derive(Clone, Copy)]
struct Offset {
    w: usize,
    ht: usize,
    base: usize,
    dy: isize,
    dx: isize,
}

/// The patch test's squared differences of one offset for a block's
/// rows: per row of the block and its two neighbours, each pixel's three
/// pairs along the row summed ([`Fields::patch_term`]'s a), which
/// [`Patches::test`] sums over three rows.
struct Patches {
    a: Vec<[f64; RUN]>,
    len: usize,
}

impl Patches {
    fn new(rows: usize) -> Patches {
        // The sums below take a pair and the two beside it.
        const { assert!(PATCH == 3) };
        Patches {
            a: vec![[0.0; RUN]; rows + 2],
            len: 0,
        }
    }

    /// The sums along each of the rows `ys` and the two beside them, for
    /// the pixels `xs` (those whose neighbour at dx is on the film): the
    /// pairs at columns x − 1, x and x + 1 of row py and those + dx of
    /// row py + dy, added in that order, a pair not on the film (or with
    /// fewer than two samples either side) adding 0.
    #[inline(always)]
    fn make(
        &mut self,
        f: &Fields,
        at: &Offset,
        ys: std::ops::Range<usize>,
        xs: std::ops::Range<usize>,
    ) {
        let Offset {
            w,
            ht,
            base,
            dy,
            dx,
        } = *at;
        let len = xs.len();
        self.len = len;
        // Term j is the pair at column x = xs.start + j − 1: those with
        // both on the film are terms from..to.
        let from = (1 + dx.min(0).unsigned_abs()).saturating_sub(xs.start);
        let to = (len + 2).min((w + 1).saturating_sub(xs.start + dx.max(0) as usize));
        for (t, py) in (ys.start as isize - 1..ys.end as isize + 1).enumerate() {
            let a = &mut self.a[t];
            let qy = py + dy;
            if py < 0 || qy < 0 || py as usize >= ht || qy as usize >= ht || from >= to {
                a[..len].fill(0.0);
                continue;
            }
            let mut ta = [0.0f64; RUN + 2];
            let p = base + py as usize * w + xs.start + from - 1;
            let q = (base + qy as usize * w + xs.start + from - 1).wrapping_add_signed(dx);
            let n = to - from;
            fn field(v: &[f64], at: usize, n: usize) -> &[f64] {
                &v[at..at + n]
            }
            let (np, nq) = (&f.n[p..p + n], &f.n[q..q + n]);
            let y = &f.y_mean;
            let (p0, p1, p2) = (field(&y[0], p, n), field(&y[1], p, n), field(&y[2], p, n));
            let (q0, q1, q2) = (field(&y[0], q, n), field(&y[1], q, n), field(&y[2], q, n));
            let counts = np.iter().zip(nq);
            let means = p0
                .iter()
                .zip(q0)
                .zip(p1.iter().zip(q1))
                .zip(p2.iter().zip(q2));
            for ((ta, (np, nq)), (((p0, q0), (p1, q1)), (p2, q2))) in
                ta[from..to].iter_mut().zip(counts).zip(means)
            {
                let both = (*np >= 2) & (*nq >= 2);
                let (d0, d1, d2) = (p0 - q0, p1 - q1, p2 - q2);
                let term = (d0 * d0 + d1 * d1) + d2 * d2;
                *ta = if both { term } else { 0.0 };
            }
            // Along the row: the pair before, the pair, the pair after.
            let (t0, t1, t2) = (&ta[..len], &ta[1..len + 1], &ta[2..len + 2]);
            for (((o, x), y), z) in a[..len].iter_mut().zip(t0).zip(t1).zip(t2) {
                *o = (x + y) + z;
            }
        }
    }

    /// `wq[i]` left where the patches of the pairs (p + i, q + i) pass
    /// ([`patch_passes`]), else 0, p + i in row `row` of the block: the
    /// three rows' sums added in order. Where both patches lie whole on
    /// the film with two samples a pixel, the spreads are the pixels'
    /// [`Fields::patch_spread`]; elsewhere [`patch_spreads_of`] makes them.
    #[inline(always)]
    fn test(
        &self,
        f: &Fields,
        k: &Kernel,
        at: &Offset,
        row: usize,
        pq: (usize, usize),
        wq: &mut [f64],
    ) {
        debug_assert_eq!(wq.len(), self.len);
        let (p, q) = pq;
        let len = wq.len();
        let mut a = [0.0f64; RUN];
        let v = &self.a;
        let (r0, r1, r2) = (&v[row][..len], &v[row + 1][..len], &v[row + 2][..len]);
        for (((o, x), y), z) in a[..len].iter_mut().zip(r0).zip(r1).zip(r2) {
            *o = (x + y) + z;
        }
        let full = k.patch[PATCH * PATCH];
        let (sp, sq) = (&f.patch_spread[p..p + len], &f.patch_spread[q..q + len]);
        let mut partial = false;
        for (((wq, a), sp), sq) in wq.iter_mut().zip(&a[..len]).zip(sp).zip(sq) {
            let b = sp + sq;
            let whole = !b.is_nan();
            partial |= !whole;
            *wq = if !whole || *a <= full * b { *wq } else { 0.0 };
        }
        if partial {
            for (i, wq) in wq.iter_mut().enumerate() {
                if (sp[i] + sq[i]).is_nan() {
                    let (b, m) = patch_spreads_of(f, at, p + i, q + i);
                    if !patch_passes(k, a[i], b, m) {
                        *wq = 0.0;
                    }
                }
            }
        }
    }
}

/// The patch test's spreads and count of the pair (p, q), q at the
/// offset `at` from p: Σ_u S_{p+u} + Σ_u S_{q+u} over the m pairs of the
/// 3 × 3 patches both on the film with two samples or more, each side
/// summed along the rows, then over them, in order.
fn patch_spreads_of(f: &Fields, at: &Offset, p: usize, q: usize) -> (f64, f64) {
    let Offset { w, ht, base, .. } = *at;
    let (py, px) = ((p - base) / w, (p - base) % w);
    let (qy, qx) = ((q - base) / w, (q - base) % w);
    let on = |v: usize, u: isize, len: usize| v.checked_add_signed(u).filter(|&v| v < len);
    let (mut sp, mut sq, mut m) = (0.0f64, 0.0f64, 0.0f64);
    for uy in -1..=1 {
        let (mut rp, mut rq) = (0.0f64, 0.0f64);
        for ux in -1..=1 {
            let (Some(y0), Some(x0)) = (on(py, uy, ht), on(px, ux, w)) else {
                continue;
            };
            let (Some(y1), Some(x1)) = (on(qy, uy, ht), on(qx, ux, w)) else {
                continue;
            };
            let (p, q) = (base + y0 * w + x0, base + y1 * w + x1);
            if f.n[p] >= 2 && f.n[q] >= 2 {
                (rp, rq, m) = (rp + f.spread[p], rq + f.spread[q], m + 1.0);
            }
        }
        (sp, sq) = (sp + rp, sq + rq);
    }
    (sp + sq, m)
}

/// Each pair (p + i, q + i)'s weight into `wq`: `ws` × q's sample count
/// where they are compatible ([`Fields::compatible`]), else 0; the weight
/// of a pixel p + i with fewer than two samples is never read. Decided
/// here where the squares are clear of [`agree`](super::welch::agree)'s boundary, or where
/// s = 0 (then the written form is d ≤ 0); true when some pair is
/// neither, which the caller then decides with [`Fields::compatible`].
#[inline(always)]
fn pair_weights(f: &Fields, k: &Kernel, pairs: &Pairs, wq: &mut [f64]) -> bool {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked just above).
        return unsafe { avx2::pair_weights(f, k, pairs, wq) };
    }
    pair_weights_portable(f, k, pairs, wq, 0)
}

/// The pairs (p + i, q + i) of one window offset along a run, whose
/// spatial weight is `ws`.
#[derive(Clone, Copy)]
pub(super) struct Pairs {
    pub(super) ws: f64,
    pub(super) p: usize,
    pub(super) q: usize,
}

/// [`pair_weights`] from pair `from` on, one pair at a time.
#[inline(always)]
pub(super) fn pair_weights_portable(
    f: &Fields,
    k: &Kernel,
    pairs: &Pairs,
    wq: &mut [f64],
    from: usize,
) -> bool {
    let Pairs { ws, p, q } = *pairs;
    let last = k.t2.len() - 1;
    let mut undecided = false;
    for (i, wq) in wq.iter_mut().enumerate().skip(from) {
        let (p, q) = (p + i, q + i);
        let (np, nq) = (f.n[p], f.n[q]);
        let left_out =
            (np < 2) | (nq < 2) | (f.spread[q] > f.limit[p]) | (f.spread[p] > f.limit[q]);
        let valid = !left_out;
        let crit2 = k.t2[((np + nq).saturating_sub(2) as usize).min(last)];
        let mut same = valid;
        for c in 0..3 {
            let d = (f.y_mean[c][p] - f.y_mean[c][q]).abs();
            let s = f.se2[c][p] + f.se2[c][q];
            let bound2 = crit2 * s;
            let d2 = d * d;
            let (inside, outside) = (d2 < bound2 * (1.0 - MARGIN), d2 > bound2 * (1.0 + MARGIN));
            let clear = (bound2 > TINY) & (inside | outside);
            let zero = s == 0.0;
            same &= (clear & inside) | (!clear & zero & (d <= 0.0));
            undecided |= valid & !clear & !zero;
        }
        *wq = ws * nq as f64 * f64::from(u8::from(same));
    }
    undecided
}

#[cfg(test)]
mod tests;
