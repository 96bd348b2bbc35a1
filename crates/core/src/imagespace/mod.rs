//! Image-space filters applied to reconstructed images (docs/filter.md §3): the
//! bilateral filter, the 3 × 3 median and OIDN. They work frame by frame, and
//! pixels that contain no valid sample (`occupancy` 0) are neither used as
//! neighbours nor written: docs/filter.md §3 keeps them 0 in every image.

pub mod aux;
pub mod bilateral;
pub mod median3;
pub mod oidn;

pub use bilateral::bilateral;
pub use median3::median3;
