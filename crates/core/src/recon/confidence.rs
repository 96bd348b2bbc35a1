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
mod tests;
