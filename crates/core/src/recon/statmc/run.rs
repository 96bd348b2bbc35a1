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
mod tests {
    use super::*;
    use crate::dump::Record;
    use crate::recon::statmc::welch::agree;
    use crate::recon::statmc::{Guide, denoise, stats_of};
    use crate::recon::{Image, test_header};

    /// The squared pre-test decides as the written form does, on random
    /// pairs and on pairs built at the boundary, one ulp either side, in
    /// the subnormal range and at zero spread; so does the window's loop
    /// over a run ([`pair_weights`]) wherever it decides a pair itself.
    #[test]
    fn agree_is_the_written_test() {
        let written = |d: f64, s: f64, crit: f64| d.abs() <= crit * s.sqrt();
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        // Both outcomes occur at the boundary: the cases test something.
        let (mut outcomes, mut by_run) = ([0usize; 2], 0);
        for i in 0..200_000 {
            let crit = 1.0 + 3.0 * next();
            let scale = 10f64.powi((next() * 40.0) as i32 - 20);
            let (se_p, se_q) = (next() * scale, next() * scale);
            let mut d = crit * (se_p + se_q).sqrt();
            match i % 4 {
                0 => d *= 0.5 + next(),
                1 => {}
                2 => d = f64::from_bits(d.to_bits() + 1),
                _ => d = f64::from_bits(d.to_bits().saturating_sub(1)),
            }
            let tiny = d * 1e-150;
            for (sp, sq, d) in [
                (se_p, se_q, d),
                (se_p * 1e-300, se_q * 1e-300, tiny),
                (0.0, 0.0, d),
                (0.0, 0.0, 0.0),
            ] {
                let want = written(d, sp + sq, crit);
                assert_eq!(
                    agree(0.0, d, sp + sq, crit, crit * crit),
                    want,
                    "{d} {sp} {sq} {crit}"
                );
                // The same pair as pixels of 8 samples, four times in a
                // run (in vector registers where the CPU has them) and
                // once pair by pair.
                let f = Fields {
                    features: None,
                    n: vec![8; 8],
                    mean: std::array::from_fn(|_| vec![0.0; 8]),
                    y_mean: std::array::from_fn(|_| [[0.0; 4], [d; 4]].concat()),
                    se2: std::array::from_fn(|_| [[sp; 4], [sq; 4]].concat()),
                    spread: vec![0.0; 8],
                    limit: vec![f64::INFINITY; 8],
                    patch_spread: vec![f64::NAN; 8],
                };
                let k = Kernel {
                    t: vec![crit; 15],
                    t2: vec![crit * crit; 15],
                    spatial: [1.0; RADIUS + 1],
                    patch: Kernel::new(1).patch,
                };
                let weight = if want { 8.0 } else { 0.0 };
                let mut wq = [0.0; 4];
                let pairs = Pairs {
                    ws: 1.0,
                    p: 0,
                    q: 4,
                };
                if !pair_weights(&f, &k, &pairs, &mut wq) {
                    assert_eq!(wq, [weight; 4], "{d} {sp} {sq} {crit}");
                    by_run += 1;
                }
                if !pair_weights_portable(&f, &k, &pairs, &mut wq[..1], 0) {
                    assert_eq!(wq[0], weight, "{d} {sp} {sq} {crit}");
                }
                assert_eq!(f.compatible(0, 4, &k), want);
                if i % 4 != 0 {
                    outcomes[usize::from(want)] += 1;
                }
            }
        }
        assert!(outcomes[0] > 1000 && outcomes[1] > 1000, "{outcomes:?}");
        assert!(by_run > 400_000, "{by_run} pairs decided in the run");
    }

    /// The window as its definition says it, one output pixel at a time:
    /// the compatible neighbours' means whose patches pass, each weighted
    /// by its count, the spatial Gaussian and the features' weight, the
    /// others skipped (every patch passing where `patched` is false).
    fn denoise_per_pixel(
        f: &Fields,
        k: &Kernel,
        (w, ht): (usize, usize),
        patched: bool,
    ) -> Vec<[f64; 3]> {
        // The patch test's sums of the pair (p, q), pixels of one frame
        // at (x, y) and (nx, ny): along each row, then over the rows.
        let patches = |base: usize, (x, y): (usize, usize), (nx, ny): (usize, usize)| {
            let on = |x: usize, u: isize, len: usize| x.checked_add_signed(u).filter(|&v| v < len);
            // Σ a, Σ S_p, Σ S_q and the count m.
            let mut sums = [0.0f64; 4];
            for uy in -1..=1 {
                let mut row = [0.0f64; 4];
                for ux in -1..=1 {
                    let (Some(px), Some(py)) = (on(x, ux, w), on(y, uy, ht)) else {
                        continue;
                    };
                    let (Some(qx), Some(qy)) = (on(nx, ux, w), on(ny, uy, ht)) else {
                        continue;
                    };
                    let pair = f.patch_term(base + py * w + px, base + qy * w + qx);
                    if let Some((a, sp, sq)) = pair {
                        row = [row[0] + a, row[1] + sp, row[2] + sq, row[3] + 1.0];
                    }
                }
                sums = std::array::from_fn(|i| sums[i] + row[i]);
            }
            let [a, sp, sq, m] = sums;
            !patched || patch_passes(k, a, sp + sq, m)
        };
        (0..f.n.len())
            .map(|px| {
                let n = f.n[px];
                if n < 2 {
                    return std::array::from_fn(|c| if n == 1 { f.mean[c][px] } else { 0.0 });
                }
                let (base, i) = (px - px % (w * ht), px % (w * ht));
                let (x, y) = (i % w, i / w);
                let (mut sum, mut weight) = ([0.0f64; 3], 0.0f64);
                for ny in y.saturating_sub(RADIUS)..(y + RADIUS + 1).min(ht) {
                    for nx in x.saturating_sub(RADIUS)..(x + RADIUS + 1).min(w) {
                        let q = base + ny * w + nx;
                        if !f.compatible(px, q, k) || !patches(base, (x, y), (nx, ny)) {
                            continue;
                        }
                        let wq = k.spatial[ny.abs_diff(y)] * k.spatial[nx.abs_diff(x)];
                        let wq = wq * f.n[q] as f64;
                        let wq = f.features.as_ref().map_or(wq, |g| wq * g.weight(px, q));
                        for (c, s) in sum.iter_mut().enumerate() {
                            *s += wq * f.mean[c][q];
                        }
                        weight += wq;
                    }
                }
                sum.map(|s| s / weight)
            })
            .collect()
    }

    /// The window taken offset by offset along runs of a block's rows
    /// gives each pixel the bits of its own window's loop: films narrower
    /// than the window and wider than a run, blocks across frames, pixels
    /// with 0, 1 and many samples, zero-variance pixels (equal and
    /// unequal), outliers, patches that fail where the pairs pass.
    #[test]
    fn the_window_by_runs_is_the_per_pixel_window() {
        let mut unit = crate::synth::test_units(7);
        let mut patched = 0;
        let films = [
            (1, 1, 1),
            (5, 3, 2),
            (19, 23, 1),
            (7, 11, 2),
            (2 * RUN + 37, 4, 2),
        ];
        for (w, ht, frames) in films {
            let mut h = test_header(w as u32, ht as u32);
            h.frames = frames;
            let mut recs = Vec::new();
            for px in 0..w * ht * frames as usize {
                let (f, i) = (px / (w * ht), px % (w * ht));
                let (x, y) = ((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
                let kind = (unit() * 8.0) as usize;
                let n = [0, 1, 2, 8, 8, 8, 16, 3][kind];
                let level = if x < w as f32 / 2.0 { 1.0 } else { 4.0 };
                for s in 0..n {
                    let v = match kind {
                        // Zero variance: one level, or the level of a
                        // neighbouring column.
                        3 => level,
                        4 => level + (x as usize % 2) as f32,
                        _ if unit() < 0.02 => 300.0 * unit() as f32,
                        _ => level * (0.5 + unit() as f32),
                    };
                    let c = [v, v * (0.5 + 0.1 * s as f32), 0.0];
                    recs.push(Record::new(x, y, f as f32 + 0.5, c));
                }
            }
            // Features of a few levels: equal (weight 1), near and far.
            let mut feature = || -> Vec<f32> {
                let levels = [0.2, 0.2, 0.21, 0.5, 0.9];
                let len = 3 * w * ht * frames as usize;
                (0..len).map(|_| levels[(unit() * 5.0) as usize]).collect()
            };
            let (albedo, normal) = (feature(), feature());
            let guides = [
                None,
                Some(Guide::new(&albedo, None)),
                Some(Guide::new(&albedo, Some(&normal))),
            ];
            let stats = stats_of(&recs, &h, |i| i % 31 != 5);
            let k = Kernel::new(stats.iter().map(|s| s.x.n).max().unwrap_or(0));
            for guide in guides {
                let img = denoise(&recs, &h, |i| i % 31 != 5, guide);
                let fields = Fields::new(&stats, w, ht, guide);
                let want = denoise_per_pixel(&fields, &k, (w, ht), true);
                let unpatched = denoise_per_pixel(&fields, &k, (w, ht), false);
                patched += want.iter().zip(&unpatched).filter(|(a, b)| a != b).count();
                for (px, (got, want)) in img.data.iter().zip(&want).enumerate() {
                    let bits = |v: &[f64; 3]| v.map(f64::to_bits);
                    let guided = guide.is_some();
                    assert_eq!(
                        bits(got),
                        bits(want),
                        "{w} × {ht} × {frames}, {guided}, {px}"
                    );
                }
            }
        }
        // The patches left some pairs out that the pairs' own test passed.
        assert!(patched > 50, "{patched}");
    }

    /// The window at chosen pixels is the film's window there, bit for
    /// bit: a tile's pixels dense (taken as one block of rows), scattered
    /// (runs of a row each), a long row and the film's edges, both frames.
    #[test]
    fn the_window_at_pixels_is_the_films_window_there() {
        let (w, ht, frames) = (RUN + 44, 20, 2);
        let mut h = test_header(w as u32, ht as u32);
        h.frames = frames;
        let mut unit = crate::synth::test_units(19);
        let mut recs = Vec::new();
        for px in 0..w * ht * frames as usize {
            let (f, i) = (px / (w * ht), px % (w * ht));
            let (x, y) = ((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
            let level = 1.0 + (x / 40.0).floor();
            for _ in 0..(2 + (unit() * 8.0) as usize) {
                let v = level * (0.6 + 0.8 * unit() as f32);
                recs.push(Record::new(x, y, f as f32 + 0.5, [v, 0.5 * v, 0.2]));
            }
        }
        let stats = stats_of(&recs, &h, |_| true);
        let fields = Fields::new(&stats, w, ht, None);
        let k = Kernel::new(stats.iter().map(|s| s.x.n).max().unwrap_or(0));
        let mut film = Image::for_header(&h);
        window(&fields, &k, &h, 0, &mut film.data);
        let frame = w * ht;
        // Dense: rows 2–6 of the first block, columns 10–60.
        let dense: Vec<usize> = (2..7)
            .flat_map(|y| (10..61).map(move |x| y * w + x))
            .collect();
        let scattered: Vec<usize> = (0..2 * frame).step_by(37).collect();
        let mut mixed: Vec<usize> = dense.iter().chain(&scattered).copied().collect();
        mixed.extend((9 * w..10 * w).chain([0, frame - 1, frame, 2 * frame - 1]));
        mixed.sort();
        mixed.dedup();
        assert_eq!(plan(&dense, w, ht).len(), 1);
        assert_eq!(plan(&scattered[..3], w, ht).len(), 3);
        for pixels in [dense, scattered, mixed] {
            let got = window_at(&fields, &k, &h, &pixels);
            for (px, got) in pixels.iter().zip(got) {
                let want = film.data[*px];
                assert_eq!(got.map(f64::to_bits), want.map(f64::to_bits), "pixel {px}");
            }
        }
    }

    /// Where the squares cannot decide (t²·s in the subnormal range, or
    /// a pair on the boundary itself), the window takes the written form,
    /// pair by pair, as the per-pixel window does.
    #[test]
    fn the_window_decides_the_pairs_its_run_cannot() {
        let (w, ht) = (40, 3);
        let crit = 2.0f64;
        let k = Kernel {
            t: vec![crit; 64],
            t2: vec![crit * crit; 64],
            ..Kernel::new(1)
        };
        let px = w * ht;
        let tiny: f64 = 1e-300;
        // y at 0, 1 or 2 times exactly t·√(2·se2): on the boundary, subnormal.
        let on_edge = crit * (2.0 * tiny).sqrt();
        let y: Vec<f64> = (0..px).map(|i| (i % 3) as f64 * on_edge).collect();
        let f = Fields {
            features: None,
            n: vec![8; px],
            mean: std::array::from_fn(|c| (0..px).map(|i| (i * (c + 1)) as f64).collect()),
            y_mean: std::array::from_fn(|_| y.clone()),
            se2: std::array::from_fn(|_| vec![tiny; px]),
            // Far above the patches' differences: every patch passes, and
            // the pairs' own test decides.
            spread: vec![1.0; px],
            limit: vec![f64::INFINITY; px],
            patch_spread: super::super::fields::patch_spreads(&vec![8; px], &vec![1.0; px], w, ht),
        };
        let h = test_header(w as u32, ht as u32);
        let mut got = Image::for_header(&h);
        window(&f, &k, &h, 0, &mut got.data);
        let want = denoise_per_pixel(&f, &k, (w, ht), true);
        for (px, (got, want)) in got.data.iter().zip(&want).enumerate() {
            assert_eq!(got.map(f64::to_bits), want.map(f64::to_bits), "pixel {px}");
        }
        // Levels one apart agree and two apart do not: the window left
        // some pairs out, so it is not the mean of the whole window.
        let all = denoise_per_pixel(
            &Fields {
                y_mean: std::array::from_fn(|_| vec![0.0; px]),
                ..f
            },
            &k,
            (w, ht),
            true,
        );
        assert!(got.data.iter().zip(&all).any(|(g, a)| g != a));
    }

    /// The four-at-a-time loop gives the pair-by-pair loop's weights and
    /// verdict on runs of any length whose pixels differ lane by lane:
    /// counts (0, 1, 2 and more), spreads and their limits, zero
    /// variances, equal and unequal means.
    #[test]
    fn the_vector_run_is_the_portable_run() {
        let mut unit = crate::synth::test_units(11);
        let px = 256;
        for trial in 0..300 {
            let mut pick = |choices: &[f64]| choices[(unit() * choices.len() as f64) as usize];
            let n: Vec<u32> = (0..px)
                .map(|_| pick(&[0.0, 1.0, 2.0, 5.0, 8.0, 16.0]) as u32)
                .collect();
            let y: Vec<f64> = (0..px).map(|_| pick(&[0.0, 1.0, 1.5, 2.0, 9.0])).collect();
            let se2: Vec<f64> = (0..px).map(|_| pick(&[0.0, 0.0, 0.01, 0.3, 2.0])).collect();
            let f = Fields {
                features: None,
                mean: std::array::from_fn(|c| (0..px).map(|i| (i + c) as f64).collect()),
                y_mean: std::array::from_fn(|c| y.iter().map(|v| v + c as f64 * 0.1).collect()),
                se2: std::array::from_fn(|_| se2.clone()),
                spread: se2.iter().map(|v| 3.0 * v).collect(),
                limit: (0..px)
                    .map(|_| pick(&[0.0, 0.5, 5.0, f64::INFINITY]))
                    .collect(),
                patch_spread: vec![f64::NAN; px],
                n,
            };
            let k = Kernel::new(16);
            let len = 1 + trial % 120;
            let (mut vector, mut portable) = (vec![0.0; len], vec![-1.0; len]);
            let pairs = Pairs {
                ws: 0.7,
                p: 3,
                q: 130,
            };
            let undecided = pair_weights(&f, &k, &pairs, &mut vector);
            let undecided_portable = pair_weights_portable(&f, &k, &pairs, &mut portable, 0);
            assert_eq!(undecided, undecided_portable, "trial {trial}");
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&vector), bits(&portable), "trial {trial}");
        }
    }
}
