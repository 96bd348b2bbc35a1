//! Writes that never leave a half-written file under the final name: a
//! file is written under a temporary name in its destination's directory
//! (`tempfile`) and renamed into place when complete.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use tempfile::{NamedTempFile, TempDir};

use crate::Error;
use crate::guard::{self, Inputs};

/// A temporary file or folder named `.NAME.XXXXXX.SUFFIX`, created with
/// the permissions of an ordinary file or folder (0666 or 0777 less the
/// umask), not `tempfile`'s private 0600: outputs are read by other users
/// and web servers on a farm.
fn builder<'a>(prefix: &'a str, suffix: &'a str, dir: bool) -> tempfile::Builder<'a, 'a> {
    let mut b = tempfile::Builder::new();
    b.prefix(prefix).suffix(suffix);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        b.permissions(std::fs::Permissions::from_mode(if dir {
            0o777
        } else {
            0o666
        }));
    }
    #[cfg(not(unix))]
    let _ = dir;
    b
}

/// `e` without the temporary path `tempfile` adds to its message (the
/// caller names the destination instead).
fn bare(e: &std::io::Error) -> std::io::Error {
    match e.raw_os_error() {
        Some(code) => std::io::Error::from_raw_os_error(code),
        None => e.kind().into(),
    }
}

/// Every temporary file and staging folder this process has open, so that
/// a signal handler can remove them ([`remove_temporaries`]).
static TEMPORARIES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn register(p: &Path) {
    let mut t = TEMPORARIES.lock().unwrap_or_else(|e| e.into_inner());
    t.push(p.to_path_buf());
}

fn unregister(p: &Path) {
    let mut t = TEMPORARIES.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(i) = t.iter().rposition(|q| q == p) {
        t.swap_remove(i);
    }
}

/// Removes every temporary file and staging folder still open: what a
/// SIGINT or SIGTERM handler calls before the process exits, since an
/// exiting process runs no destructor. Safe to call from any thread.
pub fn remove_temporaries() {
    let t = TEMPORARIES.lock().unwrap_or_else(|e| e.into_inner());
    for p in t.iter() {
        if p.is_dir() {
            // Workers may still be adding files to a staging folder while
            // it is removed, which makes one removal fail: try again.
            for _ in 0..50 {
                if std::fs::remove_dir_all(p).is_ok() || !p.exists() {
                    break;
                }
            }
        } else {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// A file being written under a temporary name (`.NAME.XXXXXX.tmp`) beside
/// its destination, renamed into place by [`AtomicFile::commit`]. Dropped
/// uncommitted, it removes the temporary file, so an error or a panic
/// leaves the destination untouched (a killed process may leave the
/// temporary behind; its name never looks like an output).
pub struct AtomicFile {
    /// `None` once committed.
    tmp: Option<NamedTempFile>,
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
        let tmp = builder(&format!(".{name}."), ".tmp", false)
            .tempfile_in(dir)
            .map_err(|e| Error::format(&dest, format!("cannot create: {}", bare(&e))))?;
        register(tmp.path());
        Ok(AtomicFile {
            tmp: Some(tmp),
            dest,
        })
    }

    fn tmp(&self) -> &NamedTempFile {
        self.tmp.as_ref().expect("not committed")
    }

    pub fn file(&self) -> &File {
        self.tmp().as_file()
    }

    pub fn file_mut(&mut self) -> &mut File {
        self.tmp.as_mut().expect("not committed").as_file_mut()
    }

    /// The temporary path, for writers that open files themselves.
    pub fn tmp_path(&self) -> &Path {
        self.tmp().path()
    }

    pub fn dest(&self) -> &Path {
        &self.dest
    }

    /// Renames the temporary file to its destination.
    pub fn commit(mut self) -> Result<(), Error> {
        let tmp = self.tmp.take().expect("committed once");
        let tmp_path = tmp.path().to_path_buf();
        let done = tmp.persist(&self.dest).map(|_| ());
        unregister(&tmp_path);
        done.map_err(|e| Error::io(&self.dest, e.error))
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        // Uncommitted: the temporary file removes itself.
        if let Some(tmp) = &self.tmp {
            unregister(tmp.path());
        }
    }
}

/// A folder of outputs built beside its destination under a temporary
/// name (`.NAME.XXXXXX.staging`) and swapped in whole by
/// [`Staging::commit`], so the destination always holds exactly one
/// complete run: the previous one until the swap, the new one after.
/// Dropped uncommitted, the staging folder is removed.
///
/// The destination is replaced only when it is ours or new
/// ([`Inputs::check_dir`]): the folder swapped in carries
/// [`guard::MARKER`], so it is recognisably ours.
pub struct Staging {
    dir: Option<TempDir>,
    dest: PathBuf,
}

impl Staging {
    /// Creates the staging folder (and the destination's parent), once
    /// `dest` is known to be replaceable: new, empty, or a previous run's,
    /// and holding none of `inputs`.
    pub fn create(dest: impl AsRef<Path>, inputs: &Inputs) -> Result<Staging, Error> {
        let dest = dest.as_ref().to_path_buf();
        inputs.check_dir(&dest)?;
        let name = dest
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .ok_or_else(|| Error::format(&dest, "is not a folder name"))?;
        let parent = match dest.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        std::fs::create_dir_all(&parent)
            .map_err(|e| Error::format(&dest, format!("cannot create its parent folder: {e}")))?;
        let dir = builder(&format!(".{name}."), ".staging", true)
            .tempdir_in(&parent)
            .map_err(|e| Error::format(&dest, format!("cannot write beside it: {}", bare(&e))))?;
        register(dir.path());
        Ok(Staging {
            dir: Some(dir),
            dest,
        })
    }

    /// Where the outputs go until the swap.
    pub fn path(&self) -> &Path {
        self.dir.as_ref().expect("not committed").path()
    }

    pub fn dest(&self) -> &Path {
        &self.dest
    }

    /// `message` (an error while writing into the staging folder) with the
    /// staging folder's hidden name replaced by the destination's: what the
    /// user asked for and will look at.
    pub fn in_dest(&self, message: &str) -> String {
        let staged = self.path().display().to_string();
        message.replace(&staged, &self.dest.display().to_string())
    }

    /// Marks the staging folder as ours ([`guard::MARKER`], listing what
    /// it holds), swaps it in for the destination and removes the previous
    /// run's folder.
    pub fn commit(mut self) -> Result<(), Error> {
        let dir = self.dir.take().expect("committed once");
        let staged = dir.path().to_path_buf();
        guard::mark_all(&staged).map_err(|e| Error::format(&self.dest, e.to_string()))?;
        let done = swap_in(&staged, &self.dest);
        if done.is_ok() && !staged.exists() {
            let _ = dir.keep();
        } else {
            // The temporary name holds the previous run (or, if the swap
            // failed, this one): removed while still registered, so that a
            // SIGINT in the middle removes the rest.
            drop(dir);
        }
        unregister(&staged);
        done
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        if let Some(dir) = &self.dir {
            unregister(dir.path());
        }
    }
}

/// Puts `staged` at `dest`; a folder already at `dest` ends up at
/// `staged`. On Linux one atomic exchange (`renameat2`), so `dest` never
/// stops existing; elsewhere two renames.
fn swap_in(staged: &Path, dest: &Path) -> Result<(), Error> {
    if !dest.exists() {
        return std::fs::rename(staged, dest).map_err(|e| Error::io(dest, e));
    }
    #[cfg(target_os = "linux")]
    {
        use std::ffi::CString;
        use std::os::unix::ffi::OsStrExt;
        let c = |p: &Path| CString::new(p.as_os_str().as_bytes()).ok();
        if let (Some(a), Some(b)) = (c(staged), c(dest)) {
            // SAFETY: two valid NUL-terminated paths, no other pointers.
            let r = unsafe {
                libc::renameat2(
                    libc::AT_FDCWD,
                    a.as_ptr(),
                    libc::AT_FDCWD,
                    b.as_ptr(),
                    libc::RENAME_EXCHANGE,
                )
            };
            if r == 0 {
                return Ok(());
            }
        }
    }
    // Not Linux, or a file system without the exchange: move the old
    // folder aside first.
    let aside = staged.with_extension("previous");
    std::fs::rename(dest, &aside).map_err(|e| Error::io(dest, e))?;
    std::fs::rename(staged, dest).map_err(|e| Error::io(dest, e))?;
    std::fs::rename(&aside, staged).map_err(|e| Error::io(dest, e))
}

/// Writes `bytes` to `dest` atomically, synced to disk.
pub fn write_bytes(dest: &Path, bytes: &[u8]) -> Result<(), Error> {
    write_parts(dest, &[bytes])
}

/// Writes `parts`, one after the other, to `dest` atomically, synced to
/// disk: a large file made of pieces is never joined in memory.
pub fn write_parts(dest: &Path, parts: &[&[u8]]) -> Result<(), Error> {
    let mut f = AtomicFile::create(dest)?;
    let file = f.file_mut();
    parts
        .iter()
        .try_for_each(|p| file.write_all(p))
        .and_then(|_| file.sync_all())
        .map_err(|e| Error::io(dest, e))?;
    f.commit()
}
