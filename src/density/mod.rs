//! The path-density filter (SPEC §3): a streaming replay that accepts a
//! sample when the mean distance to its k nearest stored samples is below 1,
//! and stores it otherwise, followed by a final pass over the stored set.

pub mod filter;
pub mod index;
pub mod sigma;

pub use filter::{Decision, FilterCounts, FilterResult, ReplayOptions, run};
pub use index::IndexKind;
