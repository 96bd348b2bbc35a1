//! The image every stage shares: RGB per pixel and frame, in f64.

use crate::dump::Header;

/// A value as images store it: rounded to f32, clamped to the finite range.
#[inline]
pub fn stored(v: f64) -> f32 {
    (v as f32).clamp(-f32::MAX, f32::MAX)
}

/// An RGB image per frame, in f64: `data[(frame · height + row) · width + col]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub frames: usize,
    pub data: Vec<[f64; 3]>,
}

impl Image {
    pub fn new(width: usize, height: usize, frames: usize) -> Image {
        Image {
            width,
            height,
            frames,
            data: vec![[0.0; 3]; width * height * frames],
        }
    }

    pub fn for_header(h: &Header) -> Image {
        Image::new(h.width as usize, h.height as usize, h.frames as usize)
    }

    pub fn pixels_per_frame(&self) -> usize {
        self.width * self.height
    }

    /// A 64-bit digest (XXH3) of the size and the pixels' bits.
    pub fn content_hash(&self) -> u64 {
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        for n in [self.width, self.height, self.frames] {
            h.update(&(n as u64).to_le_bytes());
        }
        for p in &self.data {
            for c in p {
                h.update(&c.to_bits().to_le_bytes());
            }
        }
        h.digest()
    }

    /// The pixels of one frame.
    pub fn frame(&self, f: usize) -> &[[f64; 3]] {
        let n = self.pixels_per_frame();
        &self.data[f * n..(f + 1) * n]
    }
}
