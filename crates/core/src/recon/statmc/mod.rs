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
//! α = 0.001 two-sided and ν = n_p + n_q − 2 degrees of freedom, and when
//! their 3 × 3 patches pass the same question pooled: the pairs
//! (p + u, q + u) summed, Σ (ȳ_p+u − ȳ_q+u)² against the χ² bound at
//! [`PATCH_ALPHA`] times Σ (s²/n of both) (docs/filter.md F11). One pair
//! at 64 samples cannot tell a gradient or a texture from noise; nine
//! pooled can, so the pair's own test can be loose and still stop at
//! edges, and it still holds a one-pixel highlight a patch would pass.
//! The patch test is ours, after non-local means' patch distances
//! (docs/RESULTS.md, "The guided image"). The
//! output is the mean of the compatible pixels of the (2R + 1)² window,
//! each weighted by its sample count and a spatial Gaussian of σ = R/2
//! (and by the renderer's features where given: [`Guide`]): the samples
//! of every compatible pixel pooled. A pixel with fewer than
//! two samples keeps its mean. Deterministic and thread-invariant: each
//! output pixel is one sum in a fixed order.
//!
//! Two pixels the test cannot tell apart still do not average each other
//! when one is far noisier: its s²/n (summed over the channels) above
//! [`NOISIER`] times the other's, each pixel's taken as at least the
//! upper quartile of its 3 × 3 neighbourhood's. A pixel holding an outlier the
//! filter accepted has so wide a variance that the test alone passes it
//! into every neighbour's average, each of which counts its samples at
//! full weight: its energy is counted once per neighbour (on a synthetic
//! field with 2 % fireflies at 8 spp, 7.8× the reference's energy in all).
//! Left out both ways, the pixel keeps its own samples' mean and its
//! energy stays counted once. The neighbourhood's upper quartile keeps a
//! pixel whose few samples all missed a rare bright path, and so look
//! quiet, averaging with its neighbours: where three of nine pixels hold
//! such a path it is the region's noise, which the average should take,
//! and one alone still stands apart. An addition to Sakai et al.
//! (docs/RESULTS.md, "The guided image").

use super::Image;
use super::confidence::Moments;
use super::per_pixel;
use crate::dump::{Header, Record};

/// The window's radius R, in pixels.
pub const RADIUS: usize = 8;
/// Box-Cox λ.
const LAMBDA: f64 = 0.5;
/// Two-sided significance of the pixels' own test.
const ALPHA: f64 = 0.001;
/// The patches' width: each pixel's test is made again over the pairs of
/// the PATCH × PATCH pixels around the two.
const PATCH: usize = 3;
/// Upper-tail significance of the patch test.
const PATCH_ALPHA: f64 = 0.001;
/// Two pixels average each other only when neither's s²/n exceeds this
/// many times the other's (or its neighbourhood's upper quartile): standard
/// errors within 4× (docs/RESULTS.md, "The guided image").
pub const NOISIER: f64 = 16.0;

mod features;
mod fields;
mod run;
mod welch;

pub use features::{ALBEDO_SD, Guide, NORMAL_SD};

/// [`run::pair_weights_portable`] four pairs at a time in AVX2 registers: the
/// same comparisons (ordered, as Rust's on f64) and the same products in
/// the same order, so the same bits. [`Stats::add`] with its three
/// channels in one register.
#[cfg(target_arch = "x86_64")]
mod avx2;

use fields::Fields;
use run::{window, window_at};
use welch::Kernel;

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

/// λ = 1/2 makes x^λ the square root, correctly rounded, which glibc's
/// `powf(0.5)` matched bit for bit on every f32 sample (docs/BENCHMARKS.md,
/// "statmc's square root") at a higher cost.
fn box_cox(x: f64) -> f64 {
    const { assert!(LAMBDA == 0.5) };
    (x.max(0.0).sqrt() - 1.0) / LAMBDA
}

/// The denoised image of the valid samples `keep(i)` picks (record i):
/// the accepted ones.
pub fn denoise(
    records: &[Record],
    h: &Header,
    keep: impl Fn(usize) -> bool + Sync,
    guide: Option<Guide>,
) -> Image {
    // The statistics go once the window's fields are made.
    let window = Window::new(&stats_of(records, h, keep), h, guide);
    window.denoise(h)
}

/// What the window reads, made from the pixels' statistics ([`stats_of`]),
/// which it no longer needs.
pub(crate) struct Window {
    fields: Fields,
}

impl Window {
    pub(crate) fn new<S: AsRef<Stats> + Sync>(
        stats: &[S],
        h: &Header,
        guide: Option<Guide>,
    ) -> Window {
        let (w, ht) = (h.width as usize, h.height as usize);
        Window {
            fields: Fields::new(stats, w, ht, guide),
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

    /// The denoised values at `pixels` of the film `h` (ascending), in
    /// their order: each one [`Window::denoise`]'s, which depends only on
    /// the statistics of the pixels within [`HALO`] of it.
    pub(crate) fn denoise_at(&self, h: &Header, pixels: &[usize]) -> Vec<[f64; 3]> {
        let kernel = Kernel::new(self.fields.n.iter().copied().max().unwrap_or(0));
        window_at(&self.fields, &kernel, h, pixels)
    }
}

/// Rows either side of a pixel that its window reads, with the 3 × 3
/// neighbourhoods of [`fields::spread_limits`] and the patch test's
/// 3 × 3 patches at the window's edge.
pub(crate) const HALO: usize = RADIUS + 1;

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recon::test_header;

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
        let img = denoise(&recs, &h, |_| true, None);
        for y in 0..4 {
            for x in 0..8 {
                let want = if x < 4 { 1.0 } else { 5.0 };
                let got = img.data[y * 8 + x][0];
                assert!((got - want).abs() < 0.05, "({x}, {y}): {got}");
            }
        }
    }

    /// A side × side film of 8 quiet samples a pixel (1 to 1.15, mean
    /// 1.075), the first sample of each pixel in `bright` set to `value`.
    fn speckled(side: usize, bright: &[(usize, usize)], value: f32) -> (Header, Vec<Record>) {
        let mut recs = Vec::new();
        for y in 0..side {
            for x in 0..side {
                for s in 0..8 {
                    let mut v = 1.0 + 0.05 * ((s * 3 + x + 2 * y) % 4) as f32;
                    if s == 0 && bright.contains(&(x, y)) {
                        v = value;
                    }
                    recs.push(Record::new(x as f32 + 0.5, y as f32 + 0.5, 0.0, [v; 3]));
                }
            }
        }
        (test_header(side as u32, side as u32), recs)
    }

    /// A pixel holding an outlier passes every neighbour's test (its
    /// variance is wide) but, far noisier, averages with none of them:
    /// its energy is counted once, in its own pixel.
    #[test]
    fn a_far_noisier_neighbour_is_left_out() {
        let (h, recs) = speckled(5, &[(2, 2)], 500.0);
        let img = denoise(&recs, &h, |_| true, None);
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

    /// Where three pixels of a 3 × 3 neighbourhood hold a rare bright
    /// sample it is that region's noise: the quiet pixel among them
    /// averages them in (the neighbourhood's upper quartile, where its
    /// median would have left them out), while a quiet pixel far from
    /// them, whose neighbourhood is quiet, still leaves them out.
    #[test]
    fn noise_three_neighbours_share_is_averaged() {
        let (h, recs) = speckled(9, &[(2, 3), (4, 3), (3, 4)], 50.0);
        let img = denoise(&recs, &h, |_| true, None);
        let at = |x: usize, y: usize| img.data[y * 9 + x][0];
        assert!(
            at(3, 3) > 1.3,
            "the shared noise was left out: {}",
            at(3, 3)
        );
        assert!((at(8, 8) - 1.075).abs() < 0.05, "{}", at(8, 8));
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

    /// A film of two halves, 1 on the left and `right` on the right, 8
    /// samples a pixel spread uniformly ±40 % around the level (seed
    /// `seed`).
    fn two_regions((w, ht): (usize, usize), right: f32, seed: u64) -> (Header, Vec<Record>) {
        let mut unit = crate::synth::test_units(seed);
        let mut recs = Vec::new();
        for y in 0..ht {
            for x in 0..w {
                let level = if x < w / 2 { 1.0 } else { right };
                for _ in 0..8 {
                    let v = level * (0.6 + 0.8 * unit() as f32);
                    recs.push(Record::new(x as f32 + 0.5, y as f32 + 0.5, 0.0, [v; 3]));
                }
            }
        }
        (test_header(w as u32, ht as u32), recs)
    }

    /// Two regions whose radiance differs by less than the test can see
    /// at 8 samples a pixel average each other without a guide; their
    /// albedo keeps them apart, and an albedo equal everywhere changes
    /// no bit.
    #[test]
    fn the_albedo_keeps_apart_what_the_test_cannot() {
        let (w, ht) = (16, 6);
        let (h, recs) = two_regions((w, ht), 1.15, 3);
        let albedo: Vec<f32> = (0..w * ht)
            .flat_map(|p| [if p % w < w / 2 { 0.2 } else { 0.8 }; 3])
            .collect();
        let flat = vec![0.5f32; 3 * w * ht];
        let plain = denoise(&recs, &h, |_| true, None);
        let guided = denoise(&recs, &h, |_| true, Some(Guide::new(&albedo, None)));
        let same = denoise(&recs, &h, |_| true, Some(Guide::new(&flat, Some(&flat))));
        assert_eq!(plain, same);
        // Each side's mean of its pixels, beside the edge and far from it.
        let side = |img: &Image, xs: std::ops::Range<usize>| -> f64 {
            let n = (xs.len() * ht) as f64;
            (0..ht)
                .flat_map(|y| xs.clone().map(move |x| y * w + x))
                .map(|p| img.data[p][0])
                .sum::<f64>()
                / n
        };
        let step = |img: &Image| side(img, w / 2..w / 2 + 1) - side(img, w / 2 - 1..w / 2);
        assert!(
            step(&plain) < 0.08,
            "the test alone blurs the edge: {}",
            step(&plain)
        );
        assert!(
            step(&guided) > 0.1,
            "the albedo keeps it: {}",
            step(&guided)
        );
    }

    /// Two regions 30 % apart at 8 samples a pixel: most pairs of pixels
    /// across the edge pass the pixels' own test at α = 0.001 (checked
    /// here), and their patches, nine such pairs pooled, do not: the edge
    /// stays.
    #[test]
    fn the_patches_keep_an_edge_the_pixels_own_test_passes() {
        let (w, ht) = (24, 12);
        let (h, recs) = two_regions((w, ht), 1.3, 5);
        let fields = fields::Fields::new(&stats_of(&recs, &h, |_| true), w, ht, None);
        let kernel = welch::Kernel::new(8);
        let across = |y: usize| fields.compatible(y * w + w / 2 - 1, y * w + w / 2, &kernel);
        let passed = (0..ht).filter(|&y| across(y)).count();
        assert!(passed * 4 >= ht * 3, "the own test passed {passed} of {ht}");
        let img = denoise(&recs, &h, |_| true, None);
        // Each column's mean over the rows.
        let column = |x: usize| (0..ht).map(|y| img.data[y * w + x][0]).sum::<f64>() / ht as f64;
        let (left, right) = (column(w / 2 - 1), column(w / 2));
        assert!(right - left > 0.2, "{left} {right}");
    }

    /// An outlier the caller leaves out does not move its pixel.
    #[test]
    fn left_out_samples_do_not_count() {
        let h = test_header(1, 1);
        let mut recs: Vec<Record> = (0..8)
            .map(|i| Record::new(0.5, 0.5, 0.0, [1.0 + 0.01 * i as f32; 3]))
            .collect();
        recs.push(Record::new(0.5, 0.5, 0.0, [1000.0; 3]));
        let img = denoise(&recs, &h, |i| i < 8, None);
        assert!((img.data[0][0] - 1.035).abs() < 1e-6, "{:?}", img.data[0]);
    }
}
