//! What a run may read and what it may replace: the rules that keep a
//! user's files safe from a mistyped path.
//!
//! - **Inputs are regular files**, opened without blocking ([`open_input`]):
//!   a FIFO, a device or a folder is refused in one line instead of
//!   hanging or reading forever.
//! - **An output folder is ours or new** ([`Inputs::check_dir`]): it is
//!   replaced only when it does not exist, is empty, or holds the marker
//!   ([`MARKER`]) that every folder this tool writes carries, and never
//!   when it holds an input of the run.
//! - **An output file is never an input** ([`Inputs::check_file`]),
//!   compared by identity (device and inode, links resolved), and replaces
//!   an existing file only when that file looks like one of ours.
//!
//! ```
//! use pathdensity_format::guard::Inputs;
//! let dir = tempfile::tempdir().unwrap();
//! let dump = dir.path().join("shot.pds");
//! std::fs::write(&dump, b"PDSDUMP1").unwrap();
//! let inputs = Inputs::of([&dump]);
//! // The folder holding the dump is not a place for outputs...
//! assert!(inputs.check_dir(dir.path()).is_err());
//! // ...nor is the dump itself a place for the decisions.
//! assert!(inputs.check_file(&dump, |_| true).is_err());
//! assert!(inputs.check_dir(&dir.path().join("out")).is_ok());
//! ```

use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};

use crate::Error;

/// The file every output folder of this tool holds: its presence is what
/// makes a folder "a previous run of ours", replaceable by the next run.
pub const MARKER: &str = ".pathdensity-output";

/// The first line of [`MARKER`]; the lines after it name what the folder
/// held when it was written.
const MARKER_TEXT: &str = "This folder was written by pathdensity; a later run writing here \
replaces it whole if it holds nothing but these:\n";

/// Writes `dir`'s [`MARKER`], listing `names` (the folder's own entries)
/// as ours.
pub fn write_marker<S: AsRef<str>>(dir: &Path, names: &[S]) -> Result<(), Error> {
    let mut text = MARKER_TEXT.to_string();
    for n in names {
        text += n.as_ref();
        text.push('\n');
    }
    // Atomic: shards of one batch starting together each read it.
    crate::atomic::write_bytes(&dir.join(MARKER), text.as_bytes())
}

/// Whether `name` is the marker or one of this tool's temporaries
/// (`.NAME.XXXXXX.tmp`, `.NAME.XXXXXX.staging`): what another process of
/// ours may be writing into a folder that is still new.
fn ours_in_passing(name: &str) -> bool {
    name == MARKER
        || (name.starts_with('.') && (name.ends_with(".tmp") || name.ends_with(".staging")))
}

/// Writes `dir`'s [`MARKER`] listing every entry `dir` holds now.
pub fn mark_all(dir: &Path) -> Result<(), Error> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n != MARKER)
        .collect();
    names.sort();
    write_marker(dir, &names)
}

/// The names `dir`'s marker lists, if it has one.
pub fn marked(dir: &Path) -> Option<Vec<String>> {
    let text = read_input_text(&dir.join(MARKER), 1 << 24).ok()?;
    let rest = text.strip_prefix(MARKER_TEXT)?;
    Some(rest.lines().map(str::to_string).collect())
}

/// A file's identity: its device and inode, links resolved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Id {
    dev: u64,
    ino: u64,
}

fn identity(p: &Path) -> Option<Id> {
    let m = std::fs::metadata(p).ok()?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        Some(Id {
            dev: m.dev(),
            ino: m.ino(),
        })
    }
    #[cfg(not(unix))]
    {
        let _ = m;
        None
    }
}

/// Opens `path` for reading only if it is a regular file, without ever
/// blocking: opened non-blocking (a FIFO with no writer would block an
/// ordinary open), checked with `fstat`, then set back to blocking.
pub fn open_input(path: &Path) -> Result<File, Error> {
    let mut o = std::fs::OpenOptions::new();
    o.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        o.custom_flags(libc::O_NONBLOCK);
    }
    let file = o.open(path).map_err(|e| Error::io(path, e))?;
    let meta = file.metadata().map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::format(path, not_regular(&meta)));
    }
    #[cfg(unix)]
    {
        use std::os::fd::AsRawFd;
        let fd = file.as_raw_fd();
        // SAFETY: fcntl on a descriptor this function owns, no pointers.
        let ok = unsafe {
            let flags = libc::fcntl(fd, libc::F_GETFL);
            flags >= 0 && libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK) == 0
        };
        if !ok {
            return Err(Error::io(path, std::io::Error::last_os_error()));
        }
    }
    Ok(file)
}

/// What kind of file `meta` describes, for a refusal.
fn not_regular(meta: &std::fs::Metadata) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let t = meta.file_type();
        if t.is_fifo() {
            return "is a FIFO, not a regular file";
        }
        if t.is_char_device() || t.is_block_device() {
            return "is a device, not a regular file";
        }
        if t.is_socket() {
            return "is a socket, not a regular file";
        }
    }
    if meta.is_dir() {
        "is a directory, not a regular file"
    } else {
        "is not a regular file"
    }
}

/// The whole of a regular file of at most `limit` bytes (a manifest, a
/// report, an `.npy` header's file): refused in one line when larger.
pub fn read_input(path: &Path, limit: u64) -> Result<Vec<u8>, Error> {
    let file = open_input(path)?;
    let size = file.metadata().map_err(|e| Error::io(path, e))?.len();
    if size > limit {
        return Err(Error::format(
            path,
            format!("is {size} bytes, more than the {limit} such a file may hold"),
        ));
    }
    let mut bytes = Vec::with_capacity(size as usize);
    file.take(limit + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > limit {
        return Err(Error::format(path, "grew while being read"));
    }
    Ok(bytes)
}

/// [`read_input`] as UTF-8 text.
pub fn read_input_text(path: &Path, limit: u64) -> Result<String, Error> {
    String::from_utf8(read_input(path, limit)?)
        .map_err(|_| Error::format(path, "is not UTF-8 text"))
}

/// The inputs of a run: what no output may be, replace or contain.
#[derive(Clone, Debug, Default)]
pub struct Inputs {
    /// Each input as given, its identity and its folders (links resolved),
    /// innermost first.
    files: Vec<(PathBuf, Id, Vec<Id>)>,
}

impl Inputs {
    /// The inputs among `paths` that exist (one that does not cannot be
    /// harmed, and is refused where it is read).
    pub fn of<P: AsRef<Path>>(paths: impl IntoIterator<Item = P>) -> Inputs {
        let mut i = Inputs::default();
        for p in paths {
            i.add(p.as_ref());
        }
        i
    }

    pub fn add(&mut self, p: &Path) {
        let Some(id) = identity(p) else { return };
        let folders = std::fs::canonicalize(p)
            .map(|c| c.ancestors().skip(1).filter_map(identity).collect())
            .unwrap_or_default();
        self.files.push((p.to_path_buf(), id, folders));
    }

    /// The input `dest` is (by identity), if any.
    fn same_as(&self, dest: &Path) -> Option<&Path> {
        let id = identity(dest)?;
        self.files
            .iter()
            .find(|(_, i, _)| *i == id)
            .map(|(p, _, _)| p.as_path())
    }

    /// Refuses `dest` as an output file when it is an input, is not a
    /// regular file, or exists and does not look like one of ours
    /// (`ours` sees its first bytes).
    pub fn check_file(&self, dest: &Path, ours: fn(&[u8]) -> bool) -> Result<(), Error> {
        if let Some(input) = self.same_as(dest) {
            let what = if input == dest {
                "is an input of this run: refusing to overwrite it".to_string()
            } else {
                format!(
                    "is the same file as the input {}: refusing to overwrite it",
                    input.display()
                )
            };
            return Err(Error::format(dest, what));
        }
        let Ok(meta) = std::fs::symlink_metadata(dest) else {
            return Ok(());
        };
        if !meta.is_file() {
            return Err(Error::format(
                dest,
                format!("{}: refusing to replace it", not_regular(&meta)),
            ));
        }
        let mut head = Vec::new();
        open_input(dest)?
            .take(4096)
            .read_to_end(&mut head)
            .map_err(|e| Error::io(dest, e))?;
        if !head.is_empty() && !ours(&head) {
            return Err(Error::format(
                dest,
                "exists and was not written by pathdensity: refusing to replace it (remove it or choose another name)",
            ));
        }
        Ok(())
    }

    /// Refuses `dest` as an output folder unless it is new, empty or a
    /// previous run's (it holds [`MARKER`]), and whenever it is, or holds,
    /// an input.
    pub fn check_dir(&self, dest: &Path) -> Result<(), Error> {
        let Ok(meta) = std::fs::symlink_metadata(dest) else {
            return Ok(());
        };
        if meta.file_type().is_symlink() {
            // The staging swap would replace the link, not the folder it
            // names: the user's folder survives, but refuse the surprise.
            return Err(Error::format(
                dest,
                "is a symbolic link: name the folder itself",
            ));
        }
        if !meta.is_dir() {
            return Err(Error::format(dest, "exists and is not a directory"));
        }
        if let Some(id) = identity(dest)
            && let Some((input, _, _)) = self
                .files
                .iter()
                .find(|(_, i, folders)| *i == id || folders.contains(&id))
        {
            return Err(Error::format(
                dest,
                format!(
                    "holds an input of this run ({}): refusing to replace it",
                    input.display()
                ),
            ));
        }
        check_ours(dest)?;
        // Ours: replaced only if nothing was added to it since.
        if let Some(names) = marked(dest) {
            let listing = std::fs::read_dir(dest).map_err(|e| Error::io(dest, e))?;
            for e in listing {
                let name = e
                    .map_err(|e| Error::io(dest, e))?
                    .file_name()
                    .to_string_lossy()
                    .into_owned();
                if name != MARKER && !names.contains(&name) {
                    return Err(Error::format(
                        dest,
                        format!(
                            "holds {name}, which pathdensity did not write there: refusing to replace it (move it, or choose another folder)"
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}

/// Refuses the existing folder `dest` as an output folder unless it is
/// empty or a previous run's (it holds [`MARKER`]). A folder that does not
/// exist is new, and passes.
pub fn check_ours(dest: &Path) -> Result<(), Error> {
    if !dest.exists() || marked(dest).is_some() {
        return Ok(());
    }
    if !dest.is_dir() {
        return Err(Error::format(dest, "exists and is not a directory"));
    }
    let listing = std::fs::read_dir(dest).map_err(|e| Error::io(dest, e))?;
    let mut foreign = listing
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| !ours_in_passing(n));
    match foreign.next() {
        None => Ok(()),
        Some(name) => Err(Error::format(
            dest,
            format!(
                "holds files pathdensity did not write ({name}, …): refusing to write into it (choose a new or empty folder)"
            ),
        )),
    }
}

/// Whether `head` starts like a dump (docs/format.md).
pub fn looks_like_dump(head: &[u8]) -> bool {
    head.starts_with(crate::dump::MAGIC)
}

/// Whether `head` starts like an OpenEXR file.
pub fn looks_like_exr(head: &[u8]) -> bool {
    head.starts_with(&[0x76, 0x2f, 0x31, 0x01])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fifo_is_refused_without_blocking() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let e = open_input(&fifo).unwrap_err().to_string();
        assert!(e.contains("FIFO") && e.contains("pipe"), "{e}");
        let e = read_input(Path::new("/dev/zero"), 1 << 20)
            .unwrap_err()
            .to_string();
        assert!(e.contains("device"), "{e}");
    }

    #[test]
    fn a_folder_is_ours_new_or_empty() {
        let dir = tempfile::tempdir().unwrap();
        let none = Inputs::default();
        assert!(none.check_dir(&dir.path().join("new")).is_ok());
        assert!(none.check_dir(dir.path()).is_ok(), "empty");
        std::fs::write(dir.path().join("notes.txt"), b"mine").unwrap();
        let e = none.check_dir(dir.path()).unwrap_err().to_string();
        assert!(e.contains("notes.txt"), "{e}");
        write_marker(dir.path(), &["notes.txt"]).unwrap();
        assert!(none.check_dir(dir.path()).is_ok(), "ours");
        std::fs::write(dir.path().join("added.txt"), b"mine").unwrap();
        let e = none.check_dir(dir.path()).unwrap_err().to_string();
        assert!(e.contains("added.txt"), "{e}");
    }

    #[test]
    fn an_output_is_never_an_input_nor_holds_one() {
        let dir = tempfile::tempdir().unwrap();
        let shot = dir.path().join("shot");
        std::fs::create_dir(&shot).unwrap();
        write_marker(&shot, &["d.pds"]).unwrap();
        let dump = shot.join("d.pds");
        std::fs::write(&dump, b"PDSDUMP1").unwrap();
        let link = dir.path().join("link.pds");
        std::os::unix::fs::symlink(&dump, &link).unwrap();
        let hard = dir.path().join("hard.pds");
        std::fs::hard_link(&dump, &hard).unwrap();
        let inputs = Inputs::of([&link]);
        // Even a folder of ours is kept when it holds an input.
        assert!(inputs.check_dir(&shot).is_err());
        assert!(inputs.check_dir(dir.path()).is_err(), "an ancestor");
        for alias in [&dump, &link, &hard] {
            assert!(inputs.check_file(alias, |_| true).is_err(), "{alias:?}");
        }
        let other = dir.path().join("notes.txt");
        std::fs::write(&other, b"mine").unwrap();
        assert!(inputs.check_file(&other, looks_like_dump).is_err());
        assert!(
            inputs
                .check_file(&dir.path().join("new.pds"), looks_like_dump)
                .is_ok()
        );
        assert!(inputs.check_file(Path::new("/dev/null"), |_| true).is_err());
    }
}
