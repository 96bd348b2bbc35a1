//! Error metrics against a reference image (SPEC §5).

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
    for (a, b) in img.iter().zip(reference) {
        let a = &a.map(|v| stored(v) as f64);
        for c in 0..3 {
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
        // Both clamp to 1 on display.
        assert_eq!(m.rms_display, 0.0);
    }
}
