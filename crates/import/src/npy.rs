//! A numpy `.npy` file of records: shape (N, 6), dtype float32
//! little-endian, C order, columns `x, y, t, r, g, b` exactly as a dump
//! stores them (docs/format.md). The film's size is not in the file, so the
//! caller gives it.

use std::io::{BufReader, Read};
use std::path::Path;

use pathdensity_format::dump::{Order, Record};
use pathdensity_format::{Error, guard};

use crate::{Imported, Sink, check_out, header};

/// What the array does not say about the film.
#[derive(Clone, Copy, Debug)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    /// Samples per pixel per frame, 0 when not uniform. When given,
    /// N must equal width × height × frames × spp.
    pub spp: u32,
    pub order: Order,
}

const MAGIC: &[u8; 6] = b"\x93NUMPY";
const CHUNK_RECORDS: usize = 1 << 16;

/// Writes `out` from the records of `input`.
pub fn import(input: &Path, film: Film, out: &Path) -> Result<Imported, Error> {
    check_out(out, &[input])?;
    let file = guard::open_input(input)?;
    let size = file.metadata().map_err(|e| Error::io(input, e))?.len();
    let mut reader = BufReader::with_capacity(1 << 20, file);
    let (rows, data_offset) = read_header(&mut reader, input)?;
    let expected = rows
        .checked_mul(24)
        .and_then(|b| b.checked_add(data_offset))
        .ok_or_else(|| Error::format(input, format!("{rows} rows overflow")))?;
    if size != expected {
        return Err(Error::format(
            input,
            format!("file is {size} bytes, but {rows} rows of 6 float32 need {expected}"),
        ));
    }
    let uniform = film.width as u64 * film.height as u64 * film.frames as u64 * film.spp as u64;
    if film.spp > 0 && rows != uniform {
        return Err(Error::format(
            input,
            format!(
                "{rows} rows, but {} × {} × {} frames × {} spp = {uniform} samples",
                film.width, film.height, film.frames, film.spp
            ),
        ));
    }
    let hdr = header(
        film.width,
        film.height,
        film.frames,
        film.spp,
        film.order,
        input,
        "pathdensity import npy",
    );
    let mut sink = Sink::create(out, hdr)?;
    let mut buf = vec![Record::default(); CHUNK_RECORDS];
    let mut left = rows;
    while left > 0 {
        let n = left.min(CHUNK_RECORDS as u64) as usize;
        // The file's bytes are the records' (little-endian, like the dump).
        let bytes: &mut [u8] = bytemuck::cast_slice_mut(&mut buf[..n]);
        reader.read_exact(bytes).map_err(|e| Error::io(input, e))?;
        sink.push_all(&buf[..n])?;
        left -= n as u64;
    }
    sink.finish()
}

/// Parses the magic, version and header dictionary; returns the row count
/// and where the data starts.
fn read_header(r: &mut impl Read, path: &Path) -> Result<(u64, u64), Error> {
    let bad = |p: String| Error::format(path, p);
    let mut fixed = [0u8; 8];
    r.read_exact(&mut fixed)
        .map_err(|_| bad("not a numpy .npy file (shorter than its magic)".into()))?;
    if &fixed[..6] != MAGIC {
        return Err(bad("not a numpy .npy file (no \\x93NUMPY magic)".into()));
    }
    let (len, prefix) = match fixed[6] {
        1 => {
            let mut b = [0u8; 2];
            r.read_exact(&mut b).map_err(|e| Error::io(path, e))?;
            (u16::from_le_bytes(b) as u64, 10)
        }
        2 | 3 => {
            let mut b = [0u8; 4];
            r.read_exact(&mut b).map_err(|e| Error::io(path, e))?;
            (u32::from_le_bytes(b) as u64, 12)
        }
        v => {
            return Err(bad(format!(
                "numpy format version {v} is not supported (1 to 3 are)"
            )));
        }
    };
    if len > 1 << 16 {
        return Err(bad(format!(
            "a header of {len} bytes is not a record array's"
        )));
    }
    let mut text = vec![0u8; len as usize];
    r.read_exact(&mut text)
        .map_err(|_| bad("truncated in its header".into()))?;
    let text = String::from_utf8_lossy(&text);
    let descr = field(&text, "descr").ok_or_else(|| bad("its header has no 'descr'".into()))?;
    let descr = descr.trim_matches(|c| c == '\'' || c == '"');
    if descr != "<f4" {
        return Err(bad(format!(
            "dtype {descr:?}, but records are little-endian float32 ('<f4'): use arr.astype('<f4')"
        )));
    }
    let fortran = field(&text, "fortran_order")
        .ok_or_else(|| bad("its header has no 'fortran_order'".into()))?;
    if fortran != "False" {
        return Err(bad(
            "the array is in Fortran order: use np.ascontiguousarray(arr)".into(),
        ));
    }
    let shape = field(&text, "shape").ok_or_else(|| bad("its header has no 'shape'".into()))?;
    let dims: Vec<&str> = shape
        .trim_matches(|c| c == '(' || c == ')')
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .collect();
    let parsed: Option<Vec<u64>> = dims.iter().map(|d| d.parse().ok()).collect();
    match parsed.as_deref() {
        Some([rows, 6]) => Ok((*rows, prefix + len)),
        _ => Err(bad(format!(
            "shape {shape}, but records are an (N, 6) array of x, y, t, r, g, b"
        ))),
    }
}

/// The value of `'key': value` in a numpy header dictionary (values here
/// are a quoted string, a bool or a tuple).
fn field<'a>(dict: &'a str, key: &str) -> Option<&'a str> {
    let at = dict.find(&format!("'{key}'"))? + key.len() + 2;
    let rest = dict[at..].trim_start().strip_prefix(':')?.trim_start();
    let end = if rest.starts_with('(') {
        rest.find(')')? + 1
    } else {
        rest.find([',', '}']).unwrap_or(rest.len())
    };
    Some(rest[..end].trim())
}

#[cfg(test)]
mod tests {
    use super::field;

    #[test]
    fn fields_of_a_numpy_header() {
        let h = "{'descr': '<f4', 'fortran_order': False, 'shape': (12, 6), }";
        assert_eq!(field(h, "descr"), Some("'<f4'"));
        assert_eq!(field(h, "fortran_order"), Some("False"));
        assert_eq!(field(h, "shape"), Some("(12, 6)"));
        assert_eq!(field(h, "nothing"), None);
    }
}
