//! PNG previews: linear radiance × exposure, clamped to [0, 1], encoded
//! with the sRGB transfer curve — the same display transform as SPEC §5's
//! RMS_display, so a preview shows what that metric measures.

use std::path::Path;

use anyhow::{Context, Result};

use super::atomic::AtomicFile;
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

/// Writes an 8-bit image as PNG, atomically.
pub fn write_png(path: &Path, img: &image::RgbImage) -> Result<()> {
    let f = AtomicFile::new(path);
    img.save_with_format(f.tmp_path(), image::ImageFormat::Png)
        .with_context(|| format!("{}: cannot write PNG", path.display()))?;
    f.commit()
        .with_context(|| format!("{}: cannot rename into place", path.display()))
}

/// Writes the tone-mapped preview of one frame.
pub fn write_preview(path: &Path, img: &Image, frame: usize, exposure: f64) -> Result<()> {
    write_png(path, &tone_map(img, frame, exposure))
}

/// Writes `NAME.png` (a still) or `NAME_0000.png`, … (an animation) into
/// `dir`, returning the file names.
pub fn write_previews(dir: &Path, name: &str, img: &Image, exposure: f64) -> Result<Vec<String>> {
    (0..img.frames)
        .map(|f| {
            let file = super::exr::frame_file_name(name, f, img.frames, "png");
            write_preview(&dir.join(&file), img, f, exposure)?;
            Ok(file)
        })
        .collect()
}
