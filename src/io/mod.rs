//! Files in and out: atomic writes, EXR images, PNG previews.

pub mod atomic;
pub mod exr;
pub mod png;
