//! Reweighting firefly samples (rwmc), after Zirr, Hanika and Dachsbacher,
//! "Reweighting firefly samples for improved finite-sample Monte Carlo
//! estimates", Computer Graphics Forum 2018.
//!
//! Instead of rejecting bright samples, each sample is split between two
//! of S framebuffer cascades by its luminance (paper §4, Eq. 8–9), so the
//! plain sum of the cascades is the mean. The reweighting pass (§5) then
//! keeps a bright cascade in a pixel only as far as enough samples in the
//! pixel and its 3 × 3 neighbourhood support it (counting reliability,
//! Eq. 12–13) or the pixel is already bright (colour reliability).
//! Samples are binned by the pixel they fall in (box reconstruction).

use crate::par::prelude::*;

use super::Image;
use crate::dump::{Header, Record, Validity};
use crate::joint::lab::luminance;

/// The method's parameters; the defaults are the authors'.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RwmcParams {
    /// S, the number of cascades (≥ 2).
    pub cascades: usize,
    /// s₀, the luminance where the second cascade starts to fill.
    pub start: f64,
    /// b, the ratio between consecutive cascades (> 1).
    pub base: f64,
    /// κ, the number of samples a bright feature needs to be trusted.
    pub kappa: f64,
    /// Luminance always considered reliable (the colour-reliability floor).
    pub min_luminance: f64,
}

impl RwmcParams {
    /// The authors' defaults (Zirr et al. 2018): S = 6 cascades from
    /// s₀ = 1 with ratio b = 8, κ = 32, reliable below luminance 0.05.
    pub const DEFAULT: RwmcParams = RwmcParams {
        cascades: 6,
        start: 1.0,
        base: 8.0,
        kappa: 32.0,
        min_luminance: 0.05,
    };
}

impl Default for RwmcParams {
    fn default() -> Self {
        RwmcParams::DEFAULT
    }
}

impl RwmcParams {
    /// Where a sample of luminance `l` goes: cascade i gets `w_lo` of its
    /// colour and cascade i + 1 gets `w_hi` (paper Eq. 8–9). Between s₀bⁱ
    /// and s₀bⁱ⁺¹ the split keeps the expected value and is linear in 1/l;
    /// past the last cascade the upper weight clamps the sample.
    ///
    /// ```
    /// use pathdensity_core::recon::rwmc::RwmcParams;
    /// let p = RwmcParams::default();
    /// assert_eq!(p.split(0.5), (0, 1.0, 0.0)); // below s₀: all in cascade 0
    /// assert_eq!(p.split(8.0), (1, 1.0, 0.0)); // exactly s₀b: cascade 1
    /// let (i, lo, hi) = p.split(1e9);          // beyond s₀b⁵: clamped
    /// assert_eq!((i, lo), (4, 0.0));
    /// assert_eq!(hi, 8f64.powi(5) / 1e9);
    /// ```
    pub fn split(&self, l: f64) -> (usize, f64, f64) {
        let (mut i, mut lo, mut hi) = (0, self.start, self.start * self.base);
        while l >= hi && i < self.cascades - 2 {
            lo = hi;
            hi *= self.base;
            i += 1;
        }
        let w_lo = if l <= lo {
            1.0
        } else if l < hi {
            ((lo / l - lo / hi) / (1.0 - lo / hi)).max(0.0)
        } else {
            0.0
        };
        let w_hi = if l < hi {
            (1.0 - w_lo).max(0.0)
        } else {
            hi / l
        };
        (i, w_lo, w_hi)
    }
}

/// Per pixel (frames × height × width), the S cascades' sums divided by the
/// pixel's sample count, and that count.
struct Cascades {
    width: usize,
    height: usize,
    s: usize,
    /// `layers[px * s + i]`.
    layers: Vec<[f64; 3]>,
    /// The luminance of each layer, same indexing (read 3 × 10 times per
    /// pixel and cascade by the reweighting, so computed once).
    lums: Vec<f64>,
    count: Vec<u32>,
}

impl Cascades {
    fn splat(records: &[Record], h: &Header, p: &RwmcParams) -> Cascades {
        let pixels = h.pixels() * h.frames as usize;
        let s = p.cascades;
        let mut layers = vec![[0.0f64; 3]; pixels * s];
        let mut count = vec![0u32; pixels];
        for r in records {
            if r.validity(h) != Validity::Valid {
                continue;
            }
            let px = r.pixel_index(h);
            let c = r.rgb().map(|v| v as f64);
            let (i, w_lo, w_hi) = p.split(luminance(c));
            for (layer, w) in [(i, w_lo), (i + 1, w_hi)] {
                let acc = &mut layers[px * s + layer];
                for ch in 0..3 {
                    acc[ch] += w * c[ch];
                }
            }
            count[px] += 1;
        }
        for (px, &n) in count.iter().enumerate() {
            if n > 0 {
                for v in &mut layers[px * s..(px + 1) * s] {
                    *v = v.map(|x| x / n as f64);
                }
            }
        }
        Cascades {
            width: h.width as usize,
            height: h.height as usize,
            s,
            lums: layers.iter().map(|&c| luminance(c)).collect(),
            layers,
            count,
        }
    }

    /// Luminance of cascade `i` (per-sample average) of pixel (x, y) of
    /// frame `f`; 0 outside the film or the cascade range.
    fn lum(&self, f: usize, x: isize, y: isize, i: isize) -> f64 {
        if x < 0 || y < 0 || x >= self.width as isize || y >= self.height as isize {
            return 0.0;
        }
        if i < 0 || i >= self.s as isize {
            return 0.0;
        }
        let px = (f * self.height + y as usize) * self.width + x as usize;
        self.lums[px * self.s + i as usize]
    }
}

/// The rwmc image: cascades splatted, then reweighted pixel by pixel
/// (paper §5). Pixels without samples are 0.
pub fn rwmc(records: &[Record], h: &Header, p: &RwmcParams) -> Image {
    let cas = Cascades::splat(records, h, p);
    let (w, ht, s) = (cas.width, cas.height, cas.s);
    let inv_kappa = 1.0 / p.kappa;
    // mix(mix(1, b, 0.6), 1, clamp(1/κ, 0, 1)): up to ~b more energy in one
    // sample is accepted relative to the pixel's brightness so far.
    let mix = |a: f64, b: f64, t: f64| a * (1.0 - t) + b * t;
    let colour_slack = mix(mix(1.0, p.base, 0.6), 1.0, inv_kappa.clamp(0.0, 1.0));
    let data: Vec<[f64; 3]> = (0..cas.count.len())
        .into_par_iter()
        .map(|px| {
            let n = cas.count[px];
            if n == 0 {
                return [0.0; 3];
            }
            let (f, rest) = (px / (w * ht), px % (w * ht));
            let (x, y) = ((rest % w) as isize, (rest / w) as isize);
            let mut out = [0.0f64; 3];
            for i in 0..s {
                // N / (κ s₀ bⁱ): the authors' viewer divides by the
                // cascade's start luminance s₀bⁱ, not bⁱ alone, so s₀ sets
                // the brightness at which κ samples make a feature reliable.
                let scale = n as f64 / (p.kappa * p.start * p.base.powi(i as i32));
                // R(r): luminance of the (2r + 1)² window mean of cascade i
                // and its neighbours, brightness-normalised (Eq. 12).
                let reliability = |r: isize| {
                    let mut sum = 0.0;
                    for dy in -r..=r {
                        for dx in -r..=r {
                            let (qx, qy) = (x + dx, y + dy);
                            let ii = i as isize;
                            sum += cas.lum(f, qx, qy, ii)
                                + cas.lum(f, qx, qy, ii - 1) * p.base
                                + cas.lum(f, qx, qy, ii + 1) / p.base;
                        }
                    }
                    scale * sum / ((2 * r + 1) * (2 * r + 1)) as f64
                };
                let global = reliability(1) - inv_kappa;
                let counted = if global >= 0.0 {
                    reliability(0) - inv_kappa
                } else {
                    global
                };
                let colour = (luminance(out) * scale).max(p.min_luminance * scale) * colour_slack;
                let weight = ((counted + colour) * 0.5).clamp(0.0, 1.0);
                let c = cas.layers[px * s + i];
                for ch in 0..3 {
                    out[ch] += weight * c[ch];
                }
            }
            out
        })
        .collect();
    let mut img = Image::for_header(h);
    img.data = data;
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_split_keeps_every_sample_whole_inside_the_cascade_range() {
        let p = RwmcParams::default();
        for l in [0.0, 0.3, 1.0, 1.5, 7.9, 8.0, 100.0, 4000.0, 32767.0] {
            let (i, lo, hi) = p.split(l);
            assert!(i <= 4);
            assert!((lo + hi - 1.0).abs() < 1e-12, "l {l}: {lo} + {hi}");
            // Expected value kept: the split is exact in colour.
            assert!(lo >= 0.0 && hi >= 0.0);
        }
        // l = 2 between s₀ = 1 and 8: w_lo = (1/2 − 1/8) / (1 − 1/8) = 3/7.
        let (i, lo, hi) = p.split(2.0);
        assert_eq!(i, 0);
        assert!((lo - 3.0 / 7.0).abs() < 1e-15 && (hi - 4.0 / 7.0).abs() < 1e-15);
    }

    use crate::dump::{Header, Record};

    /// A w × h film with `n` grey samples of value `v` at every pixel
    /// centre, plus `extra` records.
    fn film(w: u32, h: u32, n: u32, v: f32, extra: &[Record]) -> (Header, Vec<Record>) {
        let header = crate::recon::test_header(w, h);
        let mut recs = Vec::new();
        for y in 0..h {
            for x in 0..w {
                for _ in 0..n {
                    recs.push(Record::new(x as f32 + 0.5, y as f32 + 0.5, 0.0, [v; 3]));
                }
            }
        }
        recs.extend_from_slice(extra);
        (header, recs)
    }

    #[test]
    fn an_undersampled_lowest_cascade_is_weighted_by_hand_computed_reliability() {
        // 64 samples of grey 0.25 per pixel, all in cascade 0 (below s₀ = 1).
        // By hand (paper §5 with the defaults): scale₀ = 64 / (32 · 1 · 1) = 2;
        // R(1) = R(0) = 2 L (the 3 × 3 mean of a flat film, 4/9 of it at a
        // corner, still ≥ 1/κ), so the counting term is 2L − 1/32; nothing
        // is accumulated yet, so the colour term is its floor 0.05 · scale₀
        // times the slack mix(mix(1, 8, 0.6), 1, 1/32) = 5.2 · 31/32 + 1/32;
        // the weight is half their sum.
        let (h, recs) = film(3, 3, 64, 0.25, &[]);
        let img = rwmc(&recs, &h, &RwmcParams::default());
        let l = luminance([0.25; 3]);
        let slack = 5.2 * (31.0 / 32.0) + 1.0 / 32.0;
        let w0 = (2.0 * l - 1.0 / 32.0 + 0.05 * 2.0 * slack) / 2.0;
        for px in [0, 4, 8] {
            for c in 0..3 {
                assert!(
                    (img.data[px][c] - w0 * 0.25).abs() < 1e-12,
                    "{px}: {:?}",
                    img.data[px]
                );
            }
        }
        assert!(w0 > 0.48 && w0 < 0.49);
    }

    #[test]
    fn a_well_sampled_film_is_its_mean_and_a_lone_firefly_is_suppressed() {
        // 1024 samples of 0.5: R = 1024 / 32 · 0.5 = 16 ≥ 1, every weight 1.
        let (h, recs) = film(3, 3, 1024, 0.5, &[]);
        let img = rwmc(&recs, &h, &RwmcParams::default());
        assert!(img.data.iter().flatten().all(|&v| (v - 0.5).abs() < 1e-12));
        // One sample of 5000 in the centre adds 4.88 to its mean; its
        // cascades (4 and 5) hold one sample, far below κ: nearly all of it
        // goes.
        let firefly = Record::new(1.5, 1.5, 0.0, [5000.0; 3]);
        let (h, recs) = film(3, 3, 1024, 0.5, &[firefly]);
        let img = rwmc(&recs, &h, &RwmcParams::default());
        let mean = (1024.0 * 0.5 + 5000.0) / 1025.0;
        let centre = img.data[4][0];
        assert!(
            centre > 0.49 && centre - 0.5 < 0.05 * (mean - 0.5),
            "{centre} vs mean {mean}"
        );
    }
}
