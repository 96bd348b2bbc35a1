//! A statistical Monte Carlo denoiser after Sakai et al., *A Statistical
//! Approach to Monte Carlo Denoising* (SIGGRAPH Asia 2024): a pixel
//! averages those neighbours whose samples a Welch t-test cannot tell
//! from its own, and no others (docs/filter.md §3, F11). The dump gives
//! every pixel's exact sample statistics, which is what the test needs;
//! fed with the filter's accepted samples, an outlier neither widens a
//! pixel's variance nor drags its mean.
//!
//! Per pixel and channel, the samples' mean x̄ (what is averaged) and, for
//! the test, the mean ȳ and unbiased variance s² of their Box-Cox
//! transform y = (x^λ − 1)/λ with λ = 1/2 (radiance is skewed; the
//! transform brings a pixel's samples nearer the normal the test assumes;
//! negative values count as 0). Pixel q is compatible with p when, on
//! every channel, |ȳ_p − ȳ_q| ≤ t(α, ν)·√(s_p²/n_p + s_q²/n_q), with
//! α = 0.05 two-sided and ν = n_p + n_q − 2 degrees of freedom (at 0.005
//! the test merged a highlight into its neighbours more often: docs/RESULTS.md,
//! "The guided image"). The
//! output is the mean of the compatible pixels of the (2R + 1)² window,
//! each weighted by its sample count and a spatial Gaussian of σ = R/2:
//! the samples of every compatible pixel pooled. A pixel with fewer than
//! two samples keeps its mean. Deterministic and thread-invariant: each
//! output pixel is one sum in a fixed order.
//!
//! Two pixels the test cannot tell apart still do not average each other
//! when one is far noisier: its s²/n (summed over the channels) above
//! [`NOISIER`] times the other's, each pixel's taken as at least the
//! median of its 3 × 3 neighbourhood's. A pixel holding an outlier the
//! filter accepted has so wide a variance that the test alone passes it
//! into every neighbour's average, each of which counts its samples at
//! full weight: its energy is counted once per neighbour (on a synthetic
//! field with 2 % fireflies at 8 spp, 7.8× the reference's energy in all).
//! Left out both ways, the pixel keeps its own samples' mean and its
//! energy stays counted once. The neighbourhood's median keeps a pixel
//! whose few samples all missed a rare bright path, and so look quiet,
//! averaging with its neighbours. An addition to Sakai et al.
//! (docs/RESULTS.md, "The guided image").

use super::Image;
use super::confidence::Moments;
use super::per_pixel;
use crate::dump::{Header, Record};
use crate::par::prelude::*;

/// The window's radius R, in pixels.
pub const RADIUS: usize = 8;
/// Box-Cox λ.
const LAMBDA: f64 = 0.5;
/// Two-sided significance of the test.
const ALPHA: f64 = 0.05;
/// Two pixels average each other only when neither's s²/n exceeds this
/// many times the other's (or the other's neighbourhood median): standard
/// errors within 4× (docs/RESULTS.md, "The guided image").
pub const NOISIER: f64 = 16.0;

/// One pixel's statistics: the moments of its samples, which the
/// confidence interval of the same samples reads too, and those of their
/// Box-Cox transform.
#[derive(Clone, Copy, Default)]
pub(crate) struct Stats {
    x: Moments,
    /// Mean and Σ(y − ȳ)² of the Box-Cox transformed samples (Welford).
    y_mean: [f64; 3],
    y_m2: [f64; 3],
}

impl AsRef<Stats> for Stats {
    fn as_ref(&self) -> &Stats {
        self
    }
}

impl AsRef<Moments> for Stats {
    fn as_ref(&self) -> &Moments {
        &self.x
    }
}

impl Stats {
    fn add(&mut self, x: [f64; 3]) {
        self.x.add(x);
        let n = self.x.n as f64;
        for (c, x) in x.into_iter().enumerate() {
            let y = box_cox(x);
            let d = y - self.y_mean[c];
            self.y_mean[c] += d / n;
            self.y_m2[c] += d * (y - self.y_mean[c]);
        }
    }

    /// s²/n of the transformed mean, per channel.
    fn se2(&self) -> [f64; 3] {
        let n = self.x.n as f64;
        self.y_m2.map(|m| m / (n - 1.0) / n)
    }
}

/// What the window reads of every pixel, one array per field: a run of a
/// row's pixels is one slice of each, so the window's loop along the run
/// runs in vector registers.
struct Fields {
    n: Vec<u32>,
    /// Mean of the samples.
    mean: [Vec<f64>; 3],
    /// Mean of the transformed samples.
    y_mean: [Vec<f64>; 3],
    /// [`Stats::se2`].
    se2: [Vec<f64>; 3],
    /// Σ over the channels of `se2`: how noisy the pixel's mean is.
    spread: Vec<f64>,
    /// [`spread_limits`].
    limit: Vec<f64>,
}

impl Fields {
    /// What the test reads of each pixel, made once: s²/n would otherwise
    /// be divided out again for each of the (2R + 1)² pixels around it.
    fn new<S: AsRef<Stats> + Sync>(stats: &[S], w: usize, ht: usize) -> Fields {
        let stats: Vec<&Stats> = stats.iter().map(AsRef::as_ref).collect();
        let channel = |f: &(dyn Fn(&Stats) -> [f64; 3] + Sync)| -> [Vec<f64>; 3] {
            std::array::from_fn(|c| stats.par_iter().map(|s| f(s)[c]).collect())
        };
        let se2 = channel(&|s| s.se2());
        let spread: Vec<f64> = (0..stats.len())
            .into_par_iter()
            .map(|px| se2.iter().map(|c| c[px]).sum())
            .collect();
        let n: Vec<u32> = stats.par_iter().map(|s| s.x.n).collect();
        let limit = spread_limits(&n, &spread, w, ht);
        Fields {
            mean: channel(&|s| s.x.mean),
            y_mean: channel(&|s| s.y_mean),
            n,
            se2,
            spread,
            limit,
        }
    }

    /// Whether pixels p and q (p with two samples or more) average each
    /// other: q has two samples or more, neither is far noisier
    /// ([`NOISIER`]), and the test passes on every channel, as [`agree`]
    /// decides it.
    fn compatible(&self, p: usize, q: usize, k: &Kernel) -> bool {
        let (spread, limit) = (&self.spread, &self.limit);
        if self.n[q] < 2 || spread[q] > limit[p] || spread[p] > limit[q] {
            return false;
        }
        let df = (self.n[p] + self.n[q] - 2) as usize;
        (0..3).fold(true, |all, c| {
            let (y, se2) = (&self.y_mean[c], &self.se2[c]);
            all & agree(y[p], y[q], se2[p] + se2[q], k.t[df], k.t2[df])
        })
    }
}

/// Per pixel, the largest spread a pixel it averages with may have:
/// [`NOISIER`] × the larger of the pixel's spread and the median spread of
/// its 3 × 3 neighbourhood (same frame, pixels with two samples or more).
fn spread_limits(n: &[u32], spread: &[f64], w: usize, ht: usize) -> Vec<f64> {
    let mut limit = vec![0.0; n.len()];
    limit.par_iter_mut().enumerate().for_each(|(px, l)| {
        let (frame, i) = (px / (w * ht), px % (w * ht));
        let (x, y) = (i % w, i / w);
        let base = frame * w * ht;
        let mut around = [0.0f64; 9];
        let mut count = 0;
        for ny in y.saturating_sub(1)..(y + 2).min(ht) {
            for nx in x.saturating_sub(1)..(x + 2).min(w) {
                let q = base + ny * w + nx;
                if n[q] >= 2 {
                    around[count] = spread[q];
                    count += 1;
                }
            }
        }
        let around = &mut around[..count];
        around.sort_by(f64::total_cmp);
        let median = around.get(count / 2).copied().unwrap_or(0.0);
        *l = NOISIER * spread[px].max(median);
    });
    limit
}

/// λ = 1/2 makes x^λ the square root, correctly rounded, which glibc's
/// `powf(0.5)` matched bit for bit on every f32 sample (docs/BENCHMARKS.md,
/// "statmc's square root") at a higher cost.
fn box_cox(x: f64) -> f64 {
    const { assert!(LAMBDA == 0.5) };
    (x.max(0.0).sqrt() - 1.0) / LAMBDA
}

/// z of the standard normal at upper tail `p` (Acklam's rational
/// approximation, relative error below 1.2·10⁻⁹ for p in (0, 0.5]).
fn normal_quantile(p: f64) -> f64 {
    let q = (-2.0 * p.ln()).sqrt();
    let c = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    let d = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    -(((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5])
        / ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0)
}

/// Student's t at upper tail `p` with `df` degrees of freedom (the
/// Cornish-Fisher expansion about the normal; within 1 % for df ≥ 3 at
/// the tails used here).
fn t_quantile(p: f64, df: f64) -> f64 {
    let z = normal_quantile(p);
    let (z3, z5, z7) = (z.powi(3), z.powi(5), z.powi(7));
    z + (z3 + z) / (4.0 * df)
        + (5.0 * z5 + 16.0 * z3 + 3.0 * z) / (96.0 * df * df)
        + (3.0 * z7 + 19.0 * z5 + 17.0 * z3 - 15.0 * z) / (384.0 * df.powi(3))
}

/// Whether two pixels' transformed means ȳ_p, ȳ_q agree on a channel,
/// given s = s_p²/n_p + s_q²/n_q: |ȳ_p − ȳ_q| ≤ t·√s, exactly as written.
/// The squares decide first, without the square root, wherever they are
/// clear of the boundary by far more than the rounding of either form (a
/// relative [`MARGIN`], against about 10⁻¹⁵), and in the normal range
/// ([`TINY`]); the written form decides the rest, so the result is the
/// written form's, bit for bit.
#[inline]
fn agree(y_p: f64, y_q: f64, s: f64, crit: f64, crit2: f64) -> bool {
    let d = (y_p - y_q).abs();
    let bound2 = crit2 * s;
    let d2 = d * d;
    let (inside, outside) = (d2 < bound2 * (1.0 - MARGIN), d2 > bound2 * (1.0 + MARGIN));
    // Which side is not predictable; whether either is clear nearly always is.
    if bound2 > TINY && (inside | outside) {
        inside
    } else {
        d <= crit * s.sqrt()
    }
}

/// [`agree`]'s margin around the boundary, relative.
const MARGIN: f64 = 1e-12;
/// Below this t²·s the squares may have lost bits: [`agree`] takes the
/// written form.
const TINY: f64 = 1e-290;

/// The window's constants.
struct Kernel {
    /// t(α/2, ν) for ν = 0 … 2 × the largest n (one entry per ν).
    t: Vec<f64>,
    t2: Vec<f64>,
    /// The spatial Gaussian at each offset 0 … R along an axis.
    spatial: [f64; RADIUS + 1],
}

impl Kernel {
    fn new(largest: u32) -> Kernel {
        let t: Vec<f64> = (0..=2 * largest as usize)
            .map(|df| t_quantile(ALPHA / 2.0, df.max(1) as f64))
            .collect();
        let t2 = t.iter().map(|t| t * t).collect();
        let sigma = RADIUS as f64 / 2.0;
        let spatial = std::array::from_fn(|d| (-((d * d) as f64) / (2.0 * sigma * sigma)).exp());
        Kernel { t, t2, spatial }
    }
}

/// The denoised image of the valid samples `keep(i)` picks (record i):
/// the accepted ones.
pub fn denoise(records: &[Record], h: &Header, keep: impl Fn(usize) -> bool + Sync) -> Image {
    // The statistics go once the window's fields are made.
    let window = Window::new(&stats_of(records, h, keep), h);
    window.denoise(h)
}

/// What the window reads, made from the pixels' statistics ([`stats_of`]),
/// which it no longer needs.
pub(crate) struct Window {
    fields: Fields,
}

impl Window {
    pub(crate) fn new<S: AsRef<Stats> + Sync>(stats: &[S], h: &Header) -> Window {
        let (w, ht) = (h.width as usize, h.height as usize);
        Window {
            fields: Fields::new(stats, w, ht),
        }
    }

    /// The denoised image.
    pub(crate) fn denoise(&self, h: &Header) -> Image {
        let mut img = Image::for_header(h);
        self.denoise_into(h, 0, &mut img.data);
        img
    }

    /// The denoised pixels of the film `h` that `out` holds, from pixel
    /// `first` (both whole rows) on: a band's own rows of the window made
    /// from the band's statistics with [`HALO`] rows either side are the
    /// whole film's.
    pub(crate) fn denoise_into(&self, h: &Header, first: usize, out: &mut [[f64; 3]]) {
        let kernel = Kernel::new(self.fields.n.iter().copied().max().unwrap_or(0));
        window(&self.fields, &kernel, h, first, out);
    }
}

/// Rows either side of a pixel that its window reads, with the 3 × 3
/// neighbourhoods of [`spread_limits`] at the window's edge.
pub(crate) const HALO: usize = RADIUS + 1;

/// The mean of its window's compatible pixels of each pixel `out` holds,
/// from pixel `first` (whole rows) on.
fn window(fields: &Fields, kernel: &Kernel, h: &Header, first: usize, out: &mut [[f64; 3]]) {
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

/// [`Stats`]' update: in AVX2 where the CPU has it (the same bits).
pub(crate) fn stats_adder() -> fn(&mut Stats, [f64; 3]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: only returned where the CPU has AVX2 (checked just above).
        return |s, x| unsafe { avx2::add(s, x) };
    }
    Stats::add
}

/// Every pixel's statistics of the valid samples `keep(i)` picks, in
/// file order, on every thread of the pool.
pub(crate) fn stats_of(
    records: &[Record],
    h: &Header,
    keep: impl Fn(usize) -> bool + Sync,
) -> Vec<Stats> {
    let bands = crate::par::current_num_threads();
    per_pixel::fold(records, h, bands, keep, stats_adder())
}

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
/// compatible neighbours, weighted by sample count and the spatial
/// Gaussian. The window is taken offset by offset in its order (row by
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
/// here where the squares are clear of [`agree`]'s boundary, or where
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
struct Pairs {
    ws: f64,
    p: usize,
    q: usize,
}

/// [`pair_weights`] from pair `from` on, one pair at a time.
#[inline(always)]
fn pair_weights_portable(
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

/// [`pair_weights_portable`] four pairs at a time in AVX2 registers: the
/// same comparisons (ordered, as Rust's on f64) and the same products in
/// the same order, so the same bits. [`Stats::add`] with its three
/// channels in one register.
#[cfg(target_arch = "x86_64")]
mod avx2;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recon::test_header;

    #[test]
    fn quantiles_against_tables() {
        assert!((normal_quantile(0.0025) - 2.807_033_768).abs() < 1e-6);
        assert!((normal_quantile(0.025) - 1.959_963_985).abs() < 1e-6);
        // t tables: t(0.0025, 30) = 3.0298, t(0.0025, 10) = 3.5814.
        assert!((t_quantile(0.0025, 30.0) - 3.0298).abs() < 2e-3);
        assert!((t_quantile(0.0025, 10.0) - 3.5814).abs() < 2e-2);
    }

    /// Two flat halves of a film: each pixel averages its own half only
    /// (the test tells 1 from 5 with 16 samples of spread 0.1), so the
    /// edge stays sharp and the noise drops.
    #[test]
    fn averages_within_a_region_and_not_across_an_edge() {
        let h = test_header(8, 4);
        let mut recs = Vec::new();
        for y in 0..4 {
            for x in 0..8 {
                let level = if x < 4 { 1.0 } else { 5.0 };
                for s in 0..16 {
                    let v = level + 0.1 * ((s * 7 + x * 3 + y) % 5) as f32 - 0.2;
                    recs.push(Record::new(x as f32 + 0.5, y as f32 + 0.5, 0.0, [v; 3]));
                }
            }
        }
        let img = denoise(&recs, &h, |_| true);
        for y in 0..4 {
            for x in 0..8 {
                let want = if x < 4 { 1.0 } else { 5.0 };
                let got = img.data[y * 8 + x][0];
                assert!((got - want).abs() < 0.05, "({x}, {y}): {got}");
            }
        }
    }

    /// A pixel holding an outlier passes every neighbour's test (its
    /// variance is wide) but, far noisier, averages with none of them:
    /// its energy is counted once, in its own pixel.
    #[test]
    fn a_far_noisier_neighbour_is_left_out() {
        let h = test_header(5, 5);
        let mut recs = Vec::new();
        for y in 0..5 {
            for x in 0..5 {
                for s in 0..8 {
                    let mut v = 1.0 + 0.05 * ((s * 3 + x + 2 * y) % 4) as f32;
                    if (x, y, s) == (2, 2, 0) {
                        v = 500.0;
                    }
                    recs.push(Record::new(x as f32 + 0.5, y as f32 + 0.5, 0.0, [v; 3]));
                }
            }
        }
        let img = denoise(&recs, &h, |_| true);
        for (px, v) in img.data.iter().enumerate() {
            if px != 12 {
                assert!((v[0] - 1.075).abs() < 0.05, "pixel {px}: {v:?}");
            }
        }
        let own: f64 = recs[12 * 8..13 * 8].iter().map(|r| r.r as f64).sum::<f64>() / 8.0;
        assert!(
            (img.data[12][0] - own).abs() < 1e-9,
            "{:?} against {own}",
            img.data[12]
        );
    }

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
    /// the compatible neighbours' means, each weighted by its count and
    /// the spatial Gaussian, the others skipped.
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
            let img = denoise(&recs, &h, |i| i % 31 != 5);
            let stats = stats_of(&recs, &h, |i| i % 31 != 5);
            let k = Kernel::new(stats.iter().map(|s| s.x.n).max().unwrap_or(0));
            let want = denoise_per_pixel(&Fields::new(&stats, w, ht), &k, w, ht);
            for (px, (got, want)) in img.data.iter().zip(&want).enumerate() {
                let bits = |v: &[f64; 3]| v.map(f64::to_bits);
                assert_eq!(bits(got), bits(want), "{w} × {ht} × {frames}, pixel {px}");
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

    /// The vector add gives the scalar add's statistics bit for bit, over
    /// runs of samples from negative and zero (either sign) through
    /// subnormal to far above the white.
    #[test]
    fn the_vector_add_is_the_scalar_add() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            eprintln!("SKIPPED: no AVX2 on this CPU");
            return;
        }
        let mut unit = crate::synth::test_units(17);
        let values = [0.0, -0.0, -0.3, 1e-310, 3e-8, 0.2, 1.0, 7.5, 4e4, 3e38];
        let mut checked = 0;
        for _ in 0..500 {
            let (mut scalar, mut vector) = (Stats::default(), Stats::default());
            for _ in 0..(unit() * 70.0) as usize {
                let mut c = || values[(unit() * values.len() as f64) as usize] * (0.5 + unit());
                let x = [c(), c(), c()];
                scalar.add(x);
                // SAFETY: the CPU has AVX2 (checked above).
                unsafe { avx2::add(&mut vector, x) };
                let bits = |s: &Stats| {
                    let f = [s.x.mean, s.x.m2, s.y_mean, s.y_m2];
                    (s.x.n, f.map(|a| a.map(f64::to_bits)))
                };
                assert_eq!(bits(&scalar), bits(&vector), "after {x:?}");
                checked += 1;
            }
        }
        assert!(checked > 10_000, "{checked}");
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

    /// An outlier the caller leaves out does not move its pixel.
    #[test]
    fn left_out_samples_do_not_count() {
        let h = test_header(1, 1);
        let mut recs: Vec<Record> = (0..8)
            .map(|i| Record::new(0.5, 0.5, 0.0, [1.0 + 0.01 * i as f32; 3]))
            .collect();
        recs.push(Record::new(0.5, 0.5, 0.0, [1000.0; 3]));
        let img = denoise(&recs, &h, |i| i < 8);
        assert!((img.data[0][0] - 1.035).abs() < 1e-6, "{:?}", img.data[0]);
    }
}
