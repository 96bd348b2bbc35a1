//! pathdensity: density-based outlier rejection for Monte Carlo sample dumps
//! (DeCoro, Weyrich & Rusinkiewicz, Pacific Graphics 2010).
//!
//! The modules follow the pipeline: [`dump`] (the `.pds` format) →
//! [`joint`] (the joint image–colour–time space) → [`density`] (the
//! filter) → [`recon`] (images) → [`metrics`] → [`report`].

pub mod commands;
pub mod config;
pub mod density;
pub mod dump;
pub mod imagespace;
pub mod io;
pub mod joint;
pub mod metrics;
pub mod pipeline;
pub mod progress;
pub mod quantile;
pub mod recon;
pub mod regress;
pub mod report;
pub mod sweep;
pub mod synth;
