//! Per pixel and channel, where the pixel's true value may lie given its
//! samples: the confidence interval x̄ ± z·s/√n of the Monte Carlo mean
//! (docs/filter.md §3, the `_ci` methods). It bounds what an image-space
//! filter may do to a pixel: OIDN or a bilateral filter blurs a small
//! light's energy into its neighbours, and a neighbour whose samples agree
//! among themselves has a narrow interval that says so.
//!
//! The variance s² of a pixel is the larger of its own unbiased sample
//! variance and the mean variance of the compatible pixels of its 3 × 3
//! neighbourhood: same frame, two samples or more, and a mean within
//! z·(SEₚ + SE_q) of the pixel's, SE from each pixel's own samples (per
//! channel). A pixel whose few samples happened to miss a rare, bright
//! path has a small own variance, and its neighbours' say how wide the
//! distribution really is; a light's pixels, whose samples all agree, do
//! not take the variance of the wall beside them, whose mean no interval
//! of theirs overlaps.
//!
//! The moments are accumulated per pixel with Welford's update in file
//! order, in f64: exact for any thread count, and with no cancellation
//! when a pixel's samples are large and nearly equal (a light's 60 ± 10⁻⁶).

use super::Image;
use super::per_pixel;
use crate::dump::{Header, Record};
use crate::par::prelude::*;

/// z of the interval: three standard errors.
pub const Z: f64 = 3.0;

/// Per pixel and channel, the interval `centre ± half_width`.
pub struct Interval {
    /// The per-pixel sample mean (box weights whatever the reconstruction
    /// filter); 0 where a pixel has no valid sample.
    pub centre: Image,
    /// z·s/√n; 0 where a pixel has no valid sample, +∞ where it has one
    /// and no compatible neighbour has two (at 1 spp the interval bounds
    /// nothing).
    pub half_width: Image,
    /// The samples behind each pixel's interval.
    pub count: Vec<u32>,
    /// s/√n from the pixel's own samples alone (0 below two samples).
    pub own_se: Image,
    /// The z of `half_width`.
    pub z: f64,
}

impl Interval {
    /// The film's intervals before any band's are put: no pixel has a
    /// sample.
    #[cfg(test)]
    pub(crate) fn empty(h: &Header, z: f64) -> Interval {
        Interval {
            centre: Image::for_header(h),
            half_width: Image::for_header(h),
            count: vec![0; h.pixels() * h.frames as usize],
            own_se: Image::for_header(h),
            z,
        }
    }

    /// `band`'s own pixels' intervals, made from its folds, put in place.
    #[cfg(test)]
    pub(crate) fn put(&mut self, band: &per_pixel::RowBand, from: &Interval) {
        band.put(&mut self.centre.data, &from.centre.data);
        band.put(&mut self.half_width.data, &from.half_width.data);
        band.put(&mut self.count, &from.count);
        band.put(&mut self.own_se.data, &from.own_se.data);
    }

    /// `from`, intervals of a row of pixels, put at the pixels `places`
    /// of these.
    pub(crate) fn put_at(&mut self, places: std::ops::Range<usize>, from: &Interval) {
        self.centre.data[places.clone()].copy_from_slice(&from.centre.data);
        self.half_width.data[places.clone()].copy_from_slice(&from.half_width.data);
        self.count[places.clone()].copy_from_slice(&from.count);
        self.own_se.data[places].copy_from_slice(&from.own_se.data);
    }

    /// `v` held inside pixel `px`'s interval, channel by channel.
    #[inline]
    pub fn clamp(&self, px: usize, v: [f64; 3]) -> [f64; 3] {
        let (c, h) = (self.centre.data[px], self.half_width.data[px]);
        std::array::from_fn(|i| v[i].clamp(c[i] - h[i], c[i] + h[i]))
    }

    /// `img` (an image-space method's output) held inside every pixel's
    /// interval: where the method moved a pixel farther from its samples'
    /// mean than z standard errors, it goes back to the interval's edge.
    /// Pixels with no sample become 0.
    pub fn bound(&self, img: &Image) -> Image {
        let mut out = img.clone();
        out.data.par_iter_mut().enumerate().for_each(|(px, v)| {
            *v = self.clamp(px, *v);
        });
        out
    }
}

impl Interval {
    /// `img` steered, block by block, towards the interval of each block's
    /// mean (docs/filter.md F10, "Blocks"): aligned blocks of b × b pixels
    /// for b = 2, 4, … up to the film's size (partial at the film's edges),
    /// finest first, each frame and channel apart. A block's mean of its
    /// pixels' sample means is unbiased with standard error √(Σ SEₚ²)/P
    /// over its P pixels with a bounded interval (SEₚ = half_width / z of
    /// this interval), far narrower than a pixel's; where the image's mean
    /// over those pixels lies beyond `z` of them, they are scaled so that
    /// it sits on the interval's edge (shifted instead where either mean
    /// is not above 0). A denoiser's bias that no pixel's interval can see
    /// (a region made darker or brighter as a whole) is then bounded,
    /// while one outlier moves its block's mean by about one of its SEs
    /// and never starts a correction. A coarser block can move a finer
    /// one again; pixels without samples or with an unbounded interval,
    /// and blocks whose image is not finite, are left alone.
    pub fn hold_blocks(&self, img: &mut Image, z: f64) {
        let (w, h) = (img.width, img.height);
        let mut b = 2;
        while b < 2 * w.max(h) {
            // A row of blocks a job: the blocks of one size are apart.
            for (f, frame) in img.data.chunks_mut((w * h).max(1)).enumerate() {
                let bands = frame.par_chunks_mut(b * w.max(1)).enumerate();
                bands.for_each(|(band, pixels)| {
                    let first = f * w * h + band * b * w;
                    let rows = pixels.len() / w;
                    for bx in (0..w).step_by(b) {
                        let cols = bx..(bx + b).min(w);
                        let block = (0..rows).flat_map(|y| cols.clone().map(move |x| y * w + x));
                        self.hold_block(pixels, first, block, z);
                    }
                });
            }
            b *= 2;
        }
    }

    /// [`Interval::hold_blocks`] of one block: the pixels `block` of
    /// `img`, a slice of the image that starts at pixel `first`.
    fn hold_block(
        &self,
        img: &mut [[f64; 3]],
        first: usize,
        block: impl Iterator<Item = usize> + Clone,
        z: f64,
    ) {
        let held = |i: &usize| {
            let px = first + i;
            self.count[px] > 0 && self.half_width.data[px].iter().all(|h| h.is_finite())
        };
        let (mut n, mut mean, mut var, mut g) = (0.0, [0.0; 3], [0.0; 3], [0.0; 3]);
        for i in block.clone().filter(held) {
            let px = first + i;
            n += 1.0;
            for c in 0..3 {
                mean[c] += self.centre.data[px][c];
                let se = self.half_width.data[px][c] / self.z;
                var[c] += se * se;
                g[c] += img[i][c];
            }
        }
        if n == 0.0 {
            return;
        }
        for c in 0..3 {
            let (mean, g, half) = (mean[c] / n, g[c] / n, z * var[c].sqrt() / n);
            let target = g.clamp(mean - half, mean + half);
            if !g.is_finite() || target == g {
                continue;
            }
            for i in block.clone().filter(held) {
                let v = &mut img[i][c];
                *v = if g > 0.0 && target > 0.0 {
                    *v * (target / g)
                } else {
                    *v + target - g
                };
            }
        }
    }
}

/// Running moments of one pixel (Welford).
#[derive(Clone, Copy, Default)]
pub(crate) struct Moments {
    pub(crate) n: u32,
    pub(crate) mean: [f64; 3],
    /// Σ (x − x̄)², per channel.
    pub(crate) m2: [f64; 3],
}

impl AsRef<Moments> for Moments {
    fn as_ref(&self) -> &Moments {
        self
    }
}

impl Moments {
    pub(crate) fn add(&mut self, x: [f64; 3]) {
        self.n += 1;
        let n = self.n as f64;
        for ((x, mean), m2) in x.into_iter().zip(&mut self.mean).zip(&mut self.m2) {
            let d = x - *mean;
            *mean += d / n;
            *m2 += d * (x - *mean);
        }
    }

    /// The unbiased sample variance, for two samples or more.
    fn variance(&self) -> Option<[f64; 3]> {
        (self.n >= 2).then(|| self.m2.map(|m| m / (self.n - 1) as f64))
    }
}

/// The confidence interval of every pixel's mean, at `z` standard errors,
/// folded in one serial pass (the pipeline makes it beside the replay,
/// whose threads it would otherwise hold up); the intervals from the
/// moments are then made on the pool.
pub fn interval(records: &[Record], h: &Header, z: f64) -> Interval {
    let moments = per_pixel::fold(records, h, 1, |_| true, Moments::add);
    from_moments(&moments, h, z)
}

/// [`interval`] of the valid samples `keep(i)` picks (record i): the
/// accepted ones, for [`super::guided`]; on every thread of the pool.
pub fn interval_of(
    records: &[Record],
    h: &Header,
    z: f64,
    keep: impl Fn(usize) -> bool + Sync,
) -> Interval {
    let bands = crate::par::current_num_threads();
    let moments = per_pixel::fold(records, h, bands, keep, Moments::add);
    from_moments(&moments, h, z)
}

/// The intervals from every pixel's moments of its samples.
pub(crate) fn from_moments<M: AsRef<Moments>>(moments: &[M], h: &Header, z: f64) -> Interval {
    from_moments_of(moments, AsRef::as_ref, h, z)
}

/// [`from_moments`] of the moments `get` reads from each pixel's `M`.
pub(crate) fn from_moments_of<M>(
    moments: &[M],
    get: impl Fn(&M) -> &Moments,
    h: &Header,
    z: f64,
) -> Interval {
    let (w, ht) = (h.width as usize, h.height as usize);
    let moments: Vec<&Moments> = moments.iter().map(get).collect();
    let own_se: Vec<[f64; 3]> = moments.par_iter().map(|m| own_se(m)).collect();
    let mut centre = Image::for_header(h);
    let mut half_width = Image::for_header(h);
    centre
        .data
        .par_iter_mut()
        .zip(half_width.data.par_iter_mut())
        .enumerate()
        .for_each(|(px, (centre, half_width))| {
            if let Some(half) = pooled_half_width(&moments, |q| own_se[q], px, w, ht, z) {
                (*centre, *half_width) = (moments[px].mean, half);
            }
        });
    let count = moments.iter().map(|m| m.n).collect();
    Interval {
        centre,
        half_width,
        count,
        own_se: Image {
            width: w,
            height: ht,
            frames: h.frames as usize,
            data: own_se,
        },
        z,
    }
}

/// [`from_moments_of`] at the pixels `at` alone, in their order, as one
/// row: the same values, each made from its 3 × 3 neighbourhood's
/// moments.
pub(crate) fn from_moments_at<M>(
    moments: &[M],
    get: impl Fn(&M) -> &Moments,
    h: &Header,
    z: f64,
    at: &[usize],
) -> Interval {
    let (w, ht) = (h.width as usize, h.height as usize);
    let moments: Vec<&Moments> = moments.iter().map(get).collect();
    let row = |data: Vec<[f64; 3]>| Image {
        width: data.len(),
        height: 1,
        frames: 1,
        data,
    };
    let interval = |&px: &usize| {
        let m = moments[px];
        let se = |q: usize| own_se(moments[q]);
        match pooled_half_width(&moments, se, px, w, ht, z) {
            Some(half) => (m.mean, half),
            None => ([0.0; 3], [0.0; 3]),
        }
    };
    let (centre, half_width): (Vec<_>, Vec<_>) = at.par_iter().map(interval).unzip();
    Interval {
        centre: row(centre),
        half_width: row(half_width),
        count: at.iter().map(|&px| moments[px].n).collect(),
        own_se: row(at.iter().map(|&px| own_se(moments[px])).collect()),
        z,
    }
}

/// The standard error of a pixel's mean from its own samples alone (0
/// below two samples).
fn own_se(m: &Moments) -> [f64; 3] {
    match m.variance() {
        Some(v) => v.map(|v| (v / m.n as f64).sqrt()),
        None => [0.0; 3],
    }
}

/// Pixel `px`'s half width z·s/√n, s² pooled over the compatible pixels
/// of its 3 × 3 neighbourhood (the module's rule) on a film `w` × `ht`
/// (frames in turn), `se(q)` pixel q's [`own_se`]; None where it has no
/// sample.
fn pooled_half_width(
    moments: &[&Moments],
    se: impl Fn(usize) -> [f64; 3],
    px: usize,
    w: usize,
    ht: usize,
    z: f64,
) -> Option<[f64; 3]> {
    let m = moments[px];
    if m.n == 0 {
        return None;
    }
    let (frame, i) = (px / (w * ht), px % (w * ht));
    let (x, y) = (i % w, i / w);
    let own_se = se(px);
    let mut pooled = [0.0; 3];
    let mut count = [0.0; 3];
    for ny in y.saturating_sub(1)..(y + 2).min(ht) {
        for nx in x.saturating_sub(1)..(x + 2).min(w) {
            let q = frame * w * ht + ny * w + nx;
            let Some(v) = moments[q].variance() else {
                continue;
            };
            let se_q = se(q);
            for c in 0..3 {
                let gap = (moments[q].mean[c] - m.mean[c]).abs();
                if gap <= z * (se_q[c] + own_se[c]) {
                    pooled[c] += v[c];
                    count[c] += 1.0;
                }
            }
        }
    }
    let own = m.variance();
    Some(std::array::from_fn(|c| {
        let s2 = match (own, count[c] > 0.0) {
            (Some(own), true) => own[c].max(pooled[c] / count[c]),
            (None, true) => pooled[c] / count[c],
            (Some(own), false) => own[c],
            // Nothing says how wide: no bound.
            (None, false) => f64::INFINITY,
        };
        z * (s2 / m.n as f64).sqrt()
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::recon::test_header as header;

    fn rec(x: f32, y: f32, v: [f32; 3]) -> Record {
        Record::new(x, y, 0.0, v)
    }

    /// Against the two-pass formula by hand on a 3 × 1 film: the middle
    /// pixel's own variance is below its compatible neighbours' mean, the
    /// left one's above it; the right pixel has one sample and a mean no
    /// neighbour's interval reaches, so nothing bounds it.
    #[test]
    fn interval_by_hand() {
        let h = header(3, 1);
        let records = [
            rec(0.5, 0.5, [1.0, 0.0, 0.0]),
            rec(0.5, 0.5, [5.0, 0.0, 0.0]),
            rec(1.5, 0.5, [2.0, 2.0, 2.0]),
            rec(1.5, 0.5, [2.0, 2.0, 2.0]),
            rec(1.5, 0.5, [3.0, 2.0, 2.0]),
            rec(2.5, 0.5, [7.0, 0.0, 0.0]),
            rec(f32::NAN, 0.5, [1e9, 0.0, 0.0]),
        ];
        let ci = interval(&records, &h, 2.0);
        // Pixel 0: mean 3, s² = 8, SE 2; pixel 1: mean 7/3, s² = 1/3, SE 1/3.
        // |3 − 7/3| ≤ 2 (2 + 1/3): compatible, pooled s² = (8 + 1/3) / 2.
        assert_eq!(ci.centre.data[0], [3.0, 0.0, 0.0]);
        assert!((ci.half_width.data[0][0] - 2.0 * (8.0f64 / 2.0).sqrt()).abs() < 1e-12);
        let pooled = (8.0 + 1.0 / 3.0) / 2.0;
        assert!((ci.centre.data[1][0] - 7.0 / 3.0).abs() < 1e-12);
        assert!((ci.half_width.data[1][0] - 2.0 * (pooled / 3.0f64).sqrt()).abs() < 1e-12);
        // Green: pixel 0's 0 lies 2 from pixel 1's 2, beyond 2 (0 + 0); pixel
        // 1 keeps its own s² = 0.
        assert_eq!(ci.half_width.data[1][1], 0.0);
        // Pixel 2: one sample at 7, beyond 2 · (1/3 + 0) of pixel 1's mean.
        assert_eq!(ci.centre.data[2], [7.0, 0.0, 0.0]);
        assert_eq!(ci.half_width.data[2][0], f64::INFINITY);
        assert_eq!(ci.clamp(2, [9.0, 1.0, 2.5]), [9.0, 1.0, 2.5]);
        assert_eq!(
            ci.clamp(1, [9.0, 1.0, 2.5]),
            [7.0 / 3.0 + 2.0 * (pooled / 3.0f64).sqrt(), 2.0, 2.0]
        );
    }

    /// A light's pixels, whose samples agree, keep a zero-width interval
    /// beside a noisy wall; a pixel whose samples missed a rare bright
    /// path takes its compatible neighbours' variance.
    #[test]
    fn pooling_only_over_compatible_neighbours() {
        let h = header(3, 1);
        let mut records = Vec::new();
        for i in 0..16 {
            records.push(rec(0.5, 0.5, [10.0; 3]));
            let wall = if i % 4 == 0 { 4.0 } else { 0.0 };
            records.push(rec(1.5, 0.5, [wall; 3]));
            records.push(rec(2.5, 0.5, [if i == 0 { 0.3 } else { 0.2 }; 3]));
        }
        let ci = interval(&records, &h, Z);
        assert_eq!(ci.half_width.data[0], [0.0; 3]);
        // The wall (mean 1, s² = 3.2, SE ≈ 0.45) and the dim pixel (mean
        // 0.20625, SE 0.00625): |1 − 0.20625| ≤ 3 (0.45 + 0.006), so the dim
        // pixel takes the mean of its own and the wall's s².
        let wall_s2 = 16.0 * 4.0 * 0.75 / 15.0 * 1.0;
        let dim_s2 = (0.01f64 * 15.0 / 16.0) / 15.0;
        let want = Z * ((wall_s2 + dim_s2) / 2.0 / 16.0f64).sqrt();
        // (0.2 and 0.3 are f32 in a record.)
        assert!(
            (ci.half_width.data[2][0] - want).abs() < 1e-7,
            "{:?}",
            ci.half_width.data[2]
        );
    }

    /// The intervals made at chosen pixels alone are the film's there,
    /// bit for bit: corners, edges, both frames, pixels with no sample
    /// or one, a bright pixel beside dim ones.
    #[test]
    fn intervals_at_pixels_are_the_films() {
        let synth = crate::synth::SynthParams {
            width: 9,
            height: 7,
            frames: 2,
            spp: 5,
            firefly_fraction: 0.1,
            ..crate::synth::SynthParams::default()
        };
        let h = synth.header();
        // Pixel 10 of each frame loses every sample, pixel 20 all but one.
        let records: Vec<Record> = synth
            .records()
            .enumerate()
            .filter(|(i, _)| {
                let (px, s) = (i / 5, i % 5);
                px % 63 != 10 && (px % 63 != 20 || s == 0)
            })
            .map(|(_, r)| r)
            .collect();
        let moments = per_pixel::fold(&records, &h, 1, |_| true, Moments::add);
        let film = from_moments(&moments, &h, Z);
        let at = [
            0,
            8,
            10,
            20,
            21,
            31,
            54,
            62,
            63,
            63 + 10,
            63 + 20,
            63 + 40,
            125,
        ];
        let got = from_moments_at(&moments, |m| m, &h, Z, &at);
        let bits =
            |v: &[[f64; 3]]| -> Vec<u64> { v.iter().flatten().map(|x| x.to_bits()).collect() };
        let film_at =
            |img: &Image| -> Vec<[f64; 3]> { at.iter().map(|&px| img.data[px]).collect() };
        assert_eq!(bits(&got.centre.data), bits(&film_at(&film.centre)));
        assert_eq!(bits(&got.half_width.data), bits(&film_at(&film.half_width)));
        assert_eq!(bits(&got.own_se.data), bits(&film_at(&film.own_se)));
        let counts: Vec<u32> = at.iter().map(|&px| film.count[px]).collect();
        assert_eq!(got.count, counts);
        assert_eq!((got.count[2], got.count[3]), (0, 1));
        assert!(
            got.half_width
                .data
                .iter()
                .flatten()
                .any(|w| w.is_finite() && *w > 0.0)
        );
    }

    /// Large, nearly equal samples: Welford keeps the variance that a
    /// one-pass Σx² − (Σx)²/n would lose to cancellation.
    #[test]
    fn no_cancellation_at_large_values() {
        let h = header(1, 1);
        let v = [1.0e7f32, 1.0e7 + 1.0, 1.0e7 + 2.0];
        let records: Vec<Record> = v.iter().map(|&v| rec(0.5, 0.5, [v; 3])).collect();
        let ci = interval(&records, &h, 1.0);
        // s² = 1, n = 3.
        assert!((ci.half_width.data[0][0] - (1.0f64 / 3.0).sqrt()).abs() < 1e-9);
        assert_eq!(ci.centre.data[0][0], 1.0e7 + 1.0);
    }

    #[test]
    fn empty_pixels_have_an_empty_interval() {
        let h = header(2, 2);
        let ci = interval(&[rec(0.5, 0.5, [1.0; 3])], &h, Z);
        // One sample, no neighbour with two: unbounded.
        assert_eq!(ci.half_width.data[0], [f64::INFINITY; 3]);
        assert_eq!(ci.clamp(0, [4.0, 1.0, -1.0]), [4.0, 1.0, -1.0]);
        assert_eq!(ci.centre.data[3], [0.0; 3]);
        assert_eq!(ci.half_width.data[3], [0.0; 3]);
        assert_eq!(ci.clamp(3, [4.0, 1.0, -1.0]), [0.0; 3]);
    }

    fn film(w: usize, h: usize, frames: usize, v: f64) -> Image {
        Image {
            width: w,
            height: h,
            frames,
            data: vec![[v; 3]; w * h * frames],
        }
    }

    /// Every pixel's mean 10 with SE 1 (own SE 5, which blocks do not use).
    fn tens(w: usize, h: usize, frames: usize) -> Interval {
        Interval {
            centre: film(w, h, frames, 10.0),
            half_width: film(w, h, frames, 2.0),
            count: vec![4; w * h * frames],
            own_se: film(w, h, frames, 5.0),
            z: 2.0,
        }
    }

    /// A 4 × 4 film: an image 9 on average is inside every 2 × 2 block's
    /// interval (10 ± 3·√4/4) but not the whole film's (10 ± 3·√16/16), and
    /// is scaled, not shifted, so that its mean sits on that edge; one
    /// pixel at 14 moves no block's mean out of its interval.
    #[test]
    fn blocks_bound_a_regional_bias_and_not_an_outlier() {
        let ci = tens(4, 4, 1);
        let mut dim = film(4, 4, 1, 9.0);
        dim.data[0] = [4.5; 3];
        dim.data[1] = [13.5; 3];
        ci.hold_blocks(&mut dim, Z);
        let k = 9.25 / 9.0;
        for (px, v) in dim.data.iter().enumerate() {
            let want = [4.5 * k, 13.5 * k, 9.0 * k][px.min(2)];
            for c in v {
                assert!((c - want).abs() < 1e-12, "{px}: {c}");
            }
        }
        let mut outlier = film(4, 4, 1, 10.0);
        outlier.data[5] = [14.0; 3];
        let before = outlier.data.clone();
        ci.hold_blocks(&mut outlier, Z);
        assert_eq!(outlier.data, before);
    }

    /// Rows of blocks held in parallel give the bits of the blocks held
    /// one after another over the whole image, on films whose sides are
    /// no multiple of the blocks', with frames.
    #[test]
    fn blocks_held_by_rows_are_those_held_in_turn() {
        let mut unit = crate::synth::test_units(3);
        for (w, h, frames) in [(13, 7, 3), (1, 9, 2), (9, 1, 1), (32, 32, 1)] {
            let mut ci = tens(w, h, frames);
            let mut img = film(w, h, frames, 9.0);
            for px in 0..w * h * frames {
                ci.centre.data[px] = [10.0 + unit(); 3];
                ci.half_width.data[px] = [if unit() < 0.05 { f64::INFINITY } else { unit() }; 3];
                img.data[px] = std::array::from_fn(|_| 8.0 + 4.0 * unit());
            }
            let (mut want, before) = (img.clone(), img.clone());
            let mut b = 2;
            while b < 2 * w.max(h) {
                for f in 0..frames {
                    for by in (0..h).step_by(b) {
                        for bx in (0..w).step_by(b) {
                            let (rows, cols) = (by..(by + b).min(h), bx..(bx + b).min(w));
                            let base = f * w * h;
                            let block =
                                rows.flat_map(|y| cols.clone().map(move |x| base + y * w + x));
                            ci.hold_block(&mut want.data, 0, block, Z);
                        }
                    }
                }
                b *= 2;
            }
            ci.hold_blocks(&mut img, Z);
            let bits = |i: &Image| {
                i.data
                    .iter()
                    .map(|p| p.map(f64::to_bits))
                    .collect::<Vec<_>>()
            };
            assert_eq!(bits(&img), bits(&want), "{w} × {h} × {frames}");
            assert_ne!(bits(&img), bits(&before), "no block moved");
        }
    }

    /// A 5 × 3 film of two frames, blocks partial at its edges. Frame 0
    /// is 9 everywhere but for one pixel of unbounded interval, which is
    /// left out and alone; the coarsest block puts the mean of the 14
    /// others on 10 − 3·√14/14. Frame 1 is 19 against 20, inside every
    /// block that has no NaN, and a NaN pixel stops every block that has
    /// it: frame 1 stays as it was (nothing crosses between frames).
    #[test]
    fn blocks_leave_unbounded_pixels_nan_and_other_frames_alone() {
        let mut ci = tens(5, 3, 2);
        let corner = 2 * 5 + 4;
        ci.half_width.data[corner] = [f64::INFINITY; 3];
        for v in &mut ci.centre.data[15..] {
            *v = [20.0; 3];
        }
        let mut img = film(5, 3, 2, 9.0);
        img.data[corner] = [100.0; 3];
        for v in &mut img.data[15..] {
            *v = [19.0; 3];
        }
        img.data[15 + 7] = [f64::NAN; 3];
        ci.hold_blocks(&mut img, Z);
        assert_eq!(img.data[corner], [100.0; 3]);
        let held: f64 = (0..15)
            .filter(|&px| px != corner)
            .map(|px| img.data[px][0])
            .sum();
        let edge = 10.0 - 3.0 * 14f64.sqrt() / 14.0;
        assert!((held / 14.0 - edge).abs() < 1e-12, "{}", held / 14.0);
        for (px, v) in img.data[15..].iter().enumerate() {
            if px == 7 {
                assert!(v[0].is_nan());
            } else {
                assert_eq!(*v, [19.0; 3], "{px}");
            }
        }
    }
}
