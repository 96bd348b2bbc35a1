//! Writes that never leave a half-written file under the final name: a
//! file is written under a temporary name in its destination's directory
//! (`tempfile`) and renamed into place when complete.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

use tempfile::NamedTempFile;

use crate::Error;

/// A file being written under a temporary name (`.NAME.XXXXXX.tmp`) beside
/// its destination, renamed into place by [`AtomicFile::commit`]. Dropped
/// uncommitted, it removes the temporary file, so an error or a panic
/// leaves the destination untouched (a killed process may leave the
/// temporary behind; its name never looks like an output).
pub struct AtomicFile {
    tmp: NamedTempFile,
    dest: PathBuf,
}

impl AtomicFile {
    /// Creates the temporary file, open for reading and writing (so that
    /// it can be memory-mapped).
    pub fn create(dest: impl AsRef<Path>) -> Result<AtomicFile, Error> {
        let dest = dest.as_ref().to_path_buf();
        let name = dest
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let dir = match dest.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        let tmp = tempfile::Builder::new()
            .prefix(&format!(".{name}."))
            .suffix(".tmp")
            .tempfile_in(dir)
            .map_err(|e| Error::io(&dest, e))?;
        Ok(AtomicFile { tmp, dest })
    }

    pub fn file(&self) -> &File {
        self.tmp.as_file()
    }

    pub fn file_mut(&mut self) -> &mut File {
        self.tmp.as_file_mut()
    }

    /// The temporary path, for writers that open files themselves.
    pub fn tmp_path(&self) -> &Path {
        self.tmp.path()
    }

    pub fn dest(&self) -> &Path {
        &self.dest
    }

    /// Renames the temporary file to its destination.
    pub fn commit(self) -> Result<(), Error> {
        let dest = self.dest;
        self.tmp
            .persist(&dest)
            .map(|_| ())
            .map_err(|e| Error::io(&dest, e.error))
    }
}

/// Writes `bytes` to `dest` atomically, synced to disk.
pub fn write_bytes(dest: &Path, bytes: &[u8]) -> Result<(), Error> {
    let mut f = AtomicFile::create(dest)?;
    let file = f.file_mut();
    file.write_all(bytes)
        .and_then(|_| file.sync_all())
        .map_err(|e| Error::io(dest, e))?;
    f.commit()
}
