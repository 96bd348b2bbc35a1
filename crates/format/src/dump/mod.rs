//! The sample dump, format version 1 (`.pds`, docs/format.md).
//!
//! A dump is a small bincode header followed by a flat array of 24-byte
//! records. [`DumpReader`] maps the file and hands out the records as a
//! zero-copy slice; [`DumpWriter`] streams records into a temporary file and
//! renames it into place when complete.

mod header;
mod reader;
mod record;
#[cfg(unix)]
mod shrink;
mod writer;

pub use header::{HEADER_LEN_MAX, Header, MAGIC, Order, VERSION};
pub use reader::{DumpReader, parse_prefix};
pub use record::{InvalidCounts, Record, Validity};
pub use writer::{DumpWriter, PresizedDump};

/// Byte offset of the first record for a header of `header_len` bytes:
/// `16 + header_len` rounded up to a multiple of 64 (docs/format.md).
pub fn data_offset(header_len: usize) -> usize {
    (16 + header_len).div_ceil(64) * 64
}

/// Everything that can be wrong with a dump file (the crate's [`crate::Error`]).
pub use crate::Error as DumpError;
