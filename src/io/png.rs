//! PNG previews: linear radiance × exposure, clamped to [0, 1], encoded
//! with the sRGB transfer curve — the same display transform as docs/filter.md §4's
//! RMS_display, so a preview shows what that metric measures.

use std::path::Path;
use std::sync::OnceLock;

use anyhow::{Context, Result};

use crate::metrics::display;
use crate::recon::Image;

/// Frame `frame` of `img` as 8-bit sRGB.
pub fn tone_map(img: &Image, frame: usize, exposure: f64) -> image::RgbImage {
    let px = img.frame(frame);
    image::RgbImage::from_fn(img.width as u32, img.height as u32, |x, y| {
        let p = px[y as usize * img.width + x as usize];
        image::Rgb(p.map(|c| level((c * exposure).clamp(0.0, 1.0))))
    })
}

/// The 8-bit level of an exposed, clamped value `u` (`display`'s), without
/// its power: the number of levels whose first value is at or below `u`.
/// The same level as `display` gives, since the curve only rises.
fn level(u: f64) -> u8 {
    level_starts().partition_point(|&s| s <= u) as u8
}

/// The least value of each level 1..=255, found once.
fn level_starts() -> &'static [f64; 255] {
    static STARTS: OnceLock<[f64; 255]> = OnceLock::new();
    STARTS.get_or_init(|| {
        std::array::from_fn(|k| {
            // By bisection on the bits, which are ordered as the values for
            // u ≥ 0: level 0 at u = 0, 255 at u = 1.
            let (mut below, mut at) = (0u64, 1f64.to_bits());
            while at - below > 1 {
                let mid = below + (at - below) / 2;
                if curve_level(f64::from_bits(mid)) > k as u8 {
                    at = mid;
                } else {
                    below = mid;
                }
            }
            f64::from_bits(at)
        })
    })
}

/// `display`'s 8-bit level of `u` ∈ [0, 1].
fn curve_level(u: f64) -> u8 {
    (display(u, 1.0) * 255.0).round() as u8
}

/// An 8-bit image encoded as PNG.
pub fn encode(img: &image::RgbImage) -> Result<Vec<u8>> {
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png)
        .context("cannot encode PNG")?;
    Ok(out.into_inner())
}

/// Writes an 8-bit image as PNG, atomically.
pub fn write_png(path: &Path, img: &image::RgbImage) -> Result<()> {
    let bytes = encode(img).with_context(|| path.display().to_string())?;
    Ok(super::atomic::write_bytes(path, &bytes)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The level from the table is the curve's, around every level's first
    /// value and over a sweep of exposed values (with NaN, ±∞ and
    /// negatives), at several exposures.
    #[test]
    fn levels_from_the_table_are_the_curves() {
        let direct = |c: f64, e: f64| (display(c, e) * 255.0).round() as u8;
        for &start in level_starts() {
            let bits = start.to_bits();
            for u in (bits.saturating_sub(2000)..=bits + 2000).map(f64::from_bits) {
                let u = u.min(1.0);
                assert_eq!(level(u), curve_level(u), "{u}");
            }
        }
        let mut values: Vec<f64> = (0..200_000).map(|i| i as f64 / 150_000.0 - 0.1).collect();
        values.extend([
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            -0.0,
            1e-300,
            0.0031308,
        ]);
        for e in [1.0, 0.37, 4.0] {
            for &c in &values {
                assert_eq!(
                    level((c * e).clamp(0.0, 1.0)),
                    direct(c, e),
                    "{c} at exposure {e}"
                );
            }
        }
    }
}
