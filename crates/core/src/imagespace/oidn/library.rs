//! Finding and loading OIDN 2 at run time, so that every build can use an
//! installed OIDN and none needs it. [`library`] looks, once per process,
//! in this order (docs/filter.md, "OIDN"):
//! 1. `OIDN_DIR`, when set, and nothing else: the library file it names,
//!    or `libOpenImageDenoise.so.2` in it or in its `lib/` (an OIDN
//!    install, or the `pyoidn` wheel's `oidn` folder, which
//!    `tools/oidn/setup.sh` prints);
//! 2. the `pyoidn` wheel in the active virtual environment (`VIRTUAL_ENV`);
//! 3. the dynamic loader's own search (`LD_LIBRARY_PATH`, the system's
//!    library folders);
//!
//! and binds the thirteen functions of OIDN's C API that
//! [`super::denoise`] calls.

use std::ffi::{CStr, c_char, c_int, c_void};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The file name OIDN 2's library has on this system.
const FILE: &str = if cfg!(target_os = "macos") {
    "libOpenImageDenoise.2.dylib"
} else {
    "libOpenImageDenoise.so.2"
};

pub(super) type Handle = *mut c_void;

/// The part of OIDN 2's C API this module calls (`oidn.h`).
pub(super) struct Api {
    pub(super) new_device: unsafe extern "C" fn(c_int) -> Handle,
    pub(super) commit_device: unsafe extern "C" fn(Handle),
    pub(super) device_error: unsafe extern "C" fn(Handle, *mut *const c_char) -> c_int,
    pub(super) device_int: unsafe extern "C" fn(Handle, *const c_char) -> c_int,
    pub(super) release_device: unsafe extern "C" fn(Handle),
    pub(super) new_filter: unsafe extern "C" fn(Handle, *const c_char) -> Handle,
    #[allow(clippy::type_complexity)]
    pub(super) shared_image: unsafe extern "C" fn(
        Handle,
        *const c_char,
        *mut c_void,
        c_int,
        usize,
        usize,
        usize,
        usize,
        usize,
    ),
    pub(super) unset_image: unsafe extern "C" fn(Handle, *const c_char),
    pub(super) set_bool: unsafe extern "C" fn(Handle, *const c_char, bool),
    pub(super) set_int: unsafe extern "C" fn(Handle, *const c_char, c_int),
    pub(super) commit_filter: unsafe extern "C" fn(Handle),
    pub(super) execute_filter: unsafe extern "C" fn(Handle),
    pub(super) release_filter: unsafe extern "C" fn(Handle),
}

pub(super) const DEVICE_TYPE_CPU: c_int = 1;

pub(super) const FORMAT_FLOAT3: c_int = 3;

/// An OIDN library found and loaded; it stays loaded for the process.
pub struct Library {
    path: PathBuf,
    pub(super) api: Api,
    /// OIDN's version (major·10000 + minor·100 + patch), from the first
    /// device made.
    pub(super) version: OnceLock<i32>,
}

// The handle from dlopen and the function pointers are process-global;
// OIDN's API may be called from any thread.
unsafe impl Send for Library {}
unsafe impl Sync for Library {}

impl Library {
    /// The file it was loaded from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// What a run says it denoised with: `OIDN 2.5.1 (PATH)`; the version
    /// once a device has been made.
    pub fn describe(&self) -> String {
        match self.version.get() {
            Some(v) => format!(
                "OIDN {}.{}.{} ({})",
                v / 10000,
                v / 100 % 100,
                v % 100,
                self.path.display()
            ),
            None => format!("OIDN ({})", self.path.display()),
        }
    }
}

/// The OIDN library this process uses, or why there is none (one
/// sentence naming where it looked); searched for once.
pub fn library() -> Result<&'static Library, &'static str> {
    static FOUND: OnceLock<Result<Library, String>> = OnceLock::new();
    FOUND
        .get_or_init(|| find(std::env::var_os("OIDN_DIR").map(PathBuf::from)))
        .as_ref()
        .map_err(String::as_str)
}

/// Whether this process can run OIDN.
pub fn available() -> bool {
    library().is_ok()
}

/// The search of [`library`], with `oidn_dir` for `OIDN_DIR`.
pub(super) fn find(oidn_dir: Option<PathBuf>) -> Result<Library, String> {
    if let Some(dir) = oidn_dir {
        let candidates = if dir.is_file() {
            vec![dir.clone()]
        } else {
            vec![dir.join(FILE), dir.join("lib").join(FILE)]
        };
        return candidates
            .iter()
            .find(|p| p.is_file())
            .ok_or_else(|| {
                format!(
                    "OIDN_DIR is {}, which holds no {FILE} (nor does its lib/)",
                    dir.display()
                )
            })
            .and_then(|p| load(p, p.clone()));
    }
    if let Some(venv) = std::env::var_os("VIRTUAL_ENV")
        && let Some(p) = pyoidn_in(Path::new(&venv))
    {
        return load(&p, p.clone());
    }
    load(Path::new(FILE), PathBuf::from(FILE)).map_err(|_| {
        format!(
            "no OIDN found: OIDN_DIR is unset and {FILE} is on neither the active \
             virtual environment's pyoidn nor the loader's path"
        )
    })
}

/// The library of the `pyoidn` wheel in a virtual environment.
pub(super) fn pyoidn_in(venv: &Path) -> Option<PathBuf> {
    let lib = venv.join("lib");
    std::fs::read_dir(&lib).ok()?.flatten().find_map(|e| {
        let p = e.path().join("site-packages/pyoidn/oidn/lib").join(FILE);
        p.is_file().then_some(p)
    })
}

#[cfg(unix)]
fn load(file: &Path, shown: PathBuf) -> Result<Library, String> {
    use std::os::unix::ffi::OsStrExt;
    let name = std::ffi::CString::new(file.as_os_str().as_bytes())
        .map_err(|_| format!("{}: not a loadable path", file.display()))?;
    // SAFETY: dlopen with a NUL-terminated name; the handle is kept for
    // the process (never closed), so the symbols stay valid.
    let handle = unsafe { libc::dlopen(name.as_ptr(), libc::RTLD_NOW | libc::RTLD_LOCAL) };
    if handle.is_null() {
        // SAFETY: dlerror returns a NUL-terminated message or null.
        let why = unsafe { libc::dlerror() };
        let why = if why.is_null() {
            "unknown error".into()
        } else {
            unsafe { CStr::from_ptr(why) }
                .to_string_lossy()
                .into_owned()
        };
        return Err(format!("{}: {why}", file.display()));
    }
    let symbol = |n: &CStr| -> Result<*mut c_void, String> {
        // SAFETY: a valid handle and a NUL-terminated name.
        let p = unsafe { libc::dlsym(handle, n.as_ptr()) };
        if p.is_null() {
            Err(format!(
                "{}: not OIDN 2 (no {})",
                file.display(),
                n.to_string_lossy()
            ))
        } else {
            Ok(p)
        }
    };
    // SAFETY: each symbol is OIDN 2's function of that name, whose C
    // signature (oidn.h) is the field's type.
    let api = unsafe {
        Api {
            new_device: fn_ptr(symbol(c"oidnNewDevice")?),
            commit_device: fn_ptr(symbol(c"oidnCommitDevice")?),
            device_error: fn_ptr(symbol(c"oidnGetDeviceError")?),
            device_int: fn_ptr(symbol(c"oidnGetDeviceInt")?),
            release_device: fn_ptr(symbol(c"oidnReleaseDevice")?),
            new_filter: fn_ptr(symbol(c"oidnNewFilter")?),
            shared_image: fn_ptr(symbol(c"oidnSetSharedFilterImage")?),
            unset_image: fn_ptr(symbol(c"oidnUnsetFilterImage")?),
            set_bool: fn_ptr(symbol(c"oidnSetFilterBool")?),
            set_int: fn_ptr(symbol(c"oidnSetFilterInt")?),
            commit_filter: fn_ptr(symbol(c"oidnCommitFilter")?),
            execute_filter: fn_ptr(symbol(c"oidnExecuteFilter")?),
            release_filter: fn_ptr(symbol(c"oidnReleaseFilter")?),
        }
    };
    let path = std::fs::canonicalize(&shown).unwrap_or(shown);
    Ok(Library {
        path,
        api,
        version: OnceLock::new(),
    })
}

/// A symbol's address as the function pointer type `F`.
///
/// # Safety
/// `F` must be the C function type of the symbol at `p`.
#[cfg(unix)]
unsafe fn fn_ptr<F: Copy>(p: *mut c_void) -> F {
    assert_eq!(std::mem::size_of::<F>(), std::mem::size_of::<*mut c_void>());
    // SAFETY: same size (checked), and the caller vouches for the type.
    unsafe { std::mem::transmute_copy(&p) }
}

#[cfg(not(unix))]
fn load(file: &Path, _shown: PathBuf) -> Result<Library, String> {
    Err(format!(
        "{}: loading OIDN at run time is implemented for Unix only",
        file.display()
    ))
}
