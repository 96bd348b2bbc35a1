//! What the binaries share: the progress bar they draw on a terminal
//! (hidden otherwise).

use std::io::IsTerminal;

use crate::progress::Progress;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

pub struct Bar(ProgressBar);

impl Bar {
    pub fn new(what: &str) -> Bar {
        if !std::io::stderr().is_terminal() {
            return Bar(ProgressBar::with_draw_target(
                None,
                ProgressDrawTarget::hidden(),
            ));
        }
        let pb = ProgressBar::new(0);
        pb.set_style(
            ProgressStyle::with_template("{msg:>10} [{bar:40}] {pos}/{len} ({per_sec}, eta {eta})")
                .expect("static template")
                .progress_chars("=> "),
        );
        pb.set_message(what.to_string());
        Bar(pb)
    }
}

impl Bar {
    /// A batch's bar: samples of its dumps, with dumps done, skipped and
    /// failed beside it.
    pub fn batch() -> Bar {
        let bar = Bar::new("");
        bar.0.set_style(
            ProgressStyle::with_template(
                "{msg} [{bar:30}] {human_pos}/{human_len} samples ({per_sec}, eta {eta})",
            )
            .expect("static template")
            .progress_chars("=> "),
        );
        bar
    }
}

impl Progress for Bar {
    fn set_length(&self, len: u64) {
        self.0.set_length(len);
    }
    fn inc(&self, n: u64) {
        self.0.inc(n);
    }
    fn message(&self, msg: &str) {
        self.0.set_message(msg.to_string());
    }
    fn finish(&self) {
        self.0.disable_steady_tick();
        self.0.finish_and_clear();
    }
    /// A stage of few long steps (the images): its elapsed time ticks
    /// between them.
    fn stage(&self, what: &str, len: u64) {
        self.0.set_message(what.to_string());
        self.0.reset();
        self.0.set_style(
            ProgressStyle::with_template("{msg:>10} [{bar:40}] {pos}/{len} ({elapsed})")
                .expect("static template")
                .progress_chars("=> "),
        );
        self.0.set_length(len);
        self.0
            .enable_steady_tick(std::time::Duration::from_millis(250));
    }
}

/// `--threads N`: 0 for one a core; more than [`par::max_threads`] is
/// capped there, with a note on stderr.
///
/// [`par::max_threads`]: pathdensity_core::par::max_threads
pub fn threads(s: &str) -> Result<usize, String> {
    let n: usize = s
        .parse()
        .map_err(|_| format!("expected a thread count, got {s:?}"))?;
    let max = pathdensity_core::par::max_threads();
    if n > max {
        eprintln!("note: --threads {n} capped at {max} (four a core, at least 64)");
        return Ok(max);
    }
    Ok(n)
}

/// On SIGINT or SIGTERM (Ctrl-C, a scheduler's pre-emption), removes every
/// temporary file and staging folder of this process and exits with 130:
/// an interrupted run leaves its outputs as they were and nothing hidden
/// behind. (SIGKILL cannot be caught: it may leave a temporary behind.)
pub fn clean_up_on_signals() {
    let _ = ctrlc::set_handler(|| {
        crate::io::atomic::remove_temporaries();
        std::process::exit(130);
    });
}

/// A binary's `main` around its job: temporaries removed on signals, an
/// error printed as one line `NAME: …` with exit code 1.
pub fn run_main(name: &str, job: impl FnOnce() -> anyhow::Result<()>) -> std::process::ExitCode {
    clean_up_on_signals();
    match job() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{name}: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
