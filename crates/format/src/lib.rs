//! pathdensity-format: the sample dump (`.pds`, docs/format.md), the image
//! type every stage shares and its EXR files, and atomic writes. What a
//! renderer needs to write dumps and references, and nothing of the filter.

pub mod atomic;
pub mod dump;
pub mod exr;
pub mod guard;
pub mod image;

/// Everything that can go wrong reading or writing this crate's files.
/// Every message names the file, so a program can print it as one line.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    // The io::Error is part of the message, not a `source`: a source would
    // make `{:#}` print it twice.
    #[error("{path}: {error}")]
    Io { path: String, error: std::io::Error },
    #[error("{path}: {problem}")]
    Format { path: String, problem: String },
}

impl Error {
    pub fn io(path: &std::path::Path, error: std::io::Error) -> Self {
        Error::Io {
            path: path.display().to_string(),
            error,
        }
    }
    pub fn format(path: &std::path::Path, problem: impl Into<String>) -> Self {
        Error::Format {
            path: path.display().to_string(),
            problem: problem.into(),
        }
    }
}
