//! Nothing is lost: a `filter` or `render` killed mid-run (SIGKILL, SIGINT)
//! leaves no partial file under a final name, and the previous outputs in
//! OUTDIR stay readable. Also: special files are refused as dumps.

mod common;

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use pathdensity::dump::DumpReader;
use pathdensity::io::exr::{self, read_rgb};
use pathdensity::synth::SynthParams;

/// Every file under a final name in `dir` is complete: images decode,
/// JSON parses. Temporary files (`.NAME.XXXXXX.tmp`) are ignored.
fn every_final_file_is_complete(dir: &Path) -> usize {
    let mut n = 0;
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        if name.starts_with('.') {
            continue;
        }
        match p.extension().and_then(|x| x.to_str()) {
            Some("exr") => {
                read_rgb(&p, exr::MAX_PIXELS).unwrap_or_else(|e| panic!("{name}: {e:#}"));
            }
            Some("png") => {
                image::open(&p).unwrap_or_else(|e| panic!("{name}: {e}"));
            }
            Some("json") => {
                let t = std::fs::read_to_string(&p).unwrap();
                serde_json::from_str::<serde_json::Value>(&t)
                    .unwrap_or_else(|e| panic!("{name}: {e}"));
            }
            Some("html") | Some("svg") => {
                let t = std::fs::read_to_string(&p).unwrap();
                assert!(t.trim_end().ends_with('>'), "{name} is cut short");
            }
            _ => {}
        }
        n += 1;
    }
    n
}

fn kill(child: &mut std::process::Child, signal: &str) {
    Command::new("kill")
        .args([signal, &child.id().to_string()])
        .status()
        .unwrap();
    let _ = child.wait();
}

#[test]
fn a_killed_filter_leaves_complete_files_and_the_previous_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let small = dir.path().join("small.pds");
    SynthParams {
        width: 32,
        height: 32,
        spp: 8,
        ..SynthParams::default()
    }
    .write(&small)
    .unwrap();
    let bin = env!("CARGO_BIN_EXE_pathdensity");
    let filter_small = || {
        let ok = Command::new(bin)
            .args([
                "filter",
                small.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
                "--methods",
                "all",
            ])
            .output()
            .unwrap();
        assert!(ok.status.success());
    };
    filter_small();
    let before = every_final_file_is_complete(&out);
    assert!(before >= 19);

    let big = dir.path().join("big.pds");
    SynthParams::default().write(&big).unwrap();
    let dump_of = |out: &Path| -> String {
        let t = std::fs::read_to_string(out.join("report.json")).unwrap();
        let v: serde_json::Value = serde_json::from_str(&t).unwrap();
        v["dump"].as_str().unwrap().to_string()
    };
    // Fixed points, then pseudo-random ones (seeded: the same every run)
    // up to past the run's end: the folder is the previous run, whole, or
    // the new one, whole — never a mix.
    let mut rng = common::Rng(7);
    let random = (0..6).map(|i| {
        let signal = ["-KILL", "-INT", "-TERM"][i % 3];
        (signal, 100 + (rng.f32() * 4500.0) as u64)
    });
    let fixed = [
        ("-KILL", 300),
        ("-INT", 900),
        ("-KILL", 1600),
        ("-KILL", 2600),
    ];
    for (signal, ms) in fixed.into_iter().chain(random) {
        let mut child = Command::new(bin)
            .args(["filter", big.to_str().unwrap(), "-o", out.to_str().unwrap()])
            .args(["--methods", "all"])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(ms));
        kill(&mut child, signal);
        let n = every_final_file_is_complete(&out);
        let made_from = dump_of(&out);
        if made_from == small.to_str().unwrap() {
            assert_eq!(
                n, before,
                "after {signal} at {ms} ms: the previous run, whole"
            );
        } else {
            // The new run had swapped in before the signal: whole too,
            // every file its report lists and nothing else.
            assert_eq!(made_from, big.to_str().unwrap());
            let t = std::fs::read_to_string(out.join("report.json")).unwrap();
            let listed = serde_json::from_str::<serde_json::Value>(&t).unwrap()["outputs"]
                .as_array()
                .unwrap()
                .len();
            assert_eq!(n, listed, "after {signal} at {ms} ms: {n} files");
            // Start over from the small run for the next point.
            filter_small();
        }
        // Nothing hidden beside OUTDIR but a SIGKILLed run's staging
        // folder (SIGKILL cannot be caught), cleared here for the next point.
        for e in std::fs::read_dir(dir.path()).unwrap() {
            let e = e.unwrap();
            let name = e.file_name().to_string_lossy().into_owned();
            if name.starts_with('.') {
                assert_eq!(
                    signal, "-KILL",
                    "after {signal} at {ms} ms: {name} left behind"
                );
                std::fs::remove_dir_all(e.path()).unwrap();
            }
        }
    }
}

/// SIGINT and SIGTERM (Ctrl-C, a scheduler's pre-emption) leave no
/// temporary file or staging folder behind, for `filter` and `synth`, and
/// exit with 130.
#[test]
fn an_interrupted_run_leaves_no_temporaries() {
    let dir = tempfile::tempdir().unwrap();
    let bin = env!("CARGO_BIN_EXE_pathdensity");
    let big = dir.path().join("big.pds");
    SynthParams::default().write(&big).unwrap();
    let runs: [(&str, Vec<String>); 2] = [
        (
            "-INT",
            vec![
                "filter".into(),
                big.to_str().unwrap().into(),
                "-o".into(),
                "out".into(),
            ],
        ),
        (
            "-TERM",
            vec![
                "synth".into(),
                "-o".into(),
                "s.pds".into(),
                "--width".into(),
                "1024".into(),
            ],
        ),
    ];
    for (signal, args) in runs {
        let mut child = Command::new(bin)
            .args(&args)
            .current_dir(dir.path())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(600));
        Command::new("kill")
            .args([signal, &child.id().to_string()])
            .status()
            .unwrap();
        let status = child.wait().unwrap();
        assert_eq!(status.code(), Some(130), "{args:?} after {signal}");
        let mut left: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(left, ["big.pds"], "{args:?} after {signal}");
    }
}

#[test]
fn a_killed_render_leaves_no_dump_under_its_final_name() {
    let dir = tempfile::tempdir().unwrap();
    let dump = dir.path().join("r.pds");
    let render = env!("CARGO_BIN_EXE_render");
    let mut child = Command::new(render)
        .args([
            "--scene",
            "glossy-room",
            "--width",
            "512",
            "--height",
            "512",
        ])
        .args(["--spp", "256", "-o", dump.to_str().unwrap()])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(700));
    kill(&mut child, "-KILL");
    assert!(!dump.exists(), "a partial dump under the final name");
}

#[test]
fn special_files_are_refused_as_dumps() {
    for p in ["/dev/zero", "/dev/null"] {
        if Path::new(p).exists() {
            let e = DumpReader::open(p).err().unwrap().to_string();
            assert!(e.contains(p) && e.contains("not a regular file"), "{e}");
        }
    }
}
