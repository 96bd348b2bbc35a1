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
use crate::dump::{Header, Record, Validity};
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

/// One pixel's statistics.
#[derive(Clone, Copy, Default)]
struct Stats {
    n: u32,
    /// Mean of the samples.
    mean: [f64; 3],
    /// Mean and Σ(y − ȳ)² of the Box-Cox transformed samples (Welford).
    y_mean: [f64; 3],
    y_m2: [f64; 3],
}

impl Stats {
    fn add(&mut self, x: [f64; 3]) {
        self.n += 1;
        let n = self.n as f64;
        for (c, x) in x.into_iter().enumerate() {
            self.mean[c] += (x - self.mean[c]) / n;
            let y = box_cox(x);
            let d = y - self.y_mean[c];
            self.y_mean[c] += d / n;
            self.y_m2[c] += d * (y - self.y_mean[c]);
        }
    }

    /// s²/n of the transformed mean, per channel.
    fn se2(&self) -> [f64; 3] {
        let n = self.n as f64;
        self.y_m2.map(|m| m / (n - 1.0) / n)
    }
}

/// What the t-test reads of a pixel.
#[derive(Clone, Copy, Debug)]
struct Test {
    n: u32,
    y_mean: [f64; 3],
    /// [`Stats::se2`].
    se2: [f64; 3],
    /// Σ over the channels of `se2`: how noisy the pixel's mean is.
    spread: f64,
}

impl Test {
    fn of(s: &Stats) -> Test {
        let se2 = s.se2();
        Test {
            n: s.n,
            y_mean: s.y_mean,
            se2,
            spread: se2.iter().sum(),
        }
    }
}

/// Per pixel, the largest spread a pixel it averages with may have:
/// [`NOISIER`] × the larger of the pixel's spread and the median spread of
/// its 3 × 3 neighbourhood (same frame, pixels with two samples or more).
fn spread_limits(tests: &[Test], w: usize, ht: usize) -> Vec<f64> {
    let mut limit = vec![0.0; tests.len()];
    limit.par_iter_mut().enumerate().for_each(|(px, l)| {
        let (frame, i) = (px / (w * ht), px % (w * ht));
        let (x, y) = (i % w, i / w);
        let base = frame * w * ht;
        let mut around = [0.0f64; 9];
        let mut n = 0;
        for ny in y.saturating_sub(1)..(y + 2).min(ht) {
            for nx in x.saturating_sub(1)..(x + 2).min(w) {
                let t = &tests[base + ny * w + nx];
                if t.n >= 2 {
                    around[n] = t.spread;
                    n += 1;
                }
            }
        }
        let around = &mut around[..n];
        around.sort_by(f64::total_cmp);
        let median = around.get(n / 2).copied().unwrap_or(0.0);
        *l = NOISIER * tests[px].spread.max(median);
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

/// Whether two pixels' transformed means agree on channel `c`:
/// |ȳ_p − ȳ_q| ≤ t·√(s_p²/n_p + s_q²/n_q), exactly as written. The squares
/// decide first, without the square root, wherever they are clear of the
/// boundary by far more than the rounding of either form (a relative
/// 10⁻¹², against about 10⁻¹⁵), and in the normal range; the written form
/// decides the rest, so the result is the written form's, bit for bit.
#[inline]
fn agree(p: &Test, q: &Test, c: usize, crit: f64, crit2: f64) -> bool {
    const MARGIN: f64 = 1e-12;
    let d = (p.y_mean[c] - q.y_mean[c]).abs();
    let s = p.se2[c] + q.se2[c];
    let bound2 = crit2 * s;
    let d2 = d * d;
    let (inside, outside) = (d2 < bound2 * (1.0 - MARGIN), d2 > bound2 * (1.0 + MARGIN));
    // Which side is not predictable; whether either is clear nearly always is.
    if bound2 > 1e-290 && (inside | outside) {
        inside
    } else {
        d <= crit * s.sqrt()
    }
}

/// The denoised image of the valid samples `keep(i)` picks (record i):
/// the accepted ones.
pub fn denoise(records: &[Record], h: &Header, keep: impl Fn(usize) -> bool) -> Image {
    let (w, ht) = (h.width as usize, h.height as usize);
    let mut stats = vec![Stats::default(); h.pixels() * h.frames as usize];
    for (i, r) in records.iter().enumerate() {
        if r.validity(h) == Validity::Valid && keep(i) {
            stats[r.pixel_index(h)].add([r.r as f64, r.g as f64, r.b as f64]);
        }
    }
    // t(α/2, ν) for ν = 0 … 2 × the largest n (one entry per ν).
    let largest = stats.iter().map(|s| s.n).max().unwrap_or(0) as usize;
    let t: Vec<f64> = (0..=2 * largest)
        .map(|df| t_quantile(ALPHA / 2.0, df.max(1) as f64))
        .collect();
    let t2: Vec<f64> = t.iter().map(|t| t * t).collect();
    let sigma = RADIUS as f64 / 2.0;
    let spatial: Vec<f64> = (0..=RADIUS)
        .map(|d| (-((d * d) as f64) / (2.0 * sigma * sigma)).exp())
        .collect();
    // What the test reads of each pixel, made once: s²/n would otherwise
    // be divided out again for each of the (2R + 1)² pixels around it.
    // The tests take the statistics' place (an in-place collect), the
    // means moved out first.
    let means: Vec<[f64; 3]> = stats.iter().map(|s| s.mean).collect();
    let tests: Vec<Test> = stats.into_iter().map(|s| Test::of(&s)).collect();
    let limits = spread_limits(&tests, w, ht);
    let mut img = Image::for_header(h);
    img.data.par_iter_mut().enumerate().for_each(|(px, out)| {
        let (tp, limit) = (&tests[px], limits[px]);
        if tp.n == 0 {
            return;
        }
        if tp.n < 2 {
            *out = means[px];
            return;
        }
        let (frame, i) = (px / (w * ht), px % (w * ht));
        let (x, y) = (i % w, i / w);
        let base = frame * w * ht;
        let (mut sum, mut weight) = ([0.0f64; 3], 0.0f64);
        for ny in y.saturating_sub(RADIUS)..(y + RADIUS + 1).min(ht) {
            let wy = spatial[ny.abs_diff(y)];
            let row = base + ny * w;
            for nx in x.saturating_sub(RADIUS)..(x + RADIUS + 1).min(w) {
                let q_px = row + nx;
                let tq = &tests[q_px];
                if tq.n < 2 || tq.spread > limit || tp.spread > limits[q_px] {
                    continue;
                }
                let df = (tp.n + tq.n - 2) as usize;
                let same = (0..3).fold(true, |all, c| all & agree(tp, tq, c, t[df], t2[df]));
                // Added as 0 where the test fails (a mean is finite, so
                // 0 · m adds nothing): no branch on the test's outcome.
                let wq = wy * spatial[nx.abs_diff(x)] * tq.n as f64 * f64::from(u8::from(same));
                for (s, m) in sum.iter_mut().zip(means[q_px]) {
                    *s += wq * m;
                }
                weight += wq;
            }
        }
        // p is always compatible with itself.
        *out = sum.map(|s| s / weight);
    });
    img
}

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
    /// the subnormal range and at zero spread.
    #[test]
    fn agree_is_the_written_test() {
        let written = |p: &Test, q: &Test, c: usize, crit: f64| {
            (p.y_mean[c] - q.y_mean[c]).abs() <= crit * (p.se2[c] + q.se2[c]).sqrt()
        };
        let test = |y: f64, se2: f64| Test {
            n: 8,
            y_mean: [y; 3],
            se2: [se2; 3],
            spread: 3.0 * se2,
        };
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        // Both outcomes occur at the boundary: the cases test something.
        let mut outcomes = [0usize; 2];
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
                let (p, q) = (test(0.0, sp), test(d, sq));
                let want = written(&p, &q, 0, crit);
                assert_eq!(
                    agree(&p, &q, 0, crit, crit * crit),
                    want,
                    "{p:?} {q:?} {crit}"
                );
                if i % 4 != 0 {
                    outcomes[usize::from(want)] += 1;
                }
            }
        }
        assert!(outcomes[0] > 1000 && outcomes[1] > 1000, "{outcomes:?}");
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
