//! Linear Rec.709 RGB → CIELAB, exactly as docs/filter.md §1 fixes it (f64, products
//! added left to right, no fused multiply-add).

/// The D65 white point relative to Y = 1.
pub(crate) const WHITE_D65: [f64; 3] = [0.95047, 1.0, 1.08883];

/// CIE's δ = 6/29: the knee between the cube root and the linear branch.
const DELTA: f64 = 6.0 / 29.0;

/// Rec.709 / sRGB primaries, D65 white.
#[inline]
pub fn rgb_to_xyz(r: f64, g: f64, b: f64) -> [f64; 3] {
    [
        0.4124564 * r + 0.3575761 * g + 0.1804375 * b,
        0.2126729 * r + 0.7151522 * g + 0.0721750 * b,
        0.0193339 * r + 0.1191920 * g + 0.9503041 * b,
    ]
}

/// Luminance Y of linear RGB (the middle row of the matrix).
#[inline]
pub fn luminance(rgb: [f64; 3]) -> f64 {
    0.2126729 * rgb[0] + 0.7151522 * rgb[1] + 0.0721750 * rgb[2]
}

/// CIE's f(u): cube root above δ³, the linear segment below. The linear
/// branch also takes negative u, so the map is finite for every finite input.
#[inline]
pub(crate) fn f(u: f64) -> f64 {
    if u > DELTA * DELTA * DELTA {
        u.cbrt()
    } else {
        u / (3.0 * DELTA * DELTA) + 4.0 / 29.0
    }
}

/// CIELAB of linear RGB for a white of luminance `white` (docs/filter.md §1's Y_w).
///
/// ```
/// let lab = pathdensity_core::joint::lab::rgb_to_lab([1.0, 1.0, 1.0], 1.0);
/// assert!((lab[0] - 100.0).abs() < 1e-4 && lab[1].abs() < 1e-2 && lab[2].abs() < 1e-2);
/// ```
#[inline]
pub fn rgb_to_lab(rgb: [f64; 3], white: f64) -> [f64; 3] {
    let [x, y, z] = rgb_to_xyz(rgb[0], rgb[1], rgb[2]);
    let fx = f(x / (white * WHITE_D65[0]));
    let fy = f(y / (white * WHITE_D65[1]));
    let fz = f(z / (white * WHITE_D65[2]));
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}
