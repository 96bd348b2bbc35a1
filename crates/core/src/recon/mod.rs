//! Reconstruction (docs/filter.md §3): per-pixel weighted means `Σ w c / Σ w` under a
//! reconstruction filter W, accumulated in f64 in file order so that the
//! result does not depend on the thread count.

pub mod clamp;
pub mod confidence;
pub mod energy;
pub mod groups;
pub mod guided;
pub mod held_out;
pub mod median;
pub mod mon;
pub mod per_pixel;
pub mod robust;
pub mod rwmc;
pub mod statmc;

use std::sync::Arc;

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
        let sum = &mut self.sum;
        footprint(self.filter, self.width, self.height, r, |px, w| {
            add(&mut sum[px], c, w)
        });
    }

    /// The film of every record `colour(i, r)` gives a colour to; `colour`
    /// is called for valid records only. Each pixel sums its samples in
    /// file order, so the bytes do not depend on the thread count: a box
    /// film is a per-pixel fold ([`per_pixel::fold_colours`], in place for
    /// a pixel- or pass-major dump); otherwise the film's rows are split
    /// into one band a thread, and each band scans every record for the
    /// samples that reach its rows.
    pub fn of_records(
        h: &Header,
        filter: ReconFilter,
        records: &[Record],
        colour: impl Fn(usize, &Record) -> Option<[f64; 3]> + Sync,
    ) -> Film {
        use crate::par::prelude::*;
        if filter == ReconFilter::Box {
            let jobs = crate::par::current_num_threads();
            let sum = per_pixel::fold_colours(records, h, jobs, colour, |acc, c| add(acc, c, 1.0));
            return Film {
                width: h.width as usize,
                height: h.height as usize,
                filter,
                sum,
            };
        }
        let mut film = Film::new(h, filter);
        let (width, height) = (film.width, film.height);
        let rows = film.sum.len() / width.max(1);
        let band_rows = rows.div_ceil(crate::par::current_num_threads()).max(1);
        // How far from its own row a sample reaches (a box film was
        // folded above).
        let reach = match filter {
            ReconFilter::Box => 1.0,
            ReconFilter::Gaussian { radius, .. } => radius + 1.0,
        };
        film.sum
            .par_chunks_mut(band_rows * width.max(1))
            .enumerate()
            .for_each(|(band, sum)| {
                let first = band * band_rows;
                let base = first * width;
                let (lo, hi) = (first as f64, (first + sum.len() / width) as f64);
                for (i, r) in records.iter().enumerate() {
                    // A cheap test before the validity check (its frame, then its row);
                    // a NaN passes it, and the check rejects it.
                    let row = (r.t as f64).floor() * height as f64 + r.y as f64;
                    if row + reach < lo || row - reach >= hi || r.validity(h) != Validity::Valid {
                        continue;
                    }
                    let Some(c) = colour(i, r) else { continue };
                    footprint(filter, width, height, r, |px, w| {
                        if let Some(acc) = px.checked_sub(base).and_then(|p| sum.get_mut(p)) {
                            add(acc, c, w);
                        }
                    });
                }
            });
        film
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

/// Calls `f(pixel, weight)` for every pixel a valid record weighs on under
/// `filter`.
#[inline]
fn footprint(
    filter: ReconFilter,
    width: usize,
    height: usize,
    r: &Record,
    mut f: impl FnMut(usize, f64),
) {
    let frame_base = r.t as usize * width * height;
    match filter {
        ReconFilter::Box => f(frame_base + r.y as usize * width + r.x as usize, 1.0),
        ReconFilter::Gaussian { s, radius } => {
            let (x, y) = (r.x as f64, r.y as f64);
            // Pixel centres i + 0.5 within radius of x.
            let span = |v: f64, n: usize| {
                let lo = (v - radius - 0.5).ceil().max(0.0) as usize;
                let hi = (v + radius - 0.5).floor().min(n as f64 - 1.0);
                (lo, hi)
            };
            let (i0, i1) = span(x, width);
            let (j0, j1) = span(y, height);
            if i1 < 0.0 || j1 < 0.0 {
                return;
            }
            for j in j0..=j1 as usize {
                let dy = j as f64 + 0.5 - y;
                for i in i0..=i1 as usize {
                    let dx = i as f64 + 0.5 - x;
                    let d2 = dx * dx + dy * dy;
                    if d2 <= radius * radius {
                        f(frame_base + j * width + i, (-d2 / (2.0 * s * s)).exp());
                    }
                }
            }
        }
    }
}

#[inline]
fn add(acc: &mut [f64; 4], c: [f64; 3], w: f64) {
    acc[0] += w * c[0];
    acc[1] += w * c[1];
    acc[2] += w * c[2];
    acc[3] += w;
}

/// The mean and filtered images of docs/filter.md §3, shared (not copied)
/// with the images a run returns.
pub struct Reconstruction {
    pub mean: Arc<Image>,
    pub filtered: Arc<Image>,
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
    accepted: impl Fn(usize) -> bool + Sync,
) -> Reconstruction {
    let (mean, occupancy) = mean(records, h, filter);
    Reconstruction::new(records, h, filter, Arc::new(mean), occupancy, accepted)
}

/// The mean of all valid samples and every pixel's number of them (its
/// occupancy): what needs no decision.
pub fn mean(records: &[Record], h: &Header, filter: ReconFilter) -> (Image, Vec<u32>) {
    // One thread: the mean is made beside the replay, which has the others.
    let mut film = Film::new(h, filter);
    let mut occupancy = vec![0u32; h.pixels() * h.frames as usize];
    for r in records {
        if r.validity(h) == Validity::Valid {
            occupancy[r.pixel_index(h)] += 1;
            film.splat(r);
        }
    }
    (film.resolve(&occupancy), occupancy)
}

impl Reconstruction {
    /// `mean` and `occupancy` (from [`mean`]) with the filtered image of
    /// the records `accepted(i)` says are accepted.
    pub fn new(
        records: &[Record],
        h: &Header,
        filter: ReconFilter,
        mean: Arc<Image>,
        occupancy: Vec<u32>,
        accepted: impl Fn(usize) -> bool + Sync,
    ) -> Reconstruction {
        let film = Film::of_records(h, filter, records, |i, r| {
            accepted(i).then_some([r.r as f64, r.g as f64, r.b as f64])
        });
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
            filtered: Arc::new(filtered),
            empty_pixels: occupancy.iter().filter(|&&n| n == 0).count() as u64,
            fallback_pixels: fallback.len() as u64,
            occupancy,
        }
    }

    /// Every sample accepted: the filtered image is the mean (no pixel
    /// falls back, since each sample weighs on its own pixel).
    pub fn all_accepted(mean: Arc<Image>, occupancy: Vec<u32>) -> Reconstruction {
        Reconstruction {
            filtered: Arc::clone(&mean),
            mean,
            empty_pixels: occupancy.iter().filter(|&&n| n == 0).count() as u64,
            fallback_pixels: 0,
            occupancy,
        }
    }
}

/// A 1 × 1 film of grey `v`, for the tests of this module's estimators.
#[cfg(test)]
pub(crate) fn test_pixel(v: f64) -> Image {
    Image {
        width: 1,
        height: 1,
        frames: 1,
        data: vec![[v; 3]],
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dump::Order;

    /// The box film of a pixel- or pass-major dump, folded in place, is
    /// the film of one serial pass in file order, on 1 to 3 threads, and
    /// with a record that is not where its order puts it.
    #[test]
    fn in_place_box_films_are_the_serial_film() {
        for order in [Order::PassMajor, Order::PixelMajor] {
            for misplace in [false, true] {
                let p = crate::synth::SynthParams {
                    width: 9,
                    height: 6,
                    spp: 5,
                    frames: 2,
                    order,
                    ..crate::synth::SynthParams::default()
                };
                let h = p.header();
                let mut records: Vec<Record> = p.records().collect();
                if misplace {
                    records[37].x = (records[37].x + 1.0) % 9.0;
                }
                records[11].r = f32::NAN;
                let keep = |i: usize| !i.is_multiple_of(4);
                // A colour of the record's own, not only its RGB.
                let colour = |i: usize, r: &Record| {
                    keep(i).then_some([r.r as f64, 3.0 * r.x as f64, r.b as f64])
                };
                let mut serial = Film::new(&h, ReconFilter::Box);
                for (i, r) in records.iter().enumerate() {
                    if r.validity(&h) == Validity::Valid
                        && let Some(c) = colour(i, r)
                    {
                        serial.splat_rgb(r, c);
                    }
                }
                for threads in 1..=3 {
                    let pool = crate::par::pool(threads).unwrap();
                    let film =
                        pool.install(|| Film::of_records(&h, ReconFilter::Box, &records, colour));
                    assert!(film.width == 9 && film.height == 6);
                    assert!(film.sum == serial.sum, "{order:?}, {threads} threads");
                }
            }
        }
    }

    /// The banded film is the film of one serial pass in file order, for
    /// any number of bands, both filters, several frames and invalid
    /// records among the valid ones.
    #[test]
    fn banded_films_are_the_serial_film() {
        let mut h = test_header(7, 5);
        h.frames = 3;
        let mut unit = crate::synth::test_units(7);
        let mut records: Vec<Record> = (0..2000)
            .map(|_| {
                let (x, y, t) = (unit() * 7.0, unit() * 5.0, unit() * 3.0);
                Record::new(
                    x as f32,
                    y as f32,
                    t as f32,
                    [unit() as f32, 2.0, 100.0 * unit() as f32],
                )
            })
            .collect();
        records[5].t = f32::NAN;
        records[9].y = -1.0;
        records[11].t = 1e30;
        let keep = |i: usize| !i.is_multiple_of(3);
        for filter in [ReconFilter::Box, ReconFilter::gaussian()] {
            let mut serial = Film::new(&h, filter);
            for (i, r) in records.iter().enumerate() {
                if r.validity(&h) == Validity::Valid && keep(i) {
                    serial.splat(r);
                }
            }
            for threads in 1..=5 {
                let pool = crate::par::pool(threads).unwrap();
                let banded = pool.install(|| {
                    Film::of_records(&h, filter, &records, |i, r| {
                        keep(i).then_some([r.r as f64, r.g as f64, r.b as f64])
                    })
                });
                assert!(banded.sum == serial.sum, "{filter:?}, {threads} threads");
            }
        }
    }
}
