//! Held-out halves: which of two estimates of a white pixel is nearer the
//! truth, judged on samples the estimate was not made from
//! (docs/filter.md F10, "Held-out halves").
//!
//! Each pixel's valid samples are split in two halves by their ordinal in
//! file order (even, odd). An image G_k made from half k alone is nearly
//! independent of the other half's mean x̄_j (the filter's decisions saw
//! both), so (G_k − x̄_j)² less x̄_j's variance (its own s²/n) estimates
//! G_k's squared error, and Var(x̄_k) is x̄_k's own. Their difference,
//! averaged over both ways round and summed over a window, says whether
//! the mean or the denoised image is nearer the truth there (the
//! dual-buffer error estimates of adaptive rendering; Rousselle, Knaus and
//! Zwicker, "Adaptive Rendering with Non-Local Means Filtering", SIGGRAPH
//! Asia 2012). The estimate compares half-sample images; the full mean's
//! variance is half its half's, and a denoiser's bias is not, so it leans
//! towards the denoiser.
//!
//! Only what the display shows as white in both G and x̄ is decided (whole
//! pixels white on every channel, or each white channel on its own:
//! [`Whites`]): there the two look the same and the linear error is the
//! only one, which the estimate measures. Elsewhere a choice of the noisy
//! mean would be seen.

use super::Image;
use super::confidence::{Interval, Moments};
use super::per_pixel::{self, RowBand};
use super::statmc::Stats;
use crate::dump::{Header, Record};
use crate::par::prelude::*;

/// The window's half-width in pixels: statmc's (17 × 17).
pub const RADIUS: usize = super::statmc::RADIUS;

/// Per pixel, one half's moments of its valid samples and `S` of its
/// accepted ones.
#[derive(Clone, Default)]
pub(crate) struct HalfFold<S> {
    pub(crate) all: Moments,
    pub(crate) accepted: S,
}

/// statmc's window reads the accepted samples' statistics.
impl AsRef<Stats> for HalfFold<Stats> {
    fn as_ref(&self) -> &Stats {
        &self.accepted
    }
}

/// Per pixel, both halves' [`HalfFold`]s: `half[0]` of the even ordinals
/// among its valid samples in file order, `half[1]` of the odd ones.
#[derive(Clone, Default)]
pub(crate) struct Halves<S> {
    /// The pixel's valid samples seen so far, of both halves.
    seen: u32,
    pub(crate) half: [HalfFold<S>; 2],
}

/// Bytes of one band's [`Halves`]: the halves' intervals and statmc's
/// window are made band by band ([`fold_halves`]), where the folds of
/// the whole film were 348 MB a half at 1080p (docs/BENCHMARKS.md). A
/// few rows in this crate's own tests, so that their small films are
/// banded.
pub(crate) const BAND_BYTES: usize = if cfg!(test) { 8 << 10 } else { 64 << 20 };

/// The film's bands for [`fold_halves`] of `S`, of about `budget` bytes
/// of folds ([`BAND_BYTES`]), with `halo` rows either side: what is made
/// from a band's folds reads that far (one row for the intervals' 3 × 3
/// neighbourhoods).
pub(crate) fn bands<S>(h: &Header, halo: usize, budget: usize) -> Vec<RowBand> {
    per_pixel::row_bands(h, size_of::<Halves<S>>(), budget, halo)
}

/// Each band's [`Halves`] of its pixels, given to `each(band, folds)` in
/// turn, or the film's as one band where the dump cannot be read in
/// place ([`per_pixel::fold_in_bands`]): both halves from one read of
/// the dump. `accepted(i)` says whether record i was accepted, `add` is
/// `S`'s update. Only the pixels `wanted` marks are folded (all where it
/// is None); the others' folds stay empty.
#[allow(clippy::too_many_arguments)]
pub(crate) fn fold_halves<S: Default + Clone + Send>(
    records: &[Record],
    h: &Header,
    bands: &[RowBand],
    wanted: Option<&[bool]>,
    accepted: impl Fn(usize) -> bool + Sync,
    add: impl Fn(&mut S, [f64; 3]) + Sync,
    each: impl FnMut(&RowBand, &[Halves<S>]),
) {
    let jobs = crate::par::current_num_threads();
    let item = |i: usize, r: &Record| {
        let colour = [r.r as f64, r.g as f64, r.b as f64];
        let picked = wanted.is_none_or(|w| w[r.pixel_index(h)]);
        picked.then(|| (colour, accepted(i)))
    };
    let fold = |f: &mut Halves<S>, (x, acc): ([f64; 3], bool)| {
        let half = &mut f.half[f.seen as usize % 2];
        f.seen += 1;
        half.all.add(x);
        if acc {
            add(&mut half.accepted, x);
        }
    };
    per_pixel::fold_in_bands(records, h, bands, jobs, item, fold, each)
}

/// Half `k`'s folds of a band's [`Halves`], which statmc's window reads.
pub(crate) fn half_of<S>(folds: &[Halves<S>], k: usize) -> Vec<&HalfFold<S>> {
    folds.iter().map(|f| &f.half[k]).collect()
}

/// The pixels the halves decide, in order: some channel white in both G
/// and x̄ ([`Whites::shown`]) and four valid samples or more (two in each
/// half). The decision reads the halves there alone, so of each half
/// only those pixels are kept.
pub struct Decided(Vec<usize>);

impl Decided {
    /// The pixels of `g`, made from all the samples with `all` their
    /// intervals, that `whites` decides; `white` the linear value the
    /// display shows as white.
    pub fn of(g: &Image, all: &Interval, white: f64, whites: Whites) -> Decided {
        let shown = |px: usize| whites.shown(&g.data[px], &all.centre.data[px], white);
        let film = (0..g.data.len()).into_par_iter();
        Decided(
            film.filter(|&px| all.count[px] >= 4 && shown(px).contains(&true))
                .collect(),
        )
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Per pixel of the film `h`, whether it lies within `r` pixels (each
    /// way, in its frame) of a decided one.
    pub fn around(&self, h: &Header, r: usize) -> Vec<bool> {
        let (w, ht) = (h.width as usize, h.height as usize);
        let mut flat = vec![0.0; h.pixels() * h.frames as usize];
        for &px in &self.0 {
            flat[px] = 1.0;
        }
        let sums = window_sums(&flat, w, ht, r);
        sums.into_par_iter().map(|s| s > 0.0).collect()
    }

    /// statmc's window of a band's `folds` (with `guide`, the band's
    /// share of the renderer's features) at the decided pixels of the
    /// band's own rows, each written to its place in `out` (one per
    /// decided pixel, in their order): a band given again, as the film
    /// after bands that were read in place, writes the same places.
    pub(crate) fn window_at<S: AsRef<Stats> + Sync>(
        &self,
        band: &RowBand,
        folds: &[S],
        guide: Option<super::statmc::Guide>,
        out: &mut [[f64; 3]],
    ) {
        let (places, at) = self.in_band(band);
        let window = super::statmc::Window::new(folds, &band.header, guide);
        out[places].copy_from_slice(&window.denoise_at(&band.header, &at));
    }

    /// Where the decided pixels of `band`'s own rows lie in the order, and
    /// each one's index among the band's folded pixels.
    pub(crate) fn in_band(&self, band: &RowBand) -> (std::ops::Range<usize>, Vec<usize>) {
        let first = band.pixels.start;
        let own = first + band.own.start..first + band.own.end;
        let from = self.0.partition_point(|&px| px < own.start);
        let to = self.0.partition_point(|&px| px < own.end);
        (
            from..to,
            self.0[from..to].iter().map(|px| px - first).collect(),
        )
    }

    /// Intervals at the decided pixels, in their order, before any
    /// band's are put ([`Interval::put_at`]): none has a sample.
    pub(crate) fn empty_interval(&self, z: f64) -> Interval {
        let row = || self.map(|_| [0.0; 3]);
        Interval {
            centre: row(),
            half_width: row(),
            count: vec![0; self.0.len()],
            own_se: row(),
            z,
        }
    }

    /// How many pixels are decided.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// `img`'s decided pixels, in their order, as one row.
    pub fn image(&self, img: &Image) -> Image {
        self.map(|px| img.data[px])
    }

    /// `at(px)` of each decided pixel px, in their order, as one row.
    pub fn map(&self, at: impl Fn(usize) -> [f64; 3]) -> Image {
        Image {
            width: self.0.len(),
            height: 1,
            frames: 1,
            data: self.0.iter().map(|&px| at(px)).collect(),
        }
    }

    /// `all`'s intervals at the decided pixels, in their order, as one row
    /// (their variances already pooled over the film's neighbours).
    #[cfg(test)]
    pub fn interval(&self, all: &Interval) -> Interval {
        Interval {
            centre: self.image(&all.centre),
            half_width: self.image(&all.half_width),
            count: self.0.iter().map(|&px| all.count[px]).collect(),
            own_se: self.image(&all.own_se),
            z: all.z,
        }
    }
}

/// What the decision reads of one half at a decided pixel: the image made
/// from its samples alone, and their mean, own standard error and count.
struct HalfPixel {
    image: [f64; 3],
    mean: [f64; 3],
    own_se: [f64; 3],
    count: u32,
}

/// One half at the [`Decided`] pixels, in their order.
pub struct Half(Vec<HalfPixel>);

impl Half {
    /// The half's `image` and its intervals `all`, both at the decided
    /// pixels in their order ([`Decided::image`], [`Decided::empty_interval`]).
    pub fn new(image: &Image, all: &Interval) -> Half {
        debug_assert_eq!(image.data.len(), all.count.len());
        let at = |i: usize| HalfPixel {
            image: image.data[i],
            mean: all.centre.data[i],
            own_se: all.own_se.data[i],
            count: all.count[i],
        };
        Half((0..all.count.len()).map(at).collect())
    }
}

/// What the halves decide: where the display shows both G and x̄ as white,
/// it cannot tell them apart, and only the linear error differs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Whites {
    /// Pixels white on every channel, as a whole (the sum of the channels'
    /// estimates): `guided_oidn`.
    Pixels,
    /// Each channel white in both, on its own (a coloured highlight's
    /// saturated channel too): `guided`, whose statmc window averages such
    /// a channel with its neighbours (docs/RESULTS.md, "The guided image").
    Channels,
}

impl Whites {
    /// Which channels of a pixel are decided, G's value `g` and the mean
    /// `x` (made from two samples or more) given.
    pub fn shown(self, g: &[f64; 3], x: &[f64; 3], white: f64) -> [bool; 3] {
        let each: [bool; 3] = std::array::from_fn(|c| g[c] >= white && x[c] >= white);
        match self {
            Whites::Pixels => [each.iter().all(|&w| w); 3],
            Whites::Channels => each,
        }
    }
}

/// `g` (made from all the samples, with `all` their intervals) with every
/// decided pixel (channel, under [`Whites::Channels`]) set to its mean x̄
/// where the window's held-out estimate says
/// x̄'s squared error is the smaller; a pixel holding a rejected sample
/// (`accepted[px]` below its count) only where its own estimate says so
/// too, so that no neighbour's evidence restores an outlier the filter
/// rejected. `halves[k]` is half k's [`Half`] at the `decided` pixels;
/// `white` the linear value the display shows as white; `whites` what is
/// decided, channel by channel (a white pixel's channels together under
/// [`Whites::Pixels`]).
pub fn prefer_mean(
    g: &mut Image,
    all: &Interval,
    accepted: &[u32],
    halves: [&Half; 2],
    decided: &Decided,
    white: f64,
    whites: Whites,
) {
    let (w, ht) = (g.width, g.height);
    debug_assert!(halves.iter().all(|h| h.0.len() == decided.0.len()));
    // Per decided pixel and channel: MSE(G) − MSE(x̄), estimated from the
    // halves (None where the channel is not decided; a non-finite
    // estimate decides nothing, nor its window's sum).
    let delta: Vec<[Option<f64>; 3]> = (decided.0.par_iter().enumerate())
        .map(|(i, &px)| {
            let [a, b] = halves.map(|h| &h.0[i]);
            // A decided pixel has four samples or more; each half needs two.
            let counted = a.count >= 2 && b.count >= 2;
            let shown = whites.shown(&g.data[px], &all.centre.data[px], white);
            let d: [Option<f64>; 3] = std::array::from_fn(|c| {
                if !(counted && shown[c]) {
                    return None;
                }
                let (va, vb) = (a.own_se[c] * a.own_se[c], b.own_se[c] * b.own_se[c]);
                let held =
                    ((a.image[c] - b.mean[c]).powi(2) + (b.image[c] - a.mean[c]).powi(2)) / 2.0;
                Some(held - va - vb)
            });
            let finite = |d: Option<f64>| d.filter(|d| d.is_finite());
            match whites {
                Whites::Channels => d.map(finite),
                Whites::Pixels => [finite(d.into_iter().sum::<Option<f64>>()); 3],
            }
        })
        .collect();
    // Under Pixels the channels' estimates are one, and so is their sum.
    let channels = match whites {
        Whites::Pixels => 1,
        Whites::Channels => 3,
    };
    let sums: Vec<Vec<f64>> = (0..channels)
        .map(|c| {
            let mut flat = vec![0.0; g.data.len()];
            for (d, &px) in delta.iter().zip(&decided.0) {
                flat[px] = d[c].unwrap_or(0.0);
            }
            window_sums(&flat, w, ht, RADIUS)
        })
        .collect();
    for (d, &px) in delta.iter().zip(&decided.0) {
        let own = |d: f64| accepted[px] == all.count[px] || d > 0.0;
        for c in 0..3 {
            if d[c].is_some_and(own) && sums[c.min(channels - 1)][px] > 0.0 {
                g.data[px][c] = all.centre.data[px][c];
            }
        }
    }
}

/// Per pixel the sum of `v` over the (2r + 1)² window around it, within
/// its frame; rows first, then columns, each in a fixed order.
fn window_sums(v: &[f64], w: usize, h: usize, r: usize) -> Vec<f64> {
    let sum = |get: &dyn Fn(usize) -> f64, i: usize, len: usize| -> f64 {
        (i.saturating_sub(r)..(i + r + 1).min(len)).map(get).sum()
    };
    let rows: Vec<f64> = (0..v.len())
        .into_par_iter()
        .map(|px| {
            let (row, x) = (px - px % w, px % w);
            sum(&|q| v[row + q], x, w)
        })
        .collect();
    (0..v.len())
        .into_par_iter()
        .map(|px| {
            let frame = px / (w * h) * w * h;
            let (y, x) = ((px - frame) / w, px % w);
            sum(&|q| rows[frame + q * w + x], y, h)
        })
        .collect()
}

#[cfg(test)]
mod tests;
