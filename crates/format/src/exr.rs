//! EXR images: written as 32-bit float RGB, clamped to the finite range,
//! under a temporary name and renamed when complete, with a
//! [`WRITER_ATTRIBUTE`] in the header that says pathdensity wrote them.

use std::io::Seek;
use std::path::Path;

use exr::prelude::*;

use crate::Error;
use crate::atomic::AtomicFile;
use crate::image::{Image, stored as finite_f32};

type Result<T> = std::result::Result<T, Error>;

/// Writes frame `frame` of `img` to `path`.
pub fn write_frame(path: &Path, img: &Image, frame: usize) -> Result<()> {
    let px = img.frame(frame);
    let w = img.width;
    let f = AtomicFile::create(path)?;
    // Compressed on one thread: exr's parallel writer files the chunks in
    // the order they finish, so the same image could give other bytes.
    let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
        let p = px[y * w + x];
        (finite_f32(p[0]), finite_f32(p[1]), finite_f32(p[2]))
    });
    let mut image = exr::prelude::Image::from_channels((img.width, img.height), channels);
    image.layer_data.attributes.other.insert(
        Text::from(WRITER_ATTRIBUTE),
        AttributeValue::Text(Text::from(WRITER_VALUE)),
    );
    image
        .write()
        .non_parallel()
        .to_file(f.tmp_path())
        .map_err(|e| Error::format(path, format!("cannot write EXR: {e}")))?;
    f.commit()
}

/// The header attribute (a string) every EXR pathdensity writes carries,
/// Rust or Python (`tools/exrio.py`): an existing EXR is replaced only if
/// it has it ([`written_by_us`]), so a user's own image at an output's
/// name is never overwritten.
pub const WRITER_ATTRIBUTE: &str = "pathdensity";
const WRITER_VALUE: &str = "written by pathdensity";

/// Whether `head`, the start of a file, is an EXR whose header (within
/// `head`) holds [`WRITER_ATTRIBUTE`]. The header is a run of attributes,
/// each name NUL, type NUL, a little-endian byte count and the value,
/// ended by an empty name (the OpenEXR file layout); a truncated or
/// malformed one is not ours.
pub fn written_by_us(head: &[u8]) -> bool {
    if !crate::guard::looks_like_exr(head) || head.len() < 8 {
        return false;
    }
    let mut rest = &head[8..];
    // The NUL-terminated field at the start of `rest`, which moves past it.
    fn field<'a>(rest: &mut &'a [u8]) -> Option<&'a [u8]> {
        let end = rest.iter().position(|&b| b == 0)?;
        let f = &rest[..end];
        *rest = &rest[end + 1..];
        Some(f)
    }
    loop {
        let Some(name) = field(&mut rest) else {
            return false;
        };
        if name.is_empty() {
            return false;
        }
        let Some(kind) = field(&mut rest) else {
            return false;
        };
        let Some(size) = rest.get(..4) else {
            return false;
        };
        let size = u32::from_le_bytes(size.try_into().unwrap()) as usize;
        if name == WRITER_ATTRIBUTE.as_bytes() && kind == b"string" {
            return true;
        }
        let Some(next) = rest.get(4 + size..) else {
            return false;
        };
        rest = next;
    }
}

/// Writes `NAME.exr` for a still, `NAME_0000.exr`, … for an animation.
pub fn write_image(dir: &Path, name: &str, img: &Image) -> Result<Vec<String>> {
    let mut names = Vec::new();
    for f in 0..img.frames {
        let file = frame_file_name(name, f, img.frames, "exr");
        write_frame(&dir.join(&file), img, f)?;
        names.push(file);
    }
    Ok(names)
}

/// `NAME.EXT` for a still, `NAME_0007.EXT` for frame 7 of an animation.
pub fn frame_file_name(name: &str, frame: usize, frames: usize, ext: &str) -> String {
    if frames > 1 {
        format!("{name}_{frame:04}.{ext}")
    } else {
        format!("{name}.{ext}")
    }
}

/// The most pixels an EXR may have where nothing else bounds it (`import
/// images`): 8192 × 8192, about 1.6 GB while read.
pub const MAX_PIXELS: usize = 1 << 26;

/// Reads the RGB channels of an EXR (alpha, if any, is ignored), refusing
/// it before any pixel is allocated when it claims more than `max_pixels`
/// pixels: the size is read from its header first.
pub fn read_rgb(path: &Path, max_pixels: usize) -> Result<(usize, usize, Vec<[f64; 3]>)> {
    let mut file = std::io::BufReader::new(crate::guard::open_input(path)?);
    let cannot = |e: exr::error::Error| Error::format(path, format!("cannot read EXR: {e}"));
    let meta = exr::meta::MetaData::read_from_buffered(&mut file, false).map_err(cannot)?;
    for h in &meta.headers {
        let (w, h) = (h.layer_size.width(), h.layer_size.height());
        if w.checked_mul(h).is_none_or(|n| n > max_pixels) {
            return Err(Error::format(
                path,
                format!("claims {w} × {h} pixels, more than the {max_pixels} expected"),
            ));
        }
    }
    file.seek(std::io::SeekFrom::Start(0))
        .map_err(|e| Error::io(path, e))?;
    let img = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |res, _| (res.width(), vec![[0.0f64; 3]; res.width() * res.height()]),
            |(w, px): &mut (usize, Vec<[f64; 3]>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                px[pos.y() * *w + pos.x()] = [r as f64, g as f64, b as f64];
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(file)
        .map_err(cannot)?;
    let size = img.layer_data.size;
    Ok((
        size.width(),
        size.height(),
        img.layer_data.channel_data.pixels.1,
    ))
}

/// The files of a reference for an image of `frames` frames: `REF.exr`
/// for a still, `REF_0000.exr`, … beside it for an animation.
pub fn reference_files(path: &Path, frames: usize) -> Vec<std::path::PathBuf> {
    if frames <= 1 {
        return vec![path.to_path_buf()];
    }
    let name = path
        .with_extension("")
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    (0..frames)
        .map(|f| path.with_file_name(frame_file_name(&name, f, frames, "exr")))
        .collect()
}

/// Reads a reference for an image of `frames` frames ([`reference_files`]).
pub fn read_reference(path: &Path, width: usize, height: usize, frames: usize) -> Result<Image> {
    let mut img = Image::new(width, height, frames);
    for (f, p) in reference_files(path, frames).iter().enumerate() {
        let (w, h, px) = read_rgb(p, width * height)?;
        if (w, h) != (width, height) {
            return Err(Error::format(
                p,
                format!("reference is {w} × {h}, the dump's film is {width} × {height}"),
            ));
        }
        if px.iter().flatten().any(|v| !v.is_finite()) {
            return Err(Error::format(p, "reference holds non-finite values"));
        }
        img.data[f * width * height..(f + 1) * width * height].copy_from_slice(&px);
    }
    Ok(img)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn our_exrs_are_marked_and_others_are_not() {
        let dir = tempfile::tempdir().unwrap();
        let ours = dir.path().join("ours.exr");
        write_frame(&ours, &Image::new(3, 2, 1), 0).unwrap();
        let head = std::fs::read(&ours).unwrap();
        assert!(written_by_us(&head));
        // The same image from exr itself, with no marker.
        let theirs = dir.path().join("theirs.exr");
        let channels = SpecificChannels::rgb(|_: Vec2<usize>| (0.5f32, 0.5f32, 0.5f32));
        exr::prelude::Image::from_channels((3, 2), channels)
            .write()
            .to_file(&theirs)
            .unwrap();
        let head = std::fs::read(&theirs).unwrap();
        assert!(crate::guard::looks_like_exr(&head) && !written_by_us(&head));
        // Truncated anywhere, ours is not recognised past the cut, and
        // nothing panics.
        let head = std::fs::read(&ours).unwrap();
        for n in 0..head.len().min(400) {
            let _ = written_by_us(&head[..n]);
        }
        assert!(!written_by_us(b"not an exr at all"));
    }

    /// The same image gives the same bytes, however many times it is
    /// written (exr's parallel writer filed chunks in finishing order).
    #[test]
    fn writing_is_deterministic() {
        let dir = tempfile::tempdir().unwrap();
        let mut img = Image::new(256, 192, 1);
        let mut s = 12345u64;
        for p in img.data.iter_mut() {
            for c in p.iter_mut() {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                *c = (s >> 11) as f64 / (1u64 << 53) as f64 * 100.0;
            }
        }
        let first = dir.path().join("a.exr");
        write_frame(&first, &img, 0).unwrap();
        let want = std::fs::read(&first).unwrap();
        for i in 0..8 {
            let p = dir.path().join(format!("b{i}.exr"));
            write_frame(&p, &img, 0).unwrap();
            assert!(std::fs::read(&p).unwrap() == want, "write {i} differs");
        }
        let (w, h, px) = read_rgb(&first, MAX_PIXELS).unwrap();
        assert_eq!((w, h), (256, 192));
        assert_eq!(px[1000][1], img.data[1000][1] as f32 as f64);
    }
}
