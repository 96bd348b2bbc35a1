//! The Python module `pathdensity` (crates/python): its pytest tests
//! (`crates/python/tests/`) hold its decisions and images to this binary's
//! byte for byte, its dumps to the format crate's, and check its refusals,
//! its messages and that it releases the GIL.
//!
//! Needs tools/python/.venv (`bash tools/python/setup.sh` builds the module
//! into it); skipped loudly without it, or when the module is older than
//! the sources it is built from, unless `PATHDENSITY_REQUIRE_PYMODULE` is
//! set (CI sets it and runs the setup), which fails the test instead.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::SystemTime;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// Fails under `PATHDENSITY_REQUIRE_PYMODULE`, else says why it skips.
fn skip(why: &str) -> Option<PathBuf> {
    if std::env::var_os("PATHDENSITY_REQUIRE_PYMODULE").is_some() {
        panic!("{why}, and PATHDENSITY_REQUIRE_PYMODULE is set");
    }
    common::skipped(why);
    None
}

/// The newest modification time of the files under `dir`.
fn newest(dir: &Path) -> SystemTime {
    let mut t = SystemTime::UNIX_EPOCH;
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let p = e.path();
        let m = if p.is_dir() {
            newest(&p)
        } else {
            e.metadata()
                .and_then(|m| m.modified())
                .unwrap_or(SystemTime::UNIX_EPOCH)
        };
        t = t.max(m);
    }
    t
}

/// The venv's python, when it imports a module built after its sources.
fn python() -> Option<PathBuf> {
    let py = Path::new(ROOT).join("tools/python/.venv/bin/python");
    // The module's shared library, as the interpreter finds it.
    let found = Command::new(&py)
        .args([
            "-c",
            "import pathdensity, pytest; print(pathdensity.pathdensity.__file__)",
        ])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| PathBuf::from(String::from_utf8_lossy(&o.stdout).trim()));
    let Some(module) = found else {
        return skip("the Python module is not set up (bash tools/python/setup.sh)");
    };
    let built = std::fs::metadata(&module)
        .and_then(|m| m.modified())
        .unwrap_or(SystemTime::UNIX_EPOCH);
    let sources = ["crates/python", "crates/core", "crates/format"]
        .iter()
        .map(|d| newest(&Path::new(ROOT).join(d).join("src")))
        .max()
        .unwrap();
    if built < sources {
        return skip(&format!(
            "the Python module ({}) is older than its sources (rerun bash tools/python/setup.sh)",
            module.display()
        ));
    }
    Some(py)
}

/// Runs the module's pytest tests (those `-k` selects, if given) with
/// `envs`; asserts every one ran and passed.
fn pytest(py: &Path, select: Option<&str>, envs: &[(&str, &str)]) {
    let mut c = Command::new(py);
    c.args(["-m", "pytest", "-q", "-p", "no:cacheprovider"])
        .arg(Path::new(ROOT).join("crates/python/tests"))
        .env("PATHDENSITY_CLI", env!("CARGO_BIN_EXE_pathdensity"))
        .envs(envs.iter().copied());
    if let Some(k) = select {
        c.args(["-k", k]);
    }
    let out = c.output().expect("runs pytest");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "pytest failed:\n{text}");
    // pytest's last line: "N passed in S s", and nothing skipped or failed.
    let last = text.lines().rfind(|l| !l.trim().is_empty()).unwrap_or("");
    assert!(
        last.contains(" passed") && !last.contains("skipped") && !last.contains("failed"),
        "{text}"
    );
}

#[test]
fn the_python_modules_pytest_tests_pass() {
    let Some(py) = python() else { return };
    pytest(&py, None, &[]);
}

/// albedo= and normal= reach OIDN as the command's flags do, with the
/// pyoidn wheel's library found through `OIDN_DIR`.
#[test]
fn the_modules_albedo_and_normal_reach_oidn() {
    let Some(py) = python() else { return };
    let Some((_, oidn_dir)) = common::oidn() else {
        return;
    };
    pytest(
        &py,
        Some("albedo"),
        &[("OIDN_DIR", &oidn_dir), ("PATHDENSITY_EXPECT_OIDN", "1")],
    );
}
