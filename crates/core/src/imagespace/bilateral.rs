//! The bilateral filter (Tomasi & Manduchi 1998) as docs/filter.md §3 fixes it:
//! spatial weight exp(−d²/(2 σ_s²)) over the (2⌈3σ_s⌉+1)² window, range
//! weight exp(−ΔE²/(2 σ_r²)) with ΔE the CIELAB distance of the two pixels'
//! colours (CIE76, with the joint space's white), the window clipped at the
//! border and the result normalised by the sum of the weights used.

use crate::par::prelude::*;

use crate::config::FilterConfig;
use crate::joint::lab::rgb_to_lab;
use crate::recon::Image;

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct BilateralParams {
    /// Spatial standard deviation in pixels (default 2).
    pub sigma_s: f64,
    /// Range standard deviation in ΔE units (default 20).
    pub sigma_r: f64,
}

impl Default for BilateralParams {
    fn default() -> Self {
        FilterConfig::DEFAULT.bilateral()
    }
}

/// Filters every frame of `img`; `white` is the Lab white luminance.
pub fn bilateral(img: &Image, occupancy: &[u32], p: BilateralParams, white: f64) -> Image {
    let (w, h) = (img.width, img.height);
    let radius = (3.0 * p.sigma_s).ceil() as isize;
    let spatial: Vec<f64> = (-radius..=radius)
        .map(|d| (-(d * d) as f64 / (2.0 * p.sigma_s * p.sigma_s)).exp())
        .collect();
    let lab: Vec<[f64; 3]> = img.data.par_iter().map(|&c| rgb_to_lab(c, white)).collect();
    let mut out = Image::new(w, h, img.frames);
    out.data
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(row, line)| {
            let (frame, y) = (row / h, (row % h) as isize);
            let base = frame * w * h;
            for (x, out_px) in line.iter_mut().enumerate() {
                let centre = base + y as usize * w + x;
                if occupancy[centre] == 0 {
                    continue;
                }
                let (mut sum, mut wsum) = ([0.0f64; 3], 0.0f64);
                for dy in -radius..=radius {
                    let yy = y + dy;
                    if yy < 0 || yy >= h as isize {
                        continue;
                    }
                    for dx in -radius..=radius {
                        let xx = x as isize + dx;
                        if xx < 0 || xx >= w as isize {
                            continue;
                        }
                        let q = base + yy as usize * w + xx as usize;
                        if occupancy[q] == 0 {
                            continue;
                        }
                        let de2: f64 = (0..3).map(|c| (lab[q][c] - lab[centre][c]).powi(2)).sum();
                        let wt = spatial[(dx + radius) as usize]
                            * spatial[(dy + radius) as usize]
                            * (-de2 / (2.0 * p.sigma_r * p.sigma_r)).exp();
                        for (acc, v) in sum.iter_mut().zip(img.data[q]) {
                            *acc += wt * v;
                        }
                        wsum += wt;
                    }
                }
                // The centre's own weight is 1, so wsum ≥ 1.
                *out_px = sum.map(|s| s / wsum);
            }
        });
    out
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
