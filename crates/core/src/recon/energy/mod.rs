//! Energy accounting for the path-density filter: what it removed from
//! each pixel, and an energy-aware variant that gives that energy back
//! without giving back the spikes.
//!
//! Removed radiance is `mean − filtered` per pixel and channel: exactly
//! what the filter changed, including the renormalisation over the accepted
//! samples and median fallbacks (so it can be negative where a dark outlier
//! was rejected). Its sum over the film is the energy deficit the energy
//! ratio measures.
//!
//! The energy-aware variant spreads each pixel's removed radiance over its
//! image-space neighbourhood with a normalised Gaussian of σ_e pixels and
//! adds it to the filtered image. Why this design (docs/RESULTS.md measures
//! it): a rejected firefly is a sample of a real but rare light path
//! (a caustic seen through a diffuse bounce) whose expected contribution is
//! smooth over many pixels; the filter's fault is only that one pixel got
//! all of it. Spreading over 2πσ_e² pixels divides the spike's amplitude by
//! that area (σ_e = 8: about 400× on an even image) while the film's total radiance per
//! channel, and so the energy ratio, stays that of the mean (less the
//! sources that stand out, below). Only pixels holding samples receive
//! energy, and the weights are normalised over those inside the frame, so
//! nothing leaks off the film. The Gaussian is weighed by how near each
//! pixel's level lies to the source's ([`RANGE`]): rare paths are given
//! back where the image already holds their kind of light (a glossy
//! streak, a caustic), not as a haze over the dark pixels beside it.
//!
//! A source whose spread would still stand out of what it lands on
//! ([`STANDOUT`]) is not given back: no width of the spread hides it, and
//! its blur is a feature the reference does not have (a halo where the
//! spike was a sub-pixel light, a blob where it was a firefly). It stays
//! removed, as in the filtered image. What it lands on includes the
//! peaks of the other sources given back: a source among many (a
//! caustic's paths, a dim room's indirect light at few samples) is part
//! of one smooth field, which the spread restores; a source beside a
//! spike that stays removed is judged without it. Putting a lone one
//! back in its own pixel instead brings back the fireflies
//! (docs/RESULTS.md).

use super::Image;
use crate::joint::lab;
use crate::par::prelude::*;

/// Per pixel, `mean − filtered`.
pub fn removed(mean: &Image, filtered: &Image) -> Image {
    removed_by(mean, |px| filtered.data[px])
}

/// Per pixel px, `mean − filtered(px)`.
pub fn removed_by(mean: &Image, filtered: impl Fn(usize) -> [f64; 3]) -> Image {
    let mut out = mean.clone();
    for (px, o) in out.data.iter_mut().enumerate() {
        let f = filtered(px);
        for c in 0..3 {
            o[c] -= f[c];
        }
    }
    out
}

/// `filtered` plus `removed` spread over each source pixel's neighbourhood
/// (radius ⌈3σ_e⌉) with weights exp(−d²/2σ_e²), times the level's weight
/// ([`RANGE`]), normalised over the occupied pixels of its frame, except
/// a source that stands out
/// ([`STANDOUT`]), which stays removed. Every pixel receives its shares
/// in the order of the sources' pixels, so the result does not depend on
/// threads.
///
/// ```
/// use pathdensity_core::recon::{Image, energy};
/// let mut filtered = Image::new(5, 5, 1);
/// filtered.data.fill([5.0; 3]);
/// let mut mean = filtered.clone();
/// mean.data[12] = [31.0; 3]; // a firefly at the centre
/// let occupancy = vec![1; 25];
/// let removed = energy::removed(&mean, &filtered);
/// let out = energy::energy_aware(&filtered, &removed, &occupancy, 100.0);
/// // σ_e far above the film: the 26 units are spread almost evenly, each
/// // share well below the background of 5.
/// let total: f64 = out.data.iter().map(|p| p[0] - 5.0).sum();
/// assert!((total - 26.0).abs() < 1e-9);
/// assert!(out.data.iter().all(|p| (p[0] - 5.0 - 26.0 / 25.0).abs() < 0.01));
/// // On a black film no spread hides a lone spike: it stays removed.
/// let black = Image::new(5, 5, 1);
/// let mut spike = black.clone();
/// spike.data[12] = [26.0; 3];
/// let out = energy::energy_aware(&black, &energy::removed(&spike, &black), &occupancy, 100.0);
/// assert!(out.data.iter().all(|p| *p == [0.0; 3]));
/// ```
pub fn energy_aware(filtered: &Image, removed: &Image, occupancy: &[u32], sigma: f64) -> Image {
    let mut out = filtered.clone();
    spread_into(&mut out, removed, occupancy, sigma);
    out
}

/// [`energy_aware`] in place: `removed` spread into `out`, the filtered
/// image (or a denoised one: what the energy lands on).
pub fn spread_into(out: &mut Image, removed: &Image, occupancy: &[u32], sigma: f64) {
    let spread = Spread::new(out, sigma, occupancy);
    // What a source lands on: the log luminance its window averages,
    // relative to the film's mean and floored there, so that a black
    // window has a finite level and nothing depends on the dump's units.
    let film = mean_luminance(out, occupancy);
    let level: Vec<f32> = out
        .data
        .par_iter()
        .map(|p| (lab::luminance(*p).max(LEVEL_FLOOR * film).ln() - film.ln()) as f32)
        .collect();
    // Every source with its window's total weight and the mean of its
    // window's log levels, in pixel order.
    let all: Vec<(usize, f64, f64)> = (0..removed.data.len())
        .into_par_iter()
        .filter(|&src| removed.data[src] != [0.0; 3] && occupancy[src] > 0)
        .map(|src| {
            let (mut total, mut log_level) = (0.0, 0.0);
            spread.window(src, 0..spread.rows, |q, k| {
                total += k;
                log_level += k * level[q] as f64;
            });
            (src, total, log_level / total)
        })
        .collect();
    // Each source's peak, e/Σk of its luminance (0 for a dark one): what
    // its spread adds at its own pixel.
    let mut peaks = vec![0f32; removed.data.len()];
    for &(src, total, _) in &all {
        peaks[src] = (lab::luminance(removed.data[src]).max(0.0) / total) as f32;
    }
    // The sources given back: the largest set none of whose peaks stands
    // out of its level plus the given-back others' peaks weighed by its
    // window. A source among many is part of one smooth field (a caustic,
    // a room's indirect light) and is given back; one that only a source
    // left removed kept from standing out is not (the rim of a sub-pixel
    // light). From every source, those that stand out are taken out,
    // round by round, until none does; after the first round only those
    // whose window holds a source just taken out can change.
    // What source `src` lands on: the geometric mean of its window's
    // level plus the `peaks` of the others, weighed by the window.
    let lands_on = |src: usize, log_level: f64, peaks: &[f32]| {
        let mut others = 0.0;
        spread.window(src, 0..spread.rows, |q, k| {
            if q != src {
                others += k * peaks[q] as f64;
            }
        });
        (log_level + film.ln()).exp() + others
    };
    let mut given = vec![true; all.len()];
    let mut taken: Option<Vec<usize>> = None;
    loop {
        let now: Vec<usize> = (0..all.len())
            .into_par_iter()
            .filter(|&i| given[i])
            .filter(|&i| taken.as_ref().is_none_or(|t| spread.reaches(t, all[i].0)))
            .filter(|&i| {
                let (src, total, log_level) = all[i];
                let peak = lab::luminance(removed.data[src]) / total;
                peak > STANDOUT * lands_on(src, log_level, &peaks)
            })
            .collect();
        if now.is_empty() {
            break;
        }
        for &i in &now {
            given[i] = false;
            peaks[all[i].0] = 0.0;
        }
        taken = Some(now.iter().map(|&i| all[i].0).collect());
    }
    // Each source given back lands on the pixels of its window whose
    // level is near its own ([`RANGE`]): a glossy streak's rare paths go
    // back along the streak, not as a haze over the dark floor beside it.
    // A pixel's level here is the brightest of its 3 × 3 neighbourhood,
    // so that a pixel left dark among bright ones (all its samples
    // rejected, at few samples) still receives, and a source in one is
    // not gathered back into the dark pixels. Where so few pixels share
    // its level that its peak by level, e/Σkr, would exceed what it lands
    // on (more than double it), it is spread by the plain Gaussian, whose
    // peak the rule above passed: a lone noisy bright pixel in a dim room
    // at few samples would otherwise take a neighbour's firefly back.
    let near = brightest_around(&level, spread.w, spread.h);
    let range = |own: f32, q: usize| {
        let d = (near[q] - own) as f64;
        (-d * d / (2.0 * RANGE * RANGE)).exp()
    };
    let sources: Vec<(usize, f64, Option<f32>)> = all
        .par_iter()
        .zip(given.par_iter())
        .filter(|(_, g)| **g)
        .map(|(&(src, total, log_level), _)| {
            let own = near[src];
            let mut by_level = 0.0;
            spread.window(src, 0..spread.rows, |q, k| by_level += k * range(own, q));
            let peak = lab::luminance(removed.data[src]) / by_level;
            match peak > lands_on(src, log_level, &peaks) {
                true => (src, total, None),
                false => (src, by_level, Some(own)),
            }
        })
        .collect();
    drop((all, peaks));
    let w = spread.w.max(1);
    // A band of rows a job: each takes, in pixel order, the sources whose
    // window reaches it, and writes only its own rows.
    out.data
        .par_chunks_mut(BAND_ROWS * w)
        .enumerate()
        .for_each(|(band, pixels)| {
            let first = band * BAND_ROWS;
            let rows = first..first + pixels.len() / w;
            // Sources more than r rows away reach no row of the band.
            let from = sources.partition_point(|&(s, ..)| s / w + spread.r < rows.start);
            let to = sources.partition_point(|&(s, ..)| s / w < rows.end + spread.r);
            for &(src, total, own) in &sources[from..to] {
                let e = removed.data[src];
                spread.window(src, rows.clone(), |q, k| {
                    let k = own.map_or(k, |own| k * range(own, q));
                    for (o, v) in pixels[q - first * w].iter_mut().zip(e) {
                        *o += v * k / total;
                    }
                });
            }
        });
}

/// A source stands out, and stays removed, where its spread's peak, e/Σk
/// (the luminance of its removed radiance over its window's total
/// weight), exceeds this many times what it lands on: the geometric mean
/// of the image's luminance over its window plus the peaks of the other
/// sources given back, weighed by the window ([`spread_into`],
/// docs/filter.md).
/// Chosen by measurement over 1/10–1 and ∞ (docs/RESULTS.md, "A source
/// that stands out stays removed").
pub const STANDOUT: f64 = 0.25;

/// The width, in natural-log units of luminance, of the weight a given-back
/// source's spread puts on a pixel of its window by how far that pixel's
/// level ℓ (the largest log luminance of its 3 × 3 neighbourhood) lies
/// from the source's own: exp(−(ℓ_q − ℓ_s)² / 2·RANGE²). Chosen by
/// measurement over 0.125–1 and ∞ (docs/RESULTS.md, "Given back by
/// level").
pub const RANGE: f64 = 0.25;

/// The luminance, relative to the film's mean, below which a pixel
/// counts as this dark in that geometric mean.
const LEVEL_FLOOR: f64 = 1e-4;

/// The mean luminance of the occupied pixels of `img` (the smallest
/// positive f64 where it is not positive), summed in pixel order.
fn mean_luminance(img: &Image, occupancy: &[u32]) -> f64 {
    let (sum, n) = img
        .data
        .iter()
        .zip(occupancy)
        .filter(|(_, o)| **o > 0)
        .fold((0.0, 0usize), |(s, n), (p, _)| {
            (s + lab::luminance(*p), n + 1)
        });
    let mean = sum / n.max(1) as f64;
    if mean > 0.0 { mean } else { f64::MIN_POSITIVE }
}

/// Rows of the film (over all frames) that one job of [`energy_aware`]
/// writes.
const BAND_ROWS: usize = 16;

/// The Gaussian window of [`energy_aware`] on one film.
struct Spread<'a> {
    w: usize,
    h: usize,
    /// Rows over all frames.
    rows: usize,
    r: usize,
    kernel: Vec<f64>,
    occupancy: &'a [u32],
}

impl<'a> Spread<'a> {
    fn new(img: &Image, sigma: f64, occupancy: &'a [u32]) -> Spread<'a> {
        let r = (3.0 * sigma).ceil().max(0.0) as usize;
        let kernel = (0..=2 * r)
            .map(|i| {
                let d = i as f64 - r as f64;
                (-(d * d) / (2.0 * sigma * sigma)).exp()
            })
            .collect();
        Spread {
            w: img.width,
            h: img.height,
            rows: img.height * img.frames,
            r,
            kernel,
            occupancy,
        }
    }

    /// Whether any pixel of `pixels` (in pixel order) lies in `src`'s
    /// window, occupied or not.
    fn reaches(&self, pixels: &[usize], src: usize) -> bool {
        let (w, r) = (self.w, self.r);
        let (row, x) = (src / w, src % w);
        let frame = row / self.h;
        let from = pixels.partition_point(|&q| q / w + r < row);
        let to = pixels.partition_point(|&q| q / w <= row + r);
        pixels[from..to]
            .iter()
            .any(|&q| q / w / self.h == frame && (q % w).abs_diff(x) <= r)
    }

    /// `visit(q, weight)` for each occupied pixel q of `src`'s window in
    /// its frame whose row (counted over all frames) is in `rows`, in
    /// pixel order.
    fn window(&self, src: usize, rows: std::ops::Range<usize>, mut visit: impl FnMut(usize, f64)) {
        let (w, r) = (self.w, self.r);
        let (row, x) = (src / w, src % w);
        let frame_rows = row / self.h * self.h..(row / self.h + 1) * self.h;
        let lo = row.saturating_sub(r).max(frame_rows.start).max(rows.start);
        let hi = (row + r + 1).min(frame_rows.end).min(rows.end);
        let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
        for qy in lo..hi {
            let ky = self.kernel[qy + r - row];
            for qx in x0..x1 {
                let q = qy * w + qx;
                if self.occupancy[q] > 0 {
                    visit(q, ky * self.kernel[qx + r - x]);
                }
            }
        }
    }
}

/// Per pixel the largest of `v` over its 3 × 3 neighbourhood within its
/// frame (`w` × `h` a frame), pixels without samples included: their
/// level is the floor's, which raises no maximum.
fn brightest_around(v: &[f32], w: usize, h: usize) -> Vec<f32> {
    (0..v.len())
        .into_par_iter()
        .map(|px| {
            let (frame, x, y) = (px / (w * h) * w * h, px % w, px % (w * h) / w);
            let mut m = f32::NEG_INFINITY;
            for qy in y.saturating_sub(1)..(y + 2).min(h) {
                for qx in x.saturating_sub(1)..(x + 2).min(w) {
                    m = m.max(v[frame + qy * w + qx]);
                }
            }
            m
        })
        .collect()
}

/// Σ over the film of each channel of `img`.
pub fn channel_sums(img: &Image) -> [f64; 3] {
    img.data
        .iter()
        .fold([0.0; 3], |a, p| [a[0] + p[0], a[1] + p[1], a[2] + p[2]])
}

#[cfg(test)]
mod tests;
