//! Progress of long work, reported from the library to whoever shows it
//! (the binaries draw a bar on a terminal; tests and batch runs pass
//! [`Silent`]).

/// Receives the progress of one piece of work: its length once known, then
/// increments. Called from worker threads.
pub trait Progress: Sync {
    fn set_length(&self, _len: u64) {}
    fn inc(&self, _n: u64) {}
    /// A short status beside the bar (a batch's dumps done, skipped,
    /// failed).
    fn message(&self, _msg: &str) {}
    /// The work is done (a bar clears itself).
    fn finish(&self) {}
    /// A new piece of the same work begins, `len` steps long, named
    /// `what`: the increments that follow count its steps (a bar starts
    /// again at 0).
    fn stage(&self, _what: &str, _len: u64) {}
}

/// Reports nothing.
pub struct Silent;

impl Progress for Silent {}
