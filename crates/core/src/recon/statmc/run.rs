//! statmc's window over the film, a run of a row's pixels at a time:
//! each offset of the window for the whole run, the pairs decided four at
//! a time in vector registers where the CPU has them.

use super::RADIUS;
#[cfg(target_arch = "x86_64")]
use super::avx2;
use super::fields::Fields;
use super::welch::{Kernel, MARGIN, TINY};
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
    out.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(r, out)| {
            let row = first / w.max(1) + r;
            let (base, y) = ((row / ht) * w * ht, row % ht);
            for (r, out) in out.chunks_mut(RUN).enumerate() {
                let xs = r * RUN..r * RUN + out.len();
                let run = Run { w, ht, base, y, xs };
                window_run(fields, kernel, &run, out);
            }
        });
}

/// The mean of its window's compatible pixels at each of `pixels`
/// (ascending), in their order: each pixel's the same bits as
/// [`window`]'s, whatever the run it is taken in. Pixels of a row
/// [`GAP`] or fewer apart are taken in one run, the pixels between them
/// made and dropped.
pub(super) fn window_at(
    fields: &Fields,
    kernel: &Kernel,
    h: &Header,
    pixels: &[usize],
) -> Vec<[f64; 3]> {
    let (w, ht) = (h.width as usize, h.height as usize);
    // Runs of a row, RUN pixels at most, each with the pixels it gives.
    let mut runs: Vec<(Run, &[usize])> = Vec::new();
    let mut i = 0;
    while i < pixels.len() {
        let (row, x) = (pixels[i] / w, pixels[i] % w);
        let mut len = 1;
        while let Some(&next) = pixels.get(i + len) {
            let end = next - row * w;
            if next / w != row || end - pixels[i + len - 1] % w > GAP || end >= x + RUN {
                break;
            }
            len += 1;
        }
        let (base, y) = ((row / ht) * w * ht, row % ht);
        let xs = x..pixels[i + len - 1] % w + 1;
        runs.push((Run { w, ht, base, y, xs }, &pixels[i..i + len]));
        i += len;
    }
    let given: Vec<Vec<[f64; 3]>> = runs
        .into_par_iter()
        .map(|(run, pixels)| {
            let mut all = vec![[0.0; 3]; run.xs.len()];
            window_run(fields, kernel, &run, &mut all);
            let first = run.base + run.y * run.w + run.xs.start;
            pixels.iter().map(|px| all[px - first]).collect()
        })
        .collect();
    given.concat()
}

/// Pixels of a row this far apart or nearer are taken in one run of
/// [`window_at`]: each run starts (2R + 1)² offsets, which costs about
/// as much as this many pixels more of the run.
const GAP: usize = 32;

/// Pixels per run of a row that the window takes at once: the run's
/// fields and its neighbours' stay in the core's cache over the window's
/// (2R + 1)² offsets.
const RUN: usize = 256;

/// Pixels `xs` of row y of the frame whose first pixel is `base`, on a
/// w × ht film.
struct Run {
    w: usize,
    ht: usize,
    base: usize,
    y: usize,
    xs: std::ops::Range<usize>,
}

/// The output of the pixels of `run`, into `out`: each pixel's mean of its
/// compatible neighbours, weighted by sample count, the spatial Gaussian
/// and the features' weight where there is a guide. The window is taken offset by offset in its order (row by
/// row, left to right), each offset for the whole run, so each pixel's
/// sums add the same terms in the same order as a loop over its own
/// window; a neighbour left out adds 0, which changes no sum (a sum that
/// starts at +0 is never −0, and a mean is finite).
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
        y,
        ref xs,
    } = *run;
    let mut sum = [[0.0f64; RUN]; 3];
    let mut weight = [0.0f64; RUN];
    let mut weights = [0.0f64; RUN];
    let r = RADIUS as isize;
    for ny in y.saturating_sub(RADIUS)..(y + RADIUS + 1).min(ht) {
        let wy = k.spatial[ny.abs_diff(y)];
        for dx in -r..=r {
            let ws = wy * k.spatial[dx.unsigned_abs()];
            // The run's pixels whose neighbour at x + dx is on the film.
            let lo = xs.start.max((-dx).max(0) as usize);
            let hi = xs.end.min((w as isize - dx).clamp(0, w as isize) as usize);
            if lo >= hi {
                continue;
            }
            let p = base + y * w + lo;
            let q = (base + ny * w + lo).wrapping_add_signed(dx);
            let slots = lo - xs.start..hi - xs.start;
            let run = &mut weights[slots.clone()];
            if pair_weights(f, k, &Pairs { ws, p, q }, run) {
                for (i, wq) in run.iter_mut().enumerate() {
                    let same = f.n[p + i] >= 2 && f.compatible(p + i, q + i, k);
                    *wq = ws * f.n[q + i] as f64 * f64::from(u8::from(same));
                }
            }
            if let Some(features) = &f.features {
                features.weigh(p, q, run);
            }
            for (sum, mean) in sum.iter_mut().zip(&f.mean) {
                let m = &mean[q..q + run.len()];
                for ((s, wq), m) in sum[slots.clone()].iter_mut().zip(&*run).zip(m) {
                    *s += wq * m;
                }
            }
            for (s, wq) in weight[slots].iter_mut().zip(&*run) {
                *s += wq;
            }
        }
    }
    let p = base + y * w + xs.start;
    for (i, out) in out.iter_mut().enumerate() {
        let n = f.n[p + i];
        if n >= 2 {
            // p is always compatible with itself.
            *out = std::array::from_fn(|c| sum[c][i] / weight[i]);
        } else if n == 1 {
            *out = std::array::from_fn(|c| f.mean[c][p + i]);
        }
    }
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
                };
                let k = Kernel {
                    t: vec![crit; 15],
                    t2: vec![crit * crit; 15],
                    spatial: [1.0; RADIUS + 1],
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
    /// the compatible neighbours' means, each weighted by its count, the
    /// spatial Gaussian and the features' weight, the others skipped.
    fn denoise_per_pixel(f: &Fields, k: &Kernel, w: usize, ht: usize) -> Vec<[f64; 3]> {
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
                        if !f.compatible(px, q, k) {
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

    /// The window taken offset by offset along runs of a row gives each
    /// pixel the bits of its own window's loop: films narrower than the
    /// window and wider than a run, frames, pixels with 0, 1 and many
    /// samples, zero-variance pixels (equal and unequal), outliers.
    #[test]
    fn the_window_by_runs_is_the_per_pixel_window() {
        let mut unit = crate::synth::test_units(7);
        for (w, ht, frames) in [(1, 1, 1), (5, 3, 2), (19, 23, 1), (2 * RUN + 37, 4, 2)] {
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
                let want = denoise_per_pixel(&Fields::new(&stats, w, ht, guide), &k, w, ht);
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
            spatial: Kernel::new(1).spatial,
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
            spread: vec![0.0; px],
            limit: vec![f64::INFINITY; px],
        };
        let h = test_header(w as u32, ht as u32);
        let mut got = Image::for_header(&h);
        window(&f, &k, &h, 0, &mut got.data);
        let want = denoise_per_pixel(&f, &k, w, ht);
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
            w,
            ht,
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
