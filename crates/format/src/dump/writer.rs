use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::Path;

use memmap2::MmapMut;

use super::{DumpError, Header, Record};
use crate::atomic::AtomicFile;
use crate::guard::{self, Inputs};

/// Streams records into a new dump. The header's `sample_count` is patched
/// on [`DumpWriter::finish`], which also renames the file into place.
pub struct DumpWriter {
    file: AtomicFile,
    out: BufWriter<File>,
    header: Header,
    count: u64,
}

impl DumpWriter {
    pub fn create(path: impl AsRef<Path>, header: Header) -> Result<DumpWriter, DumpError> {
        let path = path.as_ref();
        Inputs::default().check_file(path, guard::looks_like_dump)?;
        let file = AtomicFile::create(path)?;
        let f = file
            .file()
            .try_clone()
            .map_err(|e| DumpError::io(path, e))?;
        let mut out = BufWriter::with_capacity(1 << 20, f);
        let prefix = header
            .prefix_bytes()
            .map_err(|p| DumpError::format(path, p))?;
        out.write_all(&prefix).map_err(|e| DumpError::io(path, e))?;
        Ok(DumpWriter {
            file,
            out,
            header,
            count: 0,
        })
    }

    pub fn push(&mut self, r: &Record) -> Result<(), DumpError> {
        self.count += 1;
        self.out
            .write_all(bytemuck::bytes_of(r))
            .map_err(|e| DumpError::io(self.file.dest(), e))
    }

    pub fn push_all(&mut self, rs: &[Record]) -> Result<(), DumpError> {
        self.count += rs.len() as u64;
        self.out
            .write_all(bytemuck::cast_slice(rs))
            .map_err(|e| DumpError::io(self.file.dest(), e))
    }

    /// Patches the sample count, flushes, syncs and renames into place.
    pub fn finish(mut self) -> Result<Header, DumpError> {
        let dest = self.file.dest().to_path_buf();
        let ioe = |e| DumpError::io(&dest, e);
        self.header.sample_count = self.count;
        // The count is a fixed-width field, so the header keeps its length.
        let prefix = self
            .header
            .prefix_bytes()
            .map_err(|p| DumpError::format(&dest, p))?;
        self.out.flush().map_err(ioe)?;
        let mut f = self.out.into_inner().map_err(|e| ioe(e.into_error()))?;
        f.seek(SeekFrom::Start(0)).map_err(ioe)?;
        f.write_all(&prefix).map_err(ioe)?;
        f.sync_all().map_err(ioe)?;
        self.file.commit()?;
        Ok(self.header)
    }
}

/// A dump of known size, memory-mapped for writing: workers fill records at
/// their final index in any order. Renamed into place by `finish`.
pub struct PresizedDump {
    file: AtomicFile,
    map: Option<MmapMut>,
    offset: usize,
}

impl PresizedDump {
    pub fn create(path: impl AsRef<Path>, header: &Header) -> Result<PresizedDump, DumpError> {
        let path = path.as_ref();
        let prefix = header
            .prefix_bytes()
            .map_err(|p| DumpError::format(path, p))?;
        Inputs::default().check_file(path, guard::looks_like_dump)?;
        let file = AtomicFile::create(path)?;
        let mut f = file.file();
        let total = prefix.len() as u64 + 24 * header.sample_count;
        f.set_len(total).map_err(|e| DumpError::io(path, e))?;
        f.write_all(&prefix).map_err(|e| DumpError::io(path, e))?;
        let map = if header.sample_count > 0 {
            // SAFETY: the temporary file is private to this writer.
            Some(unsafe { MmapMut::map_mut(f) }.map_err(|e| DumpError::io(path, e))?)
        } else {
            None
        };
        Ok(PresizedDump {
            file,
            map,
            offset: prefix.len(),
        })
    }

    pub fn records_mut(&mut self) -> &mut [Record] {
        match &mut self.map {
            Some(m) => bytemuck::cast_slice_mut(&mut m[self.offset..]),
            None => &mut [],
        }
    }

    pub fn finish(mut self) -> Result<(), DumpError> {
        let dest = self.file.dest().to_path_buf();
        if let Some(m) = self.map.take() {
            m.flush().map_err(|e| DumpError::io(&dest, e))?;
        }
        self.file.commit()
    }
}
