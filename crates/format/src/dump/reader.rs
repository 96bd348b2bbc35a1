use std::io::Read;
use std::path::{Path, PathBuf};

use memmap2::Mmap;

use super::{DumpError, HEADER_LEN_MAX, Header, MAGIC, Record, VERSION, data_offset};

#[cfg(not(target_endian = "little"))]
compile_error!("the zero-copy dump reader assumes a little-endian host");

/// A validated dump, memory-mapped. The records are never copied: the
/// operating system pages them in as they are read, so dumps larger than
/// memory can be scanned.
pub struct DumpReader {
    path: PathBuf,
    header: Header,
    header_len: usize,
    /// Declared before `map`: the watch ends before the unmapping.
    #[cfg(unix)]
    watch: Option<super::shrink::Watch>,
    map: Option<Mmap>,
}

impl DumpReader {
    /// Opens and validates `path` strictly (docs/format.md): magic, version, header
    /// length, exact header decoding, zero padding, and a file size equal to
    /// `data_offset + 24 × sample_count`.
    pub fn open(path: impl AsRef<Path>) -> Result<DumpReader, DumpError> {
        let path = path.as_ref();
        let err = |p: String| DumpError::format(path, p);
        let mut file = crate::guard::open_input(path)?;
        let size = file.metadata().map_err(|e| DumpError::io(path, e))?.len();
        // The prefix is at most data_offset(HEADER_LEN_MAX) bytes: a bounded
        // read whatever the header claims.
        let mut prefix = Vec::new();
        (&mut file)
            .take(data_offset(HEADER_LEN_MAX) as u64)
            .read_to_end(&mut prefix)
            .map_err(|e| DumpError::io(path, e))?;
        let (header, header_len) = parse_prefix(&prefix, size).map_err(err)?;
        let expected = size;
        let map = if header.sample_count > 0 {
            // SAFETY: the file is opened read-only; a concurrent truncation
            // by another process is caught by the watch (`intact`).
            Some(unsafe { Mmap::map(&file) }.map_err(|e| DumpError::io(path, e))?)
        } else {
            None
        };
        if let Some(m) = &map
            && m.len() as u64 != expected
        {
            return Err(err(format!(
                "file changed size while being opened ({} bytes mapped, {expected} expected)",
                m.len()
            )));
        }
        Ok(DumpReader {
            path: path.to_path_buf(),
            header,
            header_len,
            #[cfg(unix)]
            watch: map
                .as_ref()
                .map(|m| super::shrink::Watch::new(m.as_ptr(), m.len())),
            map,
        })
    }

    /// Refuses what was read when the file shrank while it was mapped (the
    /// records past its new end read as zeros): what a caller checks
    /// before it keeps any result made from [`DumpReader::records`].
    pub fn intact(&self) -> Result<(), DumpError> {
        #[cfg(unix)]
        if self.watch.as_ref().is_some_and(|w| w.shrunk()) {
            let now = std::fs::metadata(&self.path).map_or(0, |m| m.len());
            let was = self.map.as_ref().map_or(0, |m| m.len());
            return Err(DumpError::format(
                &self.path,
                format!(
                    "the file shrank while it was read ({now} bytes now, {was} when opened): nothing was written from it"
                ),
            ));
        }
        Ok(())
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn header(&self) -> &Header {
        &self.header
    }

    /// Encoded header length in bytes.
    pub fn header_len(&self) -> usize {
        self.header_len
    }

    /// A 64-bit digest (XXH3) of the dump's content, header and records:
    /// equal for equal files, and what a report records to say which dump
    /// it was made from.
    pub fn content_hash(&self) -> u64 {
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        if let Ok(prefix) = self.header.prefix_bytes() {
            h.update(&prefix);
        }
        h.update(bytemuck::cast_slice(self.records()));
        h.digest()
    }

    /// Every record, in file order, without copying.
    pub fn records(&self) -> &[Record] {
        match &self.map {
            Some(m) => bytemuck::cast_slice(&m[data_offset(self.header_len)..]),
            None => &[],
        }
    }
}

/// Validates the start of a dump of `size` bytes (docs/format.md): magic, version,
/// header length, exact header decoding, zero padding, and a size equal to
/// `data_offset + 24 × sample_count`. `prefix` holds the file's first bytes
/// (at least `data_offset` of them when the file is that long). Returns the
/// header and its encoded length. Never allocates from a claimed size.
pub fn parse_prefix(prefix: &[u8], size: u64) -> Result<(Header, usize), String> {
    if prefix.len() < 16 {
        return Err(format!("file is {size} bytes, too short for a dump prefix"));
    }
    if &prefix[0..8] != MAGIC {
        return Err("not a pathdensity dump (magic is not PDSDUMP1)".into());
    }
    let version = u32::from_le_bytes(prefix[8..12].try_into().unwrap());
    if version != VERSION {
        return Err(format!(
            "unsupported dump version {version} (expected {VERSION})"
        ));
    }
    let header_len = u32::from_le_bytes(prefix[12..16].try_into().unwrap()) as usize;
    if header_len > HEADER_LEN_MAX {
        return Err(format!(
            "header_len {header_len} exceeds the limit of {HEADER_LEN_MAX}"
        ));
    }
    let offset = data_offset(header_len);
    if size < offset as u64 || prefix.len() < offset {
        return Err(format!(
            "file is {size} bytes, shorter than its header and padding ({offset} bytes)"
        ));
    }
    let header = Header::decode(&prefix[16..16 + header_len])?;
    if prefix[16 + header_len..offset].iter().any(|&b| b != 0) {
        return Err("non-zero padding between header and records".into());
    }
    let expected = header
        .sample_count
        .checked_mul(24)
        .and_then(|b| b.checked_add(offset as u64))
        .ok_or_else(|| "sample_count overflows the file size".to_string())?;
    if size != expected {
        return Err(format!(
            "file size is {size} bytes but {} samples need {expected} bytes",
            header.sample_count
        ));
    }
    Ok((header, header_len))
}
