//! An image sequence: N renders of one view, each at 1 spp with its own
//! seed, become a pass-major dump of N spp — what any renderer can give
//! without a patch (pbrt-v4 `--spp 1 --seed k`, Cycles with a seed per
//! render). Each pixel of image k is one sample of pass k.
//!
//! The images do not say where in its pixel each sample was taken, so every
//! record sits at its pixel's centre: in the joint space the samples of one
//! pixel are at image distance 0 from each other and whole pixels from their
//! neighbours' (docs/renderers.md says what that means for the filter).

use std::path::{Path, PathBuf};

use pathdensity_format::dump::Order;
use pathdensity_format::{Error, exr};

use crate::{Imported, Sink, at_centre, check_out, header};

/// Writes `out` from `inputs`, in the order given (it is the replay order).
pub fn import(inputs: &[PathBuf], out: &Path) -> Result<Imported, Error> {
    let Some(first) = inputs.first() else {
        return Err(Error::format(out, "no images to import"));
    };
    check_out(out, inputs)?;
    let spp = u32::try_from(inputs.len())
        .map_err(|_| Error::format(out, format!("{} images are too many", inputs.len())))?;
    let mut sink: Option<Sink> = None;
    let mut size = (0, 0);
    for path in inputs {
        let (w, h, pixels) = exr::read_rgb(path, exr::MAX_PIXELS)?;
        let (w32, h32) = match (u32::try_from(w), u32::try_from(h)) {
            (Ok(a), Ok(b)) => (a, b),
            _ => {
                return Err(Error::format(
                    path,
                    format!("{w} × {h} pixels is too large"),
                ));
            }
        };
        let sink = match &mut sink {
            Some(s) => {
                if (w, h) != size {
                    return Err(Error::format(
                        path,
                        format!(
                            "{w} × {h} pixels, but {} is {} × {}: every image must have the same size",
                            first.display(),
                            size.0,
                            size.1
                        ),
                    ));
                }
                s
            }
            None => {
                size = (w, h);
                let hdr = header(
                    w32,
                    h32,
                    1,
                    spp,
                    Order::PassMajor,
                    first,
                    "pathdensity import images",
                );
                sink.insert(Sink::create(out, hdr)?)
            }
        };
        let records: Vec<_> = pixels
            .iter()
            .enumerate()
            .map(|(i, p)| at_centre((i % w) as u32, (i / w) as u32, p.map(|v| v as f32)))
            .collect();
        sink.push_all(&records)?;
    }
    sink.expect("at least one image").finish()
}
