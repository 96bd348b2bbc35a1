//! pathdensity: density-based outlier rejection for Monte Carlo sample dumps
//! (DeCoro, Weyrich & Rusinkiewicz, Pacific Graphics 2010).
//!
//! This crate is the top of the workspace: the jobs the command line runs
//! ([`commands`]), the comparisons that read and write files ([`sweep`],
//! [`regress`]) and what they write beside the images ([`report`]: the
//! summary, `report.json`, `report.html`, plots, PNG previews). The
//! pipeline itself is `pathdensity-core`, the file format
//! `pathdensity-format`; both are re-exported here under their usual names.

pub use pathdensity_core::{
    config, density, imagespace, joint, method, metrics, par, pipeline, progress, quantile, recon,
    synth,
};
pub use pathdensity_format::{dump, image};

/// Files in and out: atomic writes and EXR (`pathdensity-format`), PNG
/// previews.
pub mod io {
    pub use pathdensity_format::{atomic, exr, guard};
    pub mod png;
}

pub mod cli;
pub mod commands;
pub mod regress;
pub mod report;
pub mod sweep;
