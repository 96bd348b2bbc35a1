//! Colour coordinates for HDR samples (docs/filter.md §1, F2a and F2b).
//!
//! CIELAB's f(u) = ∛u was fitted to reflective colours up to the white. The
//! samples of one consistent highlight spread over decades of radiance
//! above it, where ∛ still grows fast: two samples at 690 and 1234 × white
//! differ by ΔL* ≈ 100, a full σ_color, and look like outliers to each
//! other. Both spaces here equal CIELAB up to the white and grow like a
//! logarithm above it, so a factor of e in radiance costs a fixed 116/3 in
//! lightness however bright the sample is.

use super::lab::{WHITE_D65, f, rgb_to_xyz};

/// F2a's f: CIELAB's up to u = 1, then 1 + ln(u)/3, which meets ∛u at 1
/// with the same slope (C¹).
#[inline]
pub fn f_log(u: f64) -> f64 {
    if u > 1.0 { 1.0 + u.ln() / 3.0 } else { f(u) }
}

/// F2a, `loglab`: CIELAB with [`f_log`] for f. Above the white a* and b*
/// depend only on the ratios of X, Y and Z, not on the radiance.
///
/// ```
/// use pathdensity_core::joint::{hdr::rgb_to_loglab, lab::rgb_to_lab};
/// let c = [0.3, 0.5, 0.2];
/// assert_eq!(rgb_to_loglab(c, 1.0), rgb_to_lab(c, 1.0)); // below the white
/// let (a, b) = (rgb_to_loglab([690.0; 3], 1.0), rgb_to_loglab([1234.0; 3], 1.0));
/// assert!((b[0] - a[0] - 116.0 / 3.0 * (1234.0f64 / 690.0).ln()).abs() < 1e-6);
/// ```
#[inline]
pub fn rgb_to_loglab(rgb: [f64; 3], white: f64) -> [f64; 3] {
    let [x, y, z] = rgb_to_xyz(rgb[0], rgb[1], rgb[2]);
    let fx = f_log(x / (white * WHITE_D65[0]));
    let fy = f_log(y / (white * WHITE_D65[1]));
    let fz = f_log(z / (white * WHITE_D65[2]));
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// u′, v′ of RGB (1, 1, 1) through F2's matrix (D65), so greys have no chroma.
const WHITE_UV: [f64; 2] = [0.19783980937881362, 0.4683363132095571];

/// F2b, `logluv`: lightness as in F2a; chroma as CIELUV's
/// u* = 13 L (u′ − u′ₙ), v* = 13 L (v′ − v′ₙ), with L the lightness capped
/// at 100, so above the white a colour's chroma stops growing while its
/// lightness goes on logarithmically. A sample with X + 15Y + 3Z ≤ 0 (black,
/// or negative) has the white's chromaticity.
///
/// ```
/// use pathdensity_core::joint::hdr::rgb_to_logluv;
/// let grey = rgb_to_logluv([0.2; 3], 1.0);
/// assert!(grey[1].abs() < 1e-4 && grey[2].abs() < 1e-4);
/// let (a, b) = (rgb_to_logluv([5.0, 1.0, 1.0], 1.0), rgb_to_logluv([500.0, 100.0, 100.0], 1.0));
/// assert!((a[1] - b[1]).abs() < 1e-9 && b[0] > a[0]);
/// ```
#[inline]
pub fn rgb_to_logluv(rgb: [f64; 3], white: f64) -> [f64; 3] {
    let [x, y, z] = rgb_to_xyz(rgb[0], rgb[1], rgb[2]);
    let l = 116.0 * f_log(y / (white * WHITE_D65[1])) - 16.0;
    let d = x + 15.0 * y + 3.0 * z;
    let (u, v) = if d > 0.0 {
        (4.0 * x / d, 9.0 * y / d)
    } else {
        (WHITE_UV[0], WHITE_UV[1])
    };
    let c = 13.0 * l.min(100.0);
    [l, c * (u - WHITE_UV[0]), c * (v - WHITE_UV[1])]
}
