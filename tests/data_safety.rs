//! Never destroy what the user did not hand us: output folders that are
//! not ours, outputs that alias inputs, special files as inputs, sizes an
//! input cannot justify, a dump that shrinks while read, blessing that
//! stops half-way, names the batch needs, and files only their owner can
//! read. Every refusal is one line naming the file, with a non-zero exit.

mod common;

use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::*;
use pathdensity::dump::{DumpReader, Record};
use pathdensity::synth::SynthParams;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_pathdensity"))
}

/// Runs the binary with a deadline (a FIFO must never block it); returns
/// the exit code and stderr.
fn run(args: &[&str]) -> (Option<i32>, String) {
    let mut child = bin()
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        if start.elapsed() > Duration::from_secs(60) {
            child.kill().unwrap();
            panic!("{args:?} did not finish in 60 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Runs a command that must be refused: exit 1 (or `code`), one line that
/// names `names`, no panic.
fn refused(args: &[&str], names: &str) -> String {
    refused_with(args, names, 1)
}

fn refused_with(args: &[&str], names: &str, code: i32) -> String {
    let (got, err) = run(args);
    assert_eq!(got, Some(code), "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
    // A usage error is clap's: its line, then where help is.
    let err = match code {
        2 => err.lines().next().unwrap_or_default().to_string(),
        _ => err,
    };
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    assert!(
        err.contains(names),
        "{args:?}: {err:?} does not name {names}"
    );
    err
}

fn ok(args: &[&str]) {
    let (code, err) = run(args);
    assert_eq!(code, Some(0), "{args:?}: {err}");
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A small dump `name` in `dir`, and its mean as a reference `name_ref.exr`.
fn dump_and_reference(dir: &Path, name: &str) -> (PathBuf, PathBuf) {
    let p = SynthParams {
        width: 16,
        height: 16,
        spp: 4,
        ..SynthParams::default()
    };
    let dump = dir.join(format!("{name}.pds"));
    p.write(&dump).unwrap();
    let reference = dir.join(format!("{name}_ref.exr"));
    pathdensity::io::exr::write_frame(&reference, &synth_mean(&p), 0).unwrap();
    (dump, reference)
}

fn mkfifo(p: &Path) {
    let ok = Command::new("mkfifo").arg(p).status().unwrap().success();
    assert!(ok, "mkfifo");
}

fn bytes(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap()
}

#[test]
fn an_output_folder_that_holds_the_input_or_foreign_files_survives() {
    let dir = tempfile::tempdir().unwrap();
    let shot = dir.path().join("shot");
    std::fs::create_dir(&shot).unwrap();
    let (dump, _) = dump_and_reference(&shot, "d");
    let notes = shot.join("notes.txt");
    std::fs::write(&notes, "mine").unwrap();
    let before = bytes(&dump);
    // The folder of the dump, and its parent.
    refused(&["filter", s(&dump), "-o", s(&shot), "--no-html"], "shot");
    refused(
        &["filter", s(&dump), "-o", s(dir.path()), "--no-html"],
        "input",
    );
    assert_eq!(bytes(&dump), before);
    assert_eq!(bytes(&notes), b"mine");
    // A folder holding only a foreign file.
    let keep = dir.path().join("keep");
    std::fs::create_dir(&keep).unwrap();
    std::fs::write(keep.join("notes.txt"), "mine").unwrap();
    refused(
        &["filter", s(&dump), "-o", s(&keep), "--no-html"],
        "notes.txt",
    );
    assert_eq!(bytes(&keep.join("notes.txt")), b"mine");
    // A folder of ours is replaced; one a file was added to since is not.
    let out = dir.path().join("out");
    ok(&["filter", s(&dump), "-o", s(&out), "--no-html"]);
    ok(&["filter", s(&dump), "-o", s(&out), "--no-html"]);
    std::fs::write(out.join("added.txt"), "mine").unwrap();
    refused(
        &["filter", s(&dump), "-o", s(&out), "--no-html"],
        "added.txt",
    );
    assert!(out.join("added.txt").is_file() && out.join("report.json").is_file());
    // An empty folder is new.
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    ok(&["filter", s(&dump), "-o", s(&empty), "--no-html"]);
}

#[test]
fn sweep_and_demo_keep_foreign_folders() {
    let dir = tempfile::tempdir().unwrap();
    let (dump, reference) = dump_and_reference(dir.path(), "d");
    let keep = dir.path().join("keep");
    std::fs::create_dir(&keep).unwrap();
    std::fs::write(keep.join("notes.txt"), "mine").unwrap();
    let sweep = |out: &Path| {
        vec![
            "sweep".to_string(),
            s(&dump).into(),
            "--reference".into(),
            s(&reference).into(),
            "-o".into(),
            s(out).into(),
            "--k".into(),
            "5".into(),
            "--sigma-color".into(),
            "50".into(),
            "--sigma-image".into(),
            "3".into(),
        ]
    };
    let args = sweep(&keep);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    refused(&args, "notes.txt");
    let args = sweep(dir.path());
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    refused(&args, "input");
    assert_eq!(bytes(&keep.join("notes.txt")), b"mine");
    let demo = Command::new(env!("CARGO_BIN_EXE_demo"))
        .args(["-o", s(&keep), "--size", "8", "--reference-spp", "4"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&demo.stderr);
    assert!(!demo.status.success(), "{err}");
    assert!(
        err.contains("notes.txt") && err.trim_end().lines().count() == 1,
        "{err}"
    );
    assert_eq!(files(&keep), ["notes.txt"]);
}

fn files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn outputs_never_overwrite_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let (dump, reference) = dump_and_reference(dir.path(), "d");
    let (d, r) = (bytes(&dump), bytes(&reference));
    let out = dir.path().join("out");
    let filter = |decisions: &Path| {
        vec![
            "filter",
            s(&dump),
            "-o",
            s(&out),
            "--no-html",
            "--reference",
            s(&reference),
        ]
        .into_iter()
        .map(String::from)
        .chain(["--decisions".into(), s(decisions).into()])
        .collect::<Vec<String>>()
    };
    let link = dir.path().join("link.pds");
    std::os::unix::fs::symlink(&dump, &link).unwrap();
    for target in [&dump, &reference, &link] {
        let args = filter(target);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        refused(&args, "input");
    }
    // A file the user wrote is not a decisions file of ours.
    let notes = dir.path().join("notes.txt");
    std::fs::write(&notes, "mine").unwrap();
    let args = filter(&notes);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    refused(&args, "notes.txt");
    // A previous decisions file is.
    let dec = dir.path().join("dec.bin");
    for _ in 0..2 {
        let args = filter(&dec);
        ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    }
    assert_eq!(bytes(&dump), d);
    assert_eq!(bytes(&reference), r);
    assert_eq!(bytes(&notes), b"mine");
    // import -o naming its own input, or a file that is not a dump.
    refused(
        &["import", "images", s(&reference), "-o", s(&reference)],
        "input",
    );
    refused(
        &["import", "images", s(&reference), "-o", s(&notes)],
        "notes.txt",
    );
    assert_eq!(bytes(&reference), r);
    assert_eq!(bytes(&notes), b"mine");
}

/// `render --reference-out` replaces an EXR only if pathdensity wrote it: a
/// user's own image at that name survives.
#[test]
fn render_replaces_only_exrs_of_ours() {
    let dir = tempfile::tempdir().unwrap();
    let render = |reference: &Path| {
        Command::new(env!("CARGO_BIN_EXE_render"))
            .args(["--scene", "glossy-room", "--width", "4", "--height", "4"])
            .args(["--spp", "1", "--reference-spp", "1", "-o"])
            .arg(dir.path().join("d.pds"))
            .arg("--reference-out")
            .arg(reference)
            .output()
            .unwrap()
    };
    let ours = dir.path().join("ours.exr");
    for _ in 0..2 {
        let o = render(&ours);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    // The same file with its marker renamed: a valid EXR someone else wrote.
    let mut foreign = bytes(&ours);
    let at = foreign
        .windows(12)
        .position(|w| w == b"pathdensity\0")
        .expect("our EXR carries the marker");
    foreign[at..at + 11].copy_from_slice(b"othersoftwa");
    let theirs = dir.path().join("theirs.exr");
    std::fs::write(&theirs, &foreign).unwrap();
    let o = render(&theirs);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("theirs.exr") && err.contains("not written by pathdensity"),
        "{err}"
    );
    assert_eq!(bytes(&theirs), foreign);
}

#[test]
fn special_files_never_block_nor_grow_memory() {
    let dir = tempfile::tempdir().unwrap();
    let (dump, reference) = dump_and_reference(dir.path(), "d");
    let fifo = dir.path().join("f.pds");
    mkfifo(&fifo);
    let out = dir.path().join("out");
    refused(&["info", s(&fifo)], "FIFO");
    refused(&["filter", s(&fifo), "-o", s(&out)], "FIFO");
    refused(
        &["filter", s(&dump), "-o", s(&out), "--reference", s(&fifo)],
        "FIFO",
    );
    refused(&["import", "images", s(&fifo), "-o", s(&out)], "FIFO");
    refused(
        &[
            "import",
            "npy",
            s(&fifo),
            "--width",
            "4",
            "--height",
            "4",
            "-o",
            s(&out),
        ],
        "FIFO",
    );
    refused(&["import", "bcd", s(&fifo), "-o", s(&out)], "FIFO");
    for manifest in [s(&fifo), "/dev/zero"] {
        refused(
            &["batch", "--manifest", manifest, "-o", s(&out), "--no-html"],
            manifest,
        );
    }
    // A glob matching a FIFO fails that dump's row only.
    let batch = dir.path().join("batch");
    let glob = format!("{}/*.pds", dir.path().display());
    let (code, err) = run(&["batch", &glob, "-o", s(&batch), "--no-html"]);
    assert_eq!(code, Some(4), "{err}");
    assert!(batch.join("d").join("report.json").is_file());
    let _ = reference;
}

/// A one-pixel EXR whose header claims `w` × `h` pixels.
fn lying_exr(path: &Path, w: i32, h: i32) {
    let img = pathdensity::recon::Image::new(1, 1, 1);
    pathdensity::io::exr::write_frame(path, &img, 0).unwrap();
    let mut b = bytes(path);
    for attr in [&b"dataWindow\0box2i\0"[..], &b"displayWindow\0box2i\0"[..]] {
        let at = b.windows(attr.len()).position(|w| w == attr).unwrap() + attr.len() + 4;
        b[at + 8..at + 12].copy_from_slice(&(w - 1).to_le_bytes());
        b[at + 12..at + 16].copy_from_slice(&(h - 1).to_le_bytes());
    }
    std::fs::write(path, b).unwrap();
}

#[test]
fn sizes_an_input_cannot_justify_are_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let (dump, _) = dump_and_reference(dir.path(), "d");
    let huge = dir.path().join("d_ref.exr");
    lying_exr(&huge, 100_000, 100_000);
    let out = dir.path().join("out");
    refused(
        &["filter", s(&dump), "-o", s(&out), "--reference", s(&huge)],
        "d_ref.exr",
    );
    refused(
        &[
            "import",
            "images",
            s(&huge),
            "-o",
            s(&dir.path().join("i.pds")),
        ],
        "d_ref.exr",
    );
    let (code, err) = run(&[
        "batch",
        s(&dump),
        "--reference",
        "{dir}/{stem}_ref.exr",
        "-o",
        s(&dir.path().join("b")),
        "--no-html",
    ]);
    assert_eq!(code, Some(4), "{err}");
    assert!(!err.contains("panicked") && !err.contains("memory allocation"));
    // A tiny dump whose header claims a film no machine holds.
    let h = header(8192, 8192, 1024);
    let big = write_dump(dir.path(), "big.pds", &h, &[Record::default(); 16]);
    let err = refused(&["filter", s(&big), "-o", s(&out)], "big.pds");
    assert!(err.contains("GB"), "{err}");
    assert!(!out.exists());
    assert!(files(dir.path()).iter().all(|f| !f.contains("staging")));
    // Shards and threads.
    refused_with(
        &[
            "batch",
            s(&dump),
            "-o",
            s(&out),
            "--shard",
            "0/1000000000000",
        ],
        "shards",
        2,
    );
    refused_with(
        &[
            "batch",
            s(&dump),
            "-o",
            s(&out),
            "--shard",
            "0/18446744073709551615",
        ],
        "shards",
        2,
    );
    let (code, err) = run(&[
        "filter",
        s(&dump),
        "-o",
        s(&out),
        "--no-html",
        "--threads",
        "30000",
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("capped"), "{err}");
}

#[test]
fn a_dump_that_shrinks_while_read_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let p = SynthParams {
        width: 64,
        height: 64,
        spp: 16,
        ..SynthParams::default()
    };
    let path = dir.path().join("d.pds");
    p.write(&path).unwrap();
    let dump = DumpReader::open(&path).unwrap();
    assert!(dump.intact().is_ok());
    let n = dump.records().len();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .unwrap()
        .set_len(4096)
        .unwrap();
    // Reading past the new end raises SIGBUS: caught, read as zeros.
    let sum: f64 = dump.records().iter().map(|r| r.rgb()[0] as f64).sum();
    assert!(sum.is_finite());
    assert_eq!(dump.records().len(), n);
    let e = dump.intact().unwrap_err().to_string();
    assert!(e.contains("d.pds") && e.contains("shrank"), "{e}");
    drop(dump);
    // Another dump read afterwards is unaffected.
    let other = dir.path().join("e.pds");
    p.write(&other).unwrap();
    let dump = DumpReader::open(&other).unwrap();
    let _: f64 = dump.records().iter().map(|r| r.rgb()[1] as f64).sum();
    assert!(dump.intact().is_ok());
}

#[test]
fn bless_is_whole_per_fixture_and_says_which() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures");
    for name in ["synth-demo", "two-lights"] {
        let to = dir.path().join(name);
        std::fs::create_dir_all(to.join("expected")).unwrap();
        for e in std::fs::read_dir(root.join(name)).unwrap() {
            let e = e.unwrap();
            if e.file_type().unwrap().is_file() {
                std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
            }
        }
        for e in std::fs::read_dir(root.join(name).join("expected")).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), to.join("expected").join(e.file_name())).unwrap();
        }
    }
    // One fixture broken: its dump is gone.
    std::fs::remove_file(dir.path().join("synth-demo/dump.pds")).unwrap();
    let before = files(&dir.path().join("synth-demo/expected"));
    let out = bin()
        .args(["regress", s(dir.path()), "--bless"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(text.contains("synth-demo: NOT BLESSED"), "{text}");
    assert!(text.contains("two-lights: blessed"), "{text}");
    assert_eq!(files(&dir.path().join("synth-demo/expected")), before);
    let out = bin().args(["regress", s(dir.path())]).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("two-lights: ok"), "{text}");
}

#[test]
fn the_batch_keeps_its_own_names_and_other_folders() {
    let dir = tempfile::tempdir().unwrap();
    let shots = dir.path().join("shots");
    std::fs::create_dir(&shots).unwrap();
    let (a, _) = dump_and_reference(&shots, "a");
    let (summary, _) = dump_and_reference(&shots, "summary.csv");
    let out = dir.path().join("out");
    refused(&["batch", s(&a), s(&summary), "-o", s(&out)], "summary.csv");
    // An OUTDIR that is not ours is refused whole.
    let theirs = dir.path().join("theirs");
    std::fs::create_dir_all(theirs.join("a")).unwrap();
    refused(&["batch", s(&a), "-o", s(&theirs)], "theirs");
    // A dump's output folder (of ours) that now holds another dump fails
    // its row only.
    ok(&["batch", s(&a), "-o", s(&out), "--no-html"]);
    let nested = out.join("a");
    let (b, _) = dump_and_reference(&nested, "b");
    let (code, err) = run(&["batch", s(&a), s(&b), "-o", s(&out), "--no-html", "--force"]);
    assert_eq!(code, Some(4), "{err}");
    assert!(nested.join("b.pds").is_file());
    assert!(out.join("b").join("report.json").is_file());
    assert!(out.join("summary.csv").is_file());
}

#[test]
fn outputs_follow_the_umask() {
    let dir = tempfile::tempdir().unwrap();
    let (dump, _) = dump_and_reference(dir.path(), "d");
    let out = dir.path().join("out");
    let exe = env!("CARGO_BIN_EXE_pathdensity");
    for (umask, file, folder) in [("022", 0o644, 0o755), ("077", 0o600, 0o700)] {
        let status = Command::new("sh")
            .args([
                "-c",
                &format!(
                    "umask {umask} && '{exe}' filter '{}' -o '{}' --no-html --decisions '{}' >/dev/null",
                    s(&dump),
                    s(&out),
                    s(&dir.path().join("dec"))
                ),
            ])
            .status()
            .unwrap();
        assert!(status.success());
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&out.join("report.json")), file, "umask {umask}");
        assert_eq!(mode(&dir.path().join("dec")), file, "umask {umask}");
        assert_eq!(mode(&out), folder, "umask {umask}");
    }
}
