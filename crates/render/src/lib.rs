//! The renderer stage of pathdensity: a small path tracer whose scenes make
//! real fireflies, writing raw samples into `.pds` dumps.
//!
//! It shares with the `pathdensity` library only what must be identical on
//! both sides: the dump writer, and the reconstruction film used for
//! references (so a reference and the filter's images use the same W). The
//! filter never depends on this crate.
//!
//! Modules, from the bottom up: [`vec3`], [`sampler`], [`geometry`],
//! [`material`], [`camera`], [`scene`], [`integrator`], [`scenes`],
//! [`render`].

pub mod camera;
pub mod geometry;
pub mod integrator;
pub mod material;
pub mod render;
pub mod sampler;
pub mod scene;
pub mod scenes;
pub mod vec3;

pub use render::{AUX_SPP, RenderSettings, render_aux, render_dump, render_reference};
pub use scenes::SceneName;
