//! Files in and out: atomic writes, EXR images.

pub mod atomic;
pub mod exr;
