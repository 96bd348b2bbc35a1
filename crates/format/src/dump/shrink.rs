//! A dump truncated while it is mapped: reading past the new end raises
//! `SIGBUS`, which would kill the process with no message. While a dump
//! is mapped its address range is watched: a fault inside it maps zeroed
//! pages over the rest of the range, notes the dump as shrunk and lets the
//! reader go on, and [`super::DumpReader::intact`] then refuses the run's
//! results in one line. A fault anywhere else goes to the handler that was
//! there before (Rust's own, or the default: the process dies as before).
//!
//! Costs nothing while no fault happens: the replay reads the mapping as
//! it always did.

use std::sync::Once;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// One watched mapping; `start == 0` when free.
struct Slot {
    start: AtomicUsize,
    end: AtomicUsize,
    shrunk: AtomicBool,
}

/// How many dumps may be watched at once (more are mapped unwatched).
const SLOTS: usize = 64;

#[allow(clippy::declare_interior_mutable_const)]
const FREE: Slot = Slot {
    start: AtomicUsize::new(0),
    end: AtomicUsize::new(0),
    shrunk: AtomicBool::new(false),
};
static WATCHED: [Slot; SLOTS] = [FREE; SLOTS];
static PAGE: AtomicUsize = AtomicUsize::new(4096);
static INSTALL: Once = Once::new();

/// The handler that was installed before ours, called for faults that are
/// not ours. Written once, before our handler is installed.
static mut PREVIOUS: Option<libc::sigaction> = None;

/// A watched range; dropped before the mapping is unmapped.
pub(super) struct Watch(Option<usize>);

impl Watch {
    /// Watches `[start, start + len)`.
    pub(super) fn new(start: *const u8, len: usize) -> Watch {
        INSTALL.call_once(install);
        let start = start as usize;
        for (i, s) in WATCHED.iter().enumerate() {
            if s.start
                .compare_exchange(0, usize::MAX, Ordering::AcqRel, Ordering::Relaxed)
                .is_ok()
            {
                s.shrunk.store(false, Ordering::Release);
                s.end.store(start + len, Ordering::Release);
                s.start.store(start, Ordering::Release);
                return Watch(Some(i));
            }
        }
        Watch(None)
    }

    /// Whether a read past the file's end was caught in this range.
    pub(super) fn shrunk(&self) -> bool {
        self.0
            .is_some_and(|i| WATCHED[i].shrunk.load(Ordering::Acquire))
    }
}

impl Drop for Watch {
    fn drop(&mut self) {
        if let Some(i) = self.0 {
            WATCHED[i].end.store(0, Ordering::Release);
            WATCHED[i].start.store(0, Ordering::Release);
        }
    }
}

fn install() {
    // SAFETY: sysconf and sigaction with valid pointers; PREVIOUS is
    // written before the handler that reads it is installed.
    unsafe {
        let page = libc::sysconf(libc::_SC_PAGESIZE);
        if page > 0 {
            PAGE.store(page as usize, Ordering::Relaxed);
        }
        let mut old: libc::sigaction = std::mem::zeroed();
        if libc::sigaction(libc::SIGBUS, std::ptr::null(), &mut old) != 0 {
            return;
        }
        PREVIOUS = Some(old);
        let mut new: libc::sigaction = std::mem::zeroed();
        new.sa_sigaction = on_sigbus as *const () as usize;
        new.sa_flags = libc::SA_SIGINFO | libc::SA_ONSTACK;
        libc::sigemptyset(&mut new.sa_mask);
        libc::sigaction(libc::SIGBUS, &new, std::ptr::null_mut());
    }
}

extern "C" fn on_sigbus(sig: libc::c_int, info: *mut libc::siginfo_t, ctx: *mut libc::c_void) {
    // SAFETY: the kernel passes a valid siginfo_t; mmap and sigaction are
    // system calls, safe in a signal handler.
    unsafe {
        let addr = (*info).si_addr() as usize;
        for s in &WATCHED {
            let (start, end) = (
                s.start.load(Ordering::Acquire),
                s.end.load(Ordering::Acquire),
            );
            if start == 0 || start == usize::MAX || addr < start || addr >= end {
                continue;
            }
            // Zeroed pages from the fault to the end of the range: the
            // file shrank from its end, so everything after is gone too.
            let page = addr & !(PAGE.load(Ordering::Relaxed) - 1);
            let p = libc::mmap(
                page as *mut libc::c_void,
                end - page,
                libc::PROT_READ,
                libc::MAP_PRIVATE | libc::MAP_ANONYMOUS | libc::MAP_FIXED,
                -1,
                0,
            );
            if p != libc::MAP_FAILED {
                s.shrunk.store(true, Ordering::Release);
                return;
            }
        }
        // Not ours: whatever was there before decides.
        #[allow(static_mut_refs)]
        match PREVIOUS {
            Some(old) if old.sa_flags & libc::SA_SIGINFO != 0 && old.sa_sigaction > 1 => {
                let f: extern "C" fn(libc::c_int, *mut libc::siginfo_t, *mut libc::c_void) =
                    std::mem::transmute(old.sa_sigaction);
                f(sig, info, ctx);
            }
            Some(old) if old.sa_sigaction > 1 => {
                let f: extern "C" fn(libc::c_int) = std::mem::transmute(old.sa_sigaction);
                f(sig);
            }
            _ => {
                // The default action: reinstated, the fault repeats and
                // the process dies of SIGBUS as it would have.
                let mut dfl: libc::sigaction = std::mem::zeroed();
                dfl.sa_sigaction = libc::SIG_DFL;
                libc::sigaction(libc::SIGBUS, &dfl, std::ptr::null_mut());
            }
        }
    }
}
