//! pathdensity-import: dumps (docs/format.md) from the per-sample data other
//! renderers can give without a patch. One module per source:
//!
//! - [`images`]: N renders of one view at 1 spp with different seeds;
//! - [`npy`]: a numpy array of records, shape (N, 6), float32;
//! - [`bcd`]: the raw sample file of Boughida & Boubekeur's BCD denoiser.
//!
//! Every importer streams: it holds one image or one buffer of records at a
//! time, and writes through [`DumpWriter`], so a failure leaves no dump.
//! Depends on the format only, like the renderers.

pub mod bcd;
pub mod images;
pub mod npy;

use std::path::Path;

use pathdensity_format::Error;
use pathdensity_format::dump::{DumpWriter, Header, InvalidCounts, Order, Record, Validity};
use pathdensity_format::guard::{self, Inputs};

/// What an import wrote: the dump's header and how many of its records the
/// filter will use. Invalid records are kept in the dump, as any renderer's
/// would be, and counted here by reason (as `pathdensity info` does).
#[derive(Clone, Debug)]
pub struct Imported {
    pub header: Header,
    pub valid: u64,
    pub invalid: InvalidCounts,
}

impl std::fmt::Display for Imported {
    /// One line: `N records (W × H, S spp, ORDER), M invalid: …`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let h = &self.header;
        write!(f, "{} records ({} × {}", h.sample_count, h.width, h.height)?;
        if h.frames > 1 {
            write!(f, " × {} frames", h.frames)?;
        }
        write!(f, ", {} spp, {})", h.spp, h.order)?;
        let i = &self.invalid;
        if i.total() == 0 {
            write!(f, ", all valid")
        } else {
            write!(
                f,
                ", {} invalid (non-finite {}, outside the film {}, outside the frames {}), \
                 kept in the dump and skipped by the filter",
                i.total(),
                i.non_finite,
                i.outside_film,
                i.outside_time
            )
        }
    }
}

/// A dump being written, counting validity as records go in.
struct Sink {
    writer: DumpWriter,
    header: Header,
    valid: u64,
    invalid: InvalidCounts,
}

/// Refuses `out` before any work when it is one of `inputs` or an existing
/// file that is not a dump.
fn check_out<P: AsRef<Path>>(out: &Path, inputs: &[P]) -> Result<(), Error> {
    Inputs::of(inputs).check_file(out, guard::looks_like_dump)
}

impl Sink {
    fn create(out: &Path, header: Header) -> Result<Sink, Error> {
        Ok(Sink {
            writer: DumpWriter::create(out, header.clone())?,
            header,
            valid: 0,
            invalid: InvalidCounts::default(),
        })
    }

    fn push_all(&mut self, records: &[Record]) -> Result<(), Error> {
        for r in records {
            match r.validity(&self.header) {
                Validity::Valid => self.valid += 1,
                v => self.invalid.add(v),
            }
        }
        self.writer.push_all(records)
    }

    fn finish(self) -> Result<Imported, Error> {
        Ok(Imported {
            header: self.writer.finish()?,
            valid: self.valid,
            invalid: self.invalid,
        })
    }
}

/// A header for an imported dump; `sample_count` is set when it is finished.
fn header(
    width: u32,
    height: u32,
    frames: u32,
    spp: u32,
    order: Order,
    source: &Path,
    producer: &str,
) -> Header {
    Header {
        width,
        height,
        frames,
        spp,
        sample_count: 0,
        order,
        scene: source
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        seed: 0,
        producer: producer.into(),
    }
}

/// The record of a sample whose film position is unknown: the centre of
/// pixel (`x`, `y`) of frame 0.
fn at_centre(x: u32, y: u32, rgb: [f32; 3]) -> Record {
    Record::new(x as f32 + 0.5, y as f32 + 0.5, 0.0, rgb)
}
