//! Error metrics against a reference image (docs/filter.md §4).

pub mod flip;

use crate::image::{Image, stored};
use crate::joint::lab::luminance;

/// All metrics of one image against a reference, over a set of pixels.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
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
    /// Mean ꟻLIP of the display values ([`flip::ldr`]; lower is better),
    /// the mean over frames for an animation.
    #[serde(default)]
    pub flip: f64,
    /// Mean HDR-ꟻLIP of the linear values ([`flip::hdr`]).
    #[serde(default)]
    pub hdr_flip: f64,
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

/// Metrics of pixels `img` against `reference` (same length; docs/filter.md
/// F9). The image is
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
        flip: 0.0,
        hdr_flip: 0.0,
    }
}

/// Mean ꟻLIP and HDR-ꟻLIP of one frame of each of `images` against
/// `reference`'s: on the display values (clamp(exposure · v, 0, 1), what a
/// viewer shows and the sRGB encoding ꟻLIP undoes) and on the linear
/// values. The images as written (f32), like every metric; the reference
/// is seen once for all of them.
pub fn flip_means(
    images: &[&Image],
    reference: &Image,
    frame: usize,
    exposure: f64,
) -> Vec<(f64, f64)> {
    let (w, h) = (reference.width, reference.height);
    let r = reference_pixels(reference, frame);
    let linear: Vec<Vec<[f32; 3]>> = images.iter().map(|i| written(i.frame(frame))).collect();
    let ldr = ldr_maps_of(&linear, &r, w, h, exposure);
    let hdr = flip::hdr_many(&r, &slices(&linear), w, h, flip::PPD);
    ldr.iter()
        .zip(&hdr)
        .map(|(l, h)| (flip::mean(l), flip::mean(h)))
        .collect()
}

/// Per pixel of `frame`, the LDR-ꟻLIP error of each of `images` against
/// `reference` (the maps whose means [`flip_means`] reports), in [0, 1].
pub fn ldr_flip_maps(
    images: &[&Image],
    reference: &Image,
    frame: usize,
    exposure: f64,
) -> Vec<Vec<f32>> {
    let linear: Vec<Vec<[f32; 3]>> = images.iter().map(|i| written(i.frame(frame))).collect();
    let r = reference_pixels(reference, frame);
    ldr_maps_of(&linear, &r, reference.width, reference.height, exposure)
}

/// The pixels as the EXR stores them.
fn written(px: &[[f64; 3]]) -> Vec<[f32; 3]> {
    px.iter().map(|p| p.map(stored)).collect()
}

fn reference_pixels(reference: &Image, frame: usize) -> Vec<[f32; 3]> {
    reference
        .frame(frame)
        .iter()
        .map(|p| p.map(|v| v as f32))
        .collect()
}

fn ldr_maps_of(
    linear: &[Vec<[f32; 3]>],
    reference: &[[f32; 3]],
    w: usize,
    h: usize,
    exposure: f64,
) -> Vec<Vec<f32>> {
    let shown = |px: &[[f32; 3]]| -> Vec<[f32; 3]> {
        px.iter()
            .map(|p| p.map(|v| (v as f64 * exposure).clamp(0.0, 1.0) as f32))
            .collect()
    };
    let displayed: Vec<Vec<[f32; 3]>> = linear.iter().map(|i| shown(i)).collect();
    flip::ldr_many(&shown(reference), &slices(&displayed), w, h, flip::PPD)
}

fn slices(v: &[Vec<[f32; 3]>]) -> Vec<&[[f32; 3]]> {
    v.iter().map(Vec::as_slice).collect()
}

/// One image's [`flip_means`].
pub fn flip_pair(img: &Image, reference: &Image, frame: usize, exposure: f64) -> (f64, f64) {
    flip_means(&[img], reference, frame, exposure)[0]
}

/// Pooled metrics over all frames, and per frame; for an animation, its
/// flicker against the reference's.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ImageMetrics {
    #[serde(flatten)]
    pub pooled: Metrics,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub per_frame: Vec<Metrics>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temporal: Option<Temporal>,
}

/// Temporal stability of an animation (docs/filter.md §4, F9t): the RMS of
/// the image's frame-to-frame differences against the reference's,
/// √(mean over f ≥ 1, pixels, channels of ((I_f − I_{f−1}) − (R_f − R_{f−1}))²).
/// A method that is right on average but flickers scores high here.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Temporal {
    /// On linear values.
    pub rms: f64,
    /// On display values (exposed, clamped, sRGB-encoded), what a viewer
    /// sees flicker on.
    pub rms_display: f64,
}

/// [`Temporal`] of `img` against `reference`; `None` for a still.
pub fn temporal(img: &Image, reference: &Image, exposure: f64) -> Option<Temporal> {
    if img.frames < 2 {
        return None;
    }
    let (mut se, mut sed, mut n) = (0.0f64, 0.0f64, 0usize);
    for f in 1..img.frames {
        let pixels = img
            .frame(f - 1)
            .iter()
            .zip(img.frame(f))
            .zip(reference.frame(f - 1).iter().zip(reference.frame(f)));
        for ((a0, a1), (r0, r1)) in pixels {
            for c in 0..3 {
                let (a0, a1) = (stored(a0[c]) as f64, stored(a1[c]) as f64);
                let d = (a1 - a0) - (r1[c] - r0[c]);
                se += d * d;
                let dd = (display(a1, exposure) - display(a0, exposure))
                    - (display(r1[c], exposure) - display(r0[c], exposure));
                sed += dd * dd;
                n += 1;
            }
        }
    }
    let n = n.max(1) as f64;
    Some(Temporal {
        rms: (se / n).sqrt(),
        rms_display: (sed / n).sqrt(),
    })
}

pub fn compare(img: &Image, reference: &Image, exposure: f64) -> ImageMetrics {
    compare_all(&[img], reference, exposure).remove(0)
}

/// [`compare`] of each of `images`, the reference seen by ꟻLIP once.
pub fn compare_all(images: &[&Image], reference: &Image, exposure: f64) -> Vec<ImageMetrics> {
    // flips[frame][image]
    let flips: Vec<Vec<(f64, f64)>> = (0..reference.frames)
        .map(|f| flip_means(images, reference, f, exposure))
        .collect();
    let frames = flips.len().max(1) as f64;
    images
        .iter()
        .enumerate()
        .map(|(i, img)| {
            let mut pooled = compare_pixels(&img.data, &reference.data, exposure);
            pooled.flip = flips.iter().map(|f| f[i].0).sum::<f64>() / frames;
            pooled.hdr_flip = flips.iter().map(|f| f[i].1).sum::<f64>() / frames;
            let per_frame = if img.frames > 1 {
                (0..img.frames)
                    .map(|f| Metrics {
                        flip: flips[f][i].0,
                        hdr_flip: flips[f][i].1,
                        ..compare_pixels(img.frame(f), reference.frame(f), exposure)
                    })
                    .collect()
            } else {
                Vec::new()
            };
            ImageMetrics {
                pooled,
                per_frame,
                temporal: temporal(img, reference, exposure),
            }
        })
        .collect()
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

    #[test]
    fn temporal_is_zero_for_steady_offsets_and_sees_flicker() {
        // Two pixels, three frames. The reference brightens by 0.25 a frame.
        let mut r = Image::new(2, 1, 3);
        for f in 0..3 {
            for p in 0..2 {
                r.data[f * 2 + p] = [0.25 * f as f64; 3];
            }
        }
        // A constant bias does not flicker.
        let mut biased = r.clone();
        biased
            .data
            .iter_mut()
            .for_each(|p| *p = p.map(|v| v + 0.125));
        assert_eq!(temporal(&biased, &r, 1.0).unwrap().rms, 0.0);
        // One pixel that jumps by 0.5 in frame 1 and back in frame 2:
        // differences off by +0.5 then −0.5 on 3 of 12 channel steps each.
        let mut flicker = r.clone();
        flicker.data[2] = flicker.data[2].map(|v| v + 0.5);
        let t = temporal(&flicker, &r, 1.0).unwrap();
        assert!((t.rms - (2.0 * 3.0 * 0.25f64 / 12.0).sqrt()).abs() < 1e-15);
        assert!(t.rms_display > 0.0);
        assert!(temporal(&Image::new(2, 1, 1), &Image::new(2, 1, 1), 1.0).is_none());
    }
}
