//! Writes that never leave a half-written file under the final name.

use std::fs::File;
use std::path::{Path, PathBuf};

/// A file written under a temporary name beside its destination and renamed
/// into place by [`AtomicFile::commit`]. Dropping it uncommitted removes the
/// temporary file, so an error or a panic leaves the destination untouched.
pub struct AtomicFile {
    tmp: PathBuf,
    dest: PathBuf,
    committed: bool,
}

impl AtomicFile {
    /// Reserves a temporary name in the destination's directory.
    pub fn new(dest: impl AsRef<Path>) -> AtomicFile {
        let dest = dest.as_ref().to_path_buf();
        let name = dest
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let tmp = dest.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
        AtomicFile {
            tmp,
            dest,
            committed: false,
        }
    }

    /// Creates (truncates) the temporary file, open for reading too so
    /// that it can be memory-mapped for writing.
    pub fn create(&self) -> std::io::Result<File> {
        File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&self.tmp)
    }

    /// The temporary path, for writers that open files themselves.
    pub fn tmp_path(&self) -> &Path {
        &self.tmp
    }

    pub fn dest(&self) -> &Path {
        &self.dest
    }

    /// Renames the temporary file to its destination.
    pub fn commit(mut self) -> std::io::Result<()> {
        std::fs::rename(&self.tmp, &self.dest)?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Writes `bytes` to `dest` atomically.
pub fn write_bytes(dest: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    use anyhow::Context;
    use std::io::Write;
    let f = AtomicFile::new(dest);
    let mut file = f
        .create()
        .with_context(|| format!("{}: cannot create", dest.display()))?;
    file.write_all(bytes)
        .and_then(|_| file.sync_all())
        .with_context(|| format!("{}: write failed", dest.display()))?;
    f.commit()
        .with_context(|| format!("{}: cannot rename into place", dest.display()))
}
