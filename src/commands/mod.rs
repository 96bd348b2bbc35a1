//! The user-facing jobs, each a function the CLI calls with parsed options
//! and a [`crate::progress::Progress`] to report to.

pub mod batch;
pub mod filter;
pub mod info;
pub mod regress;
pub mod sweep;
