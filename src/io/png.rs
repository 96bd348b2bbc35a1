//! PNG previews: linear radiance × exposure, clamped to [0, 1], encoded
//! with the sRGB transfer curve — the same display transform as docs/filter.md §4's
//! RMS_display, so a preview shows what that metric measures.

use std::path::Path;

use anyhow::{Context, Result};

use crate::metrics::display;
use crate::recon::Image;

/// Frame `frame` of `img` as 8-bit sRGB.
pub fn tone_map(img: &Image, frame: usize, exposure: f64) -> image::RgbImage {
    let px = img.frame(frame);
    image::RgbImage::from_fn(img.width as u32, img.height as u32, |x, y| {
        let p = px[y as usize * img.width + x as usize];
        image::Rgb(p.map(|c| (display(c, exposure) * 255.0).round() as u8))
    })
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
