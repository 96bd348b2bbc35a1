//! pathdensity-format: the sample dump (`.pds`, docs/format.md), the image
//! type every stage shares and its EXR files, and atomic writes. What a
//! renderer needs to write dumps and references, and nothing of the filter.
//!
//! A renderer writes one record per camera sample (film position in
//! pixels, time in frames, linear RGB radiance), in the order it made
//! them; the filter replays them in that order:
//!
//! ```
//! use pathdensity_format::dump::{DumpReader, DumpWriter, Header, Order, Record};
//! # let dir = std::env::temp_dir().join(format!("pds-doc-{}", std::process::id()));
//! # std::fs::create_dir_all(&dir).unwrap();
//! let path = dir.join("scene.pds");
//! let (w, h, spp) = (4, 3, 2);
//! let mut header = Header::still(w, h, spp, Order::PixelMajor);
//! header.scene = "my scene".into();
//! // Written to a temporary name; `finish` counts the records, writes the
//! // header and renames the file into place, so a crash leaves no dump.
//! let mut dump = DumpWriter::create(&path, header)?;
//! for y in 0..h {
//!     for x in 0..w {
//!         for s in 0..spp {
//!             // Where the sample landed in the pixel, and its radiance.
//!             let (jx, jy) = (0.25 + 0.5 * s as f32, 0.5);
//!             let radiance = [0.5, 0.25, 0.125];
//!             dump.push(&Record::new(x as f32 + jx, y as f32 + jy, 0.0, radiance))?;
//!         }
//!     }
//! }
//! let header = dump.finish()?;
//! assert_eq!(header.sample_count, 24);
//!
//! // Reading maps the file: the records are a slice over it.
//! let dump = DumpReader::open(&path)?;
//! assert_eq!(dump.header().scene, "my scene");
//! assert_eq!(dump.records().len(), 24);
//! assert_eq!(dump.records()[1].x, 0.75);
//! # std::fs::remove_dir_all(&dir).unwrap();
//! # Ok::<(), pathdensity_format::Error>(())
//! ```

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
