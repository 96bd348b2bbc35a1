//! pathdensity-core: density-based outlier rejection for Monte Carlo
//! sample dumps (DeCoro, Weyrich & Rusinkiewicz, Pacific Graphics 2010).
//!
//! The modules follow the pipeline: [`dump`] (the format, re-exported from
//! `pathdensity-format`) → [`joint`] (the joint image–colour–time space) →
//! [`density`] (the filter) → [`recon`] and [`imagespace`] (images) →
//! [`metrics`]. [`config`] is the one configuration of a run and
//! [`pipeline`] runs it with no file I/O. No files, command line, plots or
//! HTML here: sweeps, fixtures and reports are the top package's.

pub use pathdensity_format::{dump, image};

pub mod config;
pub mod density;
pub mod imagespace;
pub mod joint;
pub mod method;
pub mod metrics;
mod names;
pub mod par;
pub mod pipeline;
pub mod progress;
pub mod quantile;
pub mod recon;

pub mod synth;
