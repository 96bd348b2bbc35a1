//! The raw sample file of BCD (Boughida & Boubekeur, *Bayesian Collaborative
//! Denoising for Monte Carlo Rendering*, 2017), the input of its `raw2bcd`:
//! five little-endian i32 — a version, width, height, samples per pixel and
//! channels (3 or 4; a fourth is ignored) — then the samples' floats, pixel
//! by pixel, row 0 first, every sample of a pixel together. Positions are
//! not stored: records sit at pixel centres (see [`crate::images`]).

use std::io::{BufReader, Read};
use std::path::Path;

use pathdensity_format::dump::Order;
use pathdensity_format::{Error, guard};

use crate::{Imported, Sink, at_centre, check_out, header};

const HEADER_BYTES: u64 = 20;

/// Writes `out` from the samples of `input`.
pub fn import(input: &Path, out: &Path) -> Result<Imported, Error> {
    check_out(out, &[input])?;
    let file = guard::open_input(input)?;
    let size = file.metadata().map_err(|e| Error::io(input, e))?.len();
    let mut reader = BufReader::with_capacity(1 << 20, file);
    let mut fixed = [0u8; HEADER_BYTES as usize];
    reader.read_exact(&mut fixed).map_err(|_| {
        Error::format(
            input,
            format!("{size} bytes: too short for a BCD raw header ({HEADER_BYTES} bytes)"),
        )
    })?;
    let field = |i: usize| i32::from_le_bytes(fixed[4 * i..4 * i + 4].try_into().unwrap());
    let (width, height, spp, channels) = (field(1), field(2), field(3), field(4));
    if width < 1 || height < 1 || spp < 1 {
        return Err(Error::format(
            input,
            format!("not a BCD raw file: its header says {width} × {height} pixels at {spp} spp"),
        ));
    }
    if channels != 3 && channels != 4 {
        return Err(Error::format(
            input,
            format!("not a BCD raw file: its header says {channels} channels per sample (3 or 4)"),
        ));
    }
    let (w, h, n, c) = (width as u64, height as u64, spp as u64, channels as u64);
    let expected = [w, h, n, c, 4]
        .iter()
        .try_fold(1u64, |a, &b| a.checked_mul(b))
        .and_then(|b| b.checked_add(HEADER_BYTES))
        .ok_or_else(|| {
            Error::format(
                input,
                format!("not a BCD raw file: {width} × {height} × {spp} × {channels} overflows"),
            )
        })?;
    if size != expected {
        let what = if size < expected {
            "truncated"
        } else {
            "longer than its header says"
        };
        return Err(Error::format(
            input,
            format!(
                "{what}: {size} bytes, but {width} × {height} pixels × {spp} spp × {channels} channels need {expected}"
            ),
        ));
    }
    let hdr = header(
        width as u32,
        height as u32,
        1,
        spp as u32,
        Order::PixelMajor,
        input,
        "pathdensity import bcd",
    );
    let mut sink = Sink::create(out, hdr)?;
    let mut sample = vec![0u8; (c * 4) as usize * spp as usize];
    let mut records = Vec::with_capacity(spp as usize);
    for y in 0..height as u32 {
        for x in 0..width as u32 {
            reader
                .read_exact(&mut sample)
                .map_err(|e| Error::io(input, e))?;
            records.clear();
            records.extend(sample.chunks_exact((c * 4) as usize).map(|s| {
                let v = |k: usize| f32::from_le_bytes(s[4 * k..4 * k + 4].try_into().unwrap());
                at_centre(x, y, [v(0), v(1), v(2)])
            }));
            sink.push_all(&records)?;
        }
    }
    sink.finish()
}
