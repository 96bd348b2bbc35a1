//! The bilateral filter (Tomasi & Manduchi 1998) as docs/filter.md §3 fixes it:
//! spatial weight exp(−d²/(2 σ_s²)) over the (2⌈3σ_s⌉+1)² window, range
//! weight exp(−ΔE²/(2 σ_r²)) with ΔE the CIELAB distance of the two pixels'
//! colours (CIE76, with the joint space's white), the window clipped at the
//! border and the result normalised by the sum of the weights used.

use crate::par::prelude::*;

use crate::joint::lab::rgb_to_lab;
use crate::recon::Image;

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct BilateralParams {
    /// Spatial standard deviation in pixels (default 2).
    pub sigma_s: f64,
    /// Range standard deviation in ΔE units (default 20).
    pub sigma_r: f64,
}

impl BilateralParams {
    /// σ_s = 2 px, σ_r = 20 ΔE.
    pub const DEFAULT: BilateralParams = BilateralParams {
        sigma_s: 2.0,
        sigma_r: 20.0,
    };
}

impl Default for BilateralParams {
    fn default() -> Self {
        BilateralParams::DEFAULT
    }
}

/// Filters every frame of `img` (docs/filter.md F8); `white` is the Lab
/// white luminance.
///
/// Both weights are symmetric, so each pair of pixels is weighed once and
/// its weight added to both pixels' sums: half the `exp` calls of a
/// per-pixel loop. Pixels are visited in raster order and each one's sum
/// gets its terms in its window's raster order (the neighbours before it
/// add theirs as they are visited, then its centre, then the neighbours
/// after it), so every output is the per-pixel loop's to the bit. Bands
/// of rows run in parallel; each first weighs the pairs its top rows form
/// with the `radius` rows above it, which the band above weighs too.
pub fn bilateral(img: &Image, occupancy: &[u32], p: BilateralParams, white: f64) -> Image {
    let (w, h) = (img.width, img.height);
    let radius = (3.0 * p.sigma_s).ceil() as usize;
    let spatial: Vec<f64> = (-(radius as isize)..=radius as isize)
        .map(|d| (-(d * d) as f64 / (2.0 * p.sigma_s * p.sigma_s)).exp())
        .collect();
    let lab: Vec<[f64; 3]> = img.data.par_iter().map(|&c| rgb_to_lab(c, white)).collect();
    let pairs = Pairs {
        img,
        occupancy,
        lab: &lab,
        spatial: &spatial,
        radius,
        two_var: 2.0 * p.sigma_r * p.sigma_r,
    };
    // Bands never straddle a frame; their size changes no bit.
    let band = (4 * radius).max(h.div_ceil(2 * crate::par::current_num_threads()));
    let mut out = Image::new(w, h, img.frames);
    out.data
        .par_chunks_mut(w * h)
        .enumerate()
        .for_each(|(frame, frame_out)| {
            frame_out
                .par_chunks_mut(w * band)
                .enumerate()
                .for_each(|(b, rows)| pairs.band(frame, b * band, rows));
        });
    out
}

/// The image's pixel pairs within a window, each weighed once.
struct Pairs<'a> {
    img: &'a Image,
    occupancy: &'a [u32],
    lab: &'a [[f64; 3]],
    /// exp(−d²/(2 σ_s²)) for d = −radius..=radius.
    spatial: &'a [f64],
    radius: usize,
    /// 2 σ_r².
    two_var: f64,
}

impl Pairs<'_> {
    /// The weight of pixels `a` and `b` (flat indices), `b` lying `dx −
    /// radius` columns and `dy − radius` rows from `a`: the same bits from
    /// either side.
    #[inline]
    fn weight(&self, a: usize, b: usize, dx: usize, dy: usize) -> f64 {
        let de2: f64 = (0..3)
            .map(|c| (self.lab[b][c] - self.lab[a][c]).powi(2))
            .sum();
        self.spatial[dx] * self.spatial[dy] * (-de2 / self.two_var).exp()
    }

    /// Filters rows `y0..` of frame `frame` into `out` (whole rows).
    fn band(&self, frame: usize, y0: usize, out: &mut [[f64; 3]]) {
        let (w, h, r) = (self.img.width, self.img.height, self.radius);
        let y1 = y0 + out.len() / w;
        let base = frame * w * h;
        // Per pixel of the band: the weighted sum of colours, then the sum
        // of weights.
        let mut acc = vec![[0.0f64; 4]; out.len()];
        let add = |acc: &mut [f64; 4], wt: f64, c: [f64; 3]| {
            for (a, v) in acc.iter_mut().zip(c) {
                *a += wt * v;
            }
            acc[3] += wt;
        };
        for y in y0.saturating_sub(r)..y1 {
            let own = y >= y0;
            for x in 0..w {
                let a = base + y * w + x;
                if self.occupancy[a] == 0 {
                    continue;
                }
                if own {
                    // Every neighbour before it has added its term.
                    let centre = self.weight(a, a, r, r);
                    add(&mut acc[(y - y0) * w + x], centre, self.img.data[a]);
                }
                // The neighbours after it in raster order; from a row above
                // the band, only those in the band.
                let last = (y + r + 1).min(h);
                let rows = if own { y..last } else { y0..last.min(y1) };
                for yy in rows {
                    let xs = if yy == y { x + 1 } else { x.saturating_sub(r) };
                    for xx in xs..(x + r + 1).min(w) {
                        let b = base + yy * w + xx;
                        if self.occupancy[b] == 0 {
                            continue;
                        }
                        let wt = self.weight(a, b, xx + r - x, yy + r - y);
                        if own {
                            add(&mut acc[(y - y0) * w + x], wt, self.img.data[b]);
                        }
                        if yy < y1 {
                            add(&mut acc[(yy - y0) * w + xx], wt, self.img.data[a]);
                        }
                    }
                }
            }
        }
        let occupied = &self.occupancy[base + y0 * w..base + y1 * w];
        for ((o, a), &n) in out.iter_mut().zip(&acc).zip(occupied) {
            // An occupied pixel's own weight is 1, so a[3] ≥ 1.
            if n != 0 {
                *o = [a[0], a[1], a[2]].map(|s| s / a[3]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: usize, h: usize, f: impl Fn(usize, usize) -> [f64; 3]) -> Image {
        let mut img = Image::new(w, h, 1);
        for y in 0..h {
            for x in 0..w {
                img.data[y * w + x] = f(x, y);
            }
        }
        img
    }

    /// The filter as docs/filter.md §3 states it, one pixel at a time.
    fn per_pixel(img: &Image, occupancy: &[u32], p: BilateralParams, white: f64) -> Image {
        let (w, h) = (img.width as isize, img.height as isize);
        let r = (3.0 * p.sigma_s).ceil() as isize;
        let spatial = |d: isize| (-(d * d) as f64 / (2.0 * p.sigma_s * p.sigma_s)).exp();
        let lab: Vec<[f64; 3]> = img.data.iter().map(|&c| rgb_to_lab(c, white)).collect();
        let mut out = Image::new(img.width, img.height, img.frames);
        for (i, o) in out.data.iter_mut().enumerate() {
            let (base, y, x) = (
                i as isize / (w * h) * w * h,
                i as isize % (w * h) / w,
                i as isize % w,
            );
            if occupancy[i] == 0 {
                continue;
            }
            let (mut sum, mut wsum) = ([0.0f64; 3], 0.0f64);
            for dy in -r..=r {
                for dx in -r..=r {
                    let (yy, xx) = (y + dy, x + dx);
                    if yy < 0 || yy >= h || xx < 0 || xx >= w {
                        continue;
                    }
                    let q = (base + yy * w + xx) as usize;
                    if occupancy[q] == 0 {
                        continue;
                    }
                    let de2: f64 = (0..3).map(|c| (lab[q][c] - lab[i][c]).powi(2)).sum();
                    let wt =
                        spatial(dx) * spatial(dy) * (-de2 / (2.0 * p.sigma_r * p.sigma_r)).exp();
                    for (acc, v) in sum.iter_mut().zip(img.data[q]) {
                        *acc += wt * v;
                    }
                    wsum += wt;
                }
            }
            *o = sum.map(|s| s / wsum);
        }
        out
    }

    /// Weighing each pair once, in bands, gives the per-pixel loop's bits
    /// for any radius, film, hole pattern and thread count (so any band
    /// size).
    #[test]
    fn pairs_in_bands_give_the_per_pixel_bits() {
        let mut next = crate::synth::test_units(7);
        for (w, h, frames, sigma_s) in [
            (37, 29, 2, 2.0),
            (5, 40, 1, 1.1),
            (64, 3, 1, 0.3),
            (1, 1, 1, 2.0),
        ] {
            let mut img = Image::new(w, h, frames);
            let mut occ = vec![0u32; w * h * frames];
            for (px, n) in img.data.iter_mut().zip(&mut occ) {
                let v = next();
                // Holes, fireflies and a smooth rest.
                *n = (v > 0.1) as u32;
                let scale = if v > 0.97 { 50.0 } else { 1.0 };
                *px = [next(), next(), next()].map(|c| c * scale * *n as f64);
            }
            let p = BilateralParams {
                sigma_s,
                sigma_r: 20.0,
            };
            let want = per_pixel(&img, &occ, p, 0.7);
            for threads in [1, 2, 3, 8] {
                let pool = crate::par::pool(threads).unwrap();
                let got = pool.install(|| bilateral(&img, &occ, p, 0.7));
                let same = got
                    .data
                    .iter()
                    .zip(&want.data)
                    .all(|(a, b)| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()));
                assert!(same, "{w}×{h}×{frames}, σ_s {sigma_s}, {threads} threads");
            }
        }
    }

    #[test]
    fn a_flat_image_stays_flat() {
        let img = image(9, 7, |_, _| [0.3, 0.2, 0.1]);
        let out = bilateral(&img, &[1; 63], BilateralParams::default(), 1.0);
        for p in &out.data {
            for (v, want) in p.iter().zip(img.data[0]) {
                assert!((v - want).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn a_step_edge_survives() {
        // Black | white: ΔE = 100 ≫ σ_r = 20, so the other side's weight is
        // exp(−12.5) ≈ 4e-6 at most.
        let img = image(12, 5, |x, _| if x < 6 { [0.0; 3] } else { [1.0; 3] });
        let out = bilateral(&img, &[1; 60], BilateralParams::default(), 1.0);
        for y in 0..5 {
            assert!(out.data[y * 12 + 5][0] < 1e-4);
            assert!(out.data[y * 12 + 6][0] > 1.0 - 1e-4);
        }
    }

    #[test]
    fn a_small_wiggle_is_smoothed_and_empty_pixels_stay_zero() {
        let img = image(9, 9, |x, y| [0.5 + 0.01 * ((x + y) % 2) as f64; 3]);
        let mut occ = vec![1u32; 81];
        occ[40] = 0;
        let out = bilateral(&img, &occ, BilateralParams::default(), 1.0);
        assert_eq!(out.data[40], [0.0; 3]);
        let spread = |i: &Image| {
            let v: Vec<f64> = (0..81).filter(|&p| p != 40).map(|p| i.data[p][0]).collect();
            v.iter().cloned().fold(f64::MIN, f64::max) - v.iter().cloned().fold(f64::MAX, f64::min)
        };
        assert!(spread(&out) < 0.5 * spread(&img));
    }
}
