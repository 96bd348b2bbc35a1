//! Error metrics against a reference image (docs/filter.md §4).

use crate::joint::lab::luminance;
use crate::recon::{Image, stored};

/// All metrics of one image against a reference, over a set of pixels.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Metrics {
    /// sqrt(mean over pixels and channels of (I − R)²), linear values.
    pub rms: f64,
    /// The same on display values: clamp(exposure · v, 0, 1), sRGB-encoded.
    pub rms_display: f64,
    /// mean of (I − R)² / (R² + 0.01).
    pub rel_mse: f64,
    /// Σ Y(I) / Σ Y(R); below 1 means energy was lost.
    pub energy_ratio: f64,
    /// Σ I_c / Σ R_c per channel: shows a colour shift (the paper's
    /// Figure 4: the trimmed mean loses the blue light).
    pub energy_ratio_rgb: [f64; 3],
}

/// The sRGB transfer curve for a display value in [0, 1].
pub fn srgb_encode(v: f64) -> f64 {
    if v <= 0.0031308 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Display value of a linear channel: exposed, clamped, encoded.
pub fn display(v: f64, exposure: f64) -> f64 {
    srgb_encode((v * exposure).clamp(0.0, 1.0))
}

/// Metrics of pixels `img` against `reference` (same length). The image is
/// measured as it is written (f32), so a reference read back from an image
/// this tool wrote compares exactly.
pub fn compare_pixels(img: &[[f64; 3]], reference: &[[f64; 3]], exposure: f64) -> Metrics {
    assert_eq!(img.len(), reference.len());
    let (mut se, mut sed, mut rel) = (0.0f64, 0.0f64, 0.0f64);
    let (mut yi, mut yr) = (0.0f64, 0.0f64);
    let (mut ci, mut cr) = ([0.0f64; 3], [0.0f64; 3]);
    for (a, b) in img.iter().zip(reference) {
        let a = &a.map(|v| stored(v) as f64);
        for c in 0..3 {
            ci[c] += a[c];
            cr[c] += b[c];
            let d = a[c] - b[c];
            se += d * d;
            let dd = display(a[c], exposure) - display(b[c], exposure);
            sed += dd * dd;
            rel += d * d / (b[c] * b[c] + 0.01);
        }
        yi += luminance(*a);
        yr += luminance(*b);
    }
    let n = (img.len() * 3).max(1) as f64;
    Metrics {
        rms: (se / n).sqrt(),
        rms_display: (sed / n).sqrt(),
        rel_mse: rel / n,
        energy_ratio: yi / yr,
        energy_ratio_rgb: [0, 1, 2].map(|c| ci[c] / cr[c]),
    }
}

/// Pooled metrics over all frames, and per frame.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ImageMetrics {
    #[serde(flatten)]
    pub pooled: Metrics,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub per_frame: Vec<Metrics>,
}

pub fn compare(img: &Image, reference: &Image, exposure: f64) -> ImageMetrics {
    let pooled = compare_pixels(&img.data, &reference.data, exposure);
    let per_frame = if img.frames > 1 {
        (0..img.frames)
            .map(|f| compare_pixels(img.frame(f), reference.frame(f), exposure))
            .collect()
    } else {
        Vec::new()
    };
    ImageMetrics { pooled, per_frame }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rms_of_a_constant_offset_is_the_offset() {
        let a = vec![[1.5, 1.5, 1.5]; 4];
        let b = vec![[1.0, 1.0, 1.0]; 4];
        let m = compare_pixels(&a, &b, 1.0);
        assert!((m.rms - 0.5).abs() < 1e-15);
        assert!((m.rel_mse - 0.25 / 1.01).abs() < 1e-15);
        assert!((m.energy_ratio - 1.5).abs() < 1e-6);
        assert_eq!(m.energy_ratio_rgb, [1.5; 3]);
        // Both clamp to 1 on display.
        assert_eq!(m.rms_display, 0.0);
    }

    #[test]
    fn metrics_by_hand() {
        // Two pixels; errors 0.1 (red of pixel 0) and −0.2 (blue of pixel 1).
        let r = vec![[0.5, 0.25, 0.125], [0.25, 0.5, 0.5]];
        let a = vec![[0.625, 0.25, 0.125], [0.25, 0.5, 0.25]];
        let m = compare_pixels(&a, &r, 1.0);
        let se = 0.125f64 * 0.125 + 0.25 * 0.25;
        assert!((m.rms - (se / 6.0).sqrt()).abs() < 1e-15);
        let rel = 0.125f64.powi(2) / (0.25 + 0.01) + 0.25f64.powi(2) / (0.25 + 0.01);
        assert!((m.rel_mse - rel / 6.0).abs() < 1e-15);
        let y = |p: [f64; 3]| 0.2126729 * p[0] + 0.7151522 * p[1] + 0.0721750 * p[2];
        let e = (y(a[0]) + y(a[1])) / (y(r[0]) + y(r[1]));
        assert!((m.energy_ratio - e).abs() < 1e-12);
        assert_eq!(m.energy_ratio_rgb, [0.875 / 0.75, 1.0, 0.375 / 0.625]);
        let d = |v: f64| display(v, 1.0);
        let sed = (d(0.625) - d(0.5)).powi(2) + (d(0.25) - d(0.5)).powi(2);
        assert!((m.rms_display - (sed / 6.0).sqrt()).abs() < 1e-15);
        // sRGB curve: linear segment and the power segment.
        assert!((srgb_encode(0.001) - 0.01292).abs() < 1e-15);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-15);
    }
}
