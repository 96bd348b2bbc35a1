//! Reconstruction (docs/filter.md §3): per-pixel weighted means `Σ w c / Σ w` under a
//! reconstruction filter W, accumulated in f64 in file order so that the
//! result does not depend on the thread count.

pub mod clamp;
pub mod confidence;
pub mod energy;
pub mod groups;
pub mod guided;
pub mod median;
pub mod mon;
pub mod robust;
pub mod rwmc;
pub mod statmc;

use crate::dump::{Header, Record, Validity};
pub use pathdensity_format::image::{Image, stored};

/// The reconstruction filter W (the paper's sensor response).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum ReconFilter {
    /// A sample counts for the pixel that contains it, weight 1.
    Box,
    /// Weight exp(−d²/(2 s²)) for pixel centres within distance ≤ `radius`.
    Gaussian { s: f64, radius: f64 },
}

impl ReconFilter {
    pub fn gaussian() -> ReconFilter {
        ReconFilter::Gaussian {
            s: 0.5,
            radius: 1.5,
        }
    }
}

/// A film accumulating weighted sums: RGB and the weight, per pixel.
pub struct Film {
    width: usize,
    height: usize,
    filter: ReconFilter,
    sum: Vec<[f64; 4]>,
}

impl Film {
    pub fn new(h: &Header, filter: ReconFilter) -> Film {
        Film {
            width: h.width as usize,
            height: h.height as usize,
            filter,
            sum: vec![[0.0; 4]; h.pixels() * h.frames as usize],
        }
    }

    /// Splats a valid record.
    #[inline]
    pub fn splat(&mut self, r: &Record) {
        self.splat_rgb(r, [r.r as f64, r.g as f64, r.b as f64]);
    }

    /// Splats colour `c` at a valid record's position.
    #[inline]
    pub fn splat_rgb(&mut self, r: &Record, c: [f64; 3]) {
        let frame_base = r.t as usize * self.width * self.height;
        match self.filter {
            ReconFilter::Box => {
                let px = frame_base + r.y as usize * self.width + r.x as usize;
                add(&mut self.sum[px], c, 1.0);
            }
            ReconFilter::Gaussian { s, radius } => {
                let (x, y) = (r.x as f64, r.y as f64);
                // Pixel centres i + 0.5 within radius of x.
                let span = |v: f64, n: usize| {
                    let lo = (v - radius - 0.5).ceil().max(0.0) as usize;
                    let hi = (v + radius - 0.5).floor().min(n as f64 - 1.0);
                    (lo, hi)
                };
                let (i0, i1) = span(x, self.width);
                let (j0, j1) = span(y, self.height);
                if i1 < 0.0 || j1 < 0.0 {
                    return;
                }
                for j in j0..=j1 as usize {
                    let dy = j as f64 + 0.5 - y;
                    for i in i0..=i1 as usize {
                        let dx = i as f64 + 0.5 - x;
                        let d2 = dx * dx + dy * dy;
                        if d2 <= radius * radius {
                            let w = (-d2 / (2.0 * s * s)).exp();
                            add(&mut self.sum[frame_base + j * self.width + i], c, w);
                        }
                    }
                }
            }
        }
    }

    /// Σ w of one pixel.
    pub fn weight(&self, px: usize) -> f64 {
        self.sum[px][3]
    }

    /// The weighted mean of every pixel (docs/filter.md F7); pixels with no
    /// valid sample of their own (`occupancy` 0) are 0, as §3 requires.
    pub fn resolve(&self, occupancy: &[u32]) -> Image {
        let frames = self.sum.len() / (self.width * self.height).max(1);
        let mut img = Image::new(self.width, self.height, frames);
        for ((out, s), &n) in img.data.iter_mut().zip(&self.sum).zip(occupancy) {
            if n > 0 && s[3] > 0.0 {
                *out = [s[0] / s[3], s[1] / s[3], s[2] / s[3]];
            }
        }
        img
    }
}

#[inline]
fn add(acc: &mut [f64; 4], c: [f64; 3], w: f64) {
    acc[0] += w * c[0];
    acc[1] += w * c[1];
    acc[2] += w * c[2];
    acc[3] += w;
}

/// The mean and filtered images of docs/filter.md §3.
pub struct Reconstruction {
    pub mean: Image,
    pub filtered: Image,
    pub occupancy: Vec<u32>,
    /// Pixels with valid samples but no accepted weight, which fell back to
    /// their median.
    pub fallback_pixels: u64,
    /// Pixels that contain no valid sample.
    pub empty_pixels: u64,
}

/// Reconstructs the mean of all valid samples and the filtered image of the
/// accepted ones (`accepted(i)` for record i), with the median fallback.
pub fn reconstruct(
    records: &[Record],
    h: &Header,
    filter: ReconFilter,
    accepted: impl Fn(usize) -> bool,
) -> Reconstruction {
    let (mean, occupancy) = mean(records, h, filter);
    Reconstruction::new(records, h, filter, mean, occupancy, accepted)
}

/// The mean of all valid samples and every pixel's number of them (its
/// occupancy): what needs no decision.
pub fn mean(records: &[Record], h: &Header, filter: ReconFilter) -> (Image, Vec<u32>) {
    let mut film = Film::new(h, filter);
    let mut occ = vec![0u32; h.pixels() * h.frames as usize];
    for r in records {
        if r.validity(h) == Validity::Valid {
            occ[r.pixel_index(h)] += 1;
            film.splat(r);
        }
    }
    (film.resolve(&occ), occ)
}

impl Reconstruction {
    /// `mean` and `occupancy` (from [`mean`]) with the filtered image of
    /// the records `accepted(i)` says are accepted.
    pub fn new(
        records: &[Record],
        h: &Header,
        filter: ReconFilter,
        mean: Image,
        occupancy: Vec<u32>,
        accepted: impl Fn(usize) -> bool,
    ) -> Reconstruction {
        let mut film = Film::new(h, filter);
        for (i, r) in records.iter().enumerate() {
            if r.validity(h) == Validity::Valid && accepted(i) {
                film.splat(r);
            }
        }
        let mut filtered = film.resolve(&occupancy);
        let fallback: Vec<usize> = (0..occupancy.len())
            .filter(|&px| occupancy[px] > 0 && film.weight(px) == 0.0)
            .collect();
        let medians = median::pixel_medians(records, h, &fallback);
        for (&px, m) in fallback.iter().zip(medians) {
            filtered.data[px] = m;
        }
        Reconstruction {
            mean,
            filtered,
            empty_pixels: occupancy.iter().filter(|&&n| n == 0).count() as u64,
            fallback_pixels: fallback.len() as u64,
            occupancy,
        }
    }

    /// Every sample accepted: the filtered image is the mean (no pixel
    /// falls back, since each sample weighs on its own pixel).
    pub fn all_accepted(mean: Image, occupancy: Vec<u32>) -> Reconstruction {
        Reconstruction {
            filtered: mean.clone(),
            mean,
            empty_pixels: occupancy.iter().filter(|&&n| n == 0).count() as u64,
            fallback_pixels: 0,
            occupancy,
        }
    }
}

/// A still film's header with nothing else set, for the tests of this
/// module's estimators.
#[cfg(test)]
pub(crate) fn test_header(width: u32, height: u32) -> Header {
    Header {
        width,
        height,
        frames: 1,
        spp: 0,
        sample_count: 0,
        order: crate::dump::Order::Unspecified,
        scene: String::new(),
        seed: 0,
        producer: String::new(),
    }
}
