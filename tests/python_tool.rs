//! tools/pds.py reads what the library writes and writes what it reads,
//! and replaces nothing but a dump; the exporters' shared output check
//! (tools/exporter.py) refuses what would destroy a user's file.

mod common;

use std::os::unix::fs::PermissionsExt;
use std::path::Path;
use std::process::Command;

use common::*;
use pathdensity::dump::{DumpReader, Record};

#[test]
fn the_python_module_round_trips_dumps_with_the_library() {
    if !numpy_or_skip() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let mut h = header(5, 4, 2);
    h.scene = "héllo".into();
    h.seed = 42;
    let recs: Vec<Record> = (0..50)
        .map(|i| Record::new(i as f32 * 0.1, 3.5, 1.25, [i as f32, -2.0, 1e-30]))
        .collect();
    let a = write_dump(dir.path(), "a.pds", &h, &recs);
    let b = dir.path().join("b.pds");
    let script = format!(
        "import sys; sys.path.insert(0, 'tools'); import pds\n\
         h, r = pds.read({a:?})\n\
         assert h['scene'] == 'héllo' and h['seed'] == 42 and h['frames'] == 2, h\n\
         assert len(r) == 50 and float(r['x'][10]) == float(__import__('numpy').float32(1.0)), r[10]\n\
         pds.write({b:?}, r, width=5, height=4, frames=2, scene='héllo', seed=42, producer='tests')\n"
    );
    let st = Command::new("python3")
        .args(["-c", &script])
        .status()
        .unwrap();
    assert!(st.success());
    let d = DumpReader::open(&b).unwrap();
    assert_eq!(d.records(), &recs[..]);
    h.sample_count = 50;
    assert_eq!(d.header(), &h);
    // Byte for byte the same file as the library's writer.
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
}

/// Runs `script` in python3 with `tools/` on its path and `args` as
/// `sys.argv[1:]`; its stdout, after asserting it succeeded. An alarm ends
/// it if a check blocks (on a FIFO, say) instead of refusing.
fn python(script: &str, args: &[&Path]) -> String {
    let prelude = "import signal, sys; signal.alarm(60); sys.path.insert(0, 'tools')\n";
    let o = Command::new("python3")
        .arg("-c")
        .arg(format!("{prelude}{script}"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8(o.stdout).unwrap()
}

/// Whether python3 has numpy; says loudly that the test skips when not.
fn numpy_or_skip() -> bool {
    let found = python_with_numpy();
    if !found {
        common::skipped("python3 with numpy is not installed (.ci/run installs it)");
    }
    found
}

fn mkfifo(path: &Path) {
    let ok = Command::new("mkfifo").arg(path).status().unwrap().success();
    assert!(ok, "mkfifo");
}

#[test]
fn the_python_writer_replaces_a_previous_dump_and_nothing_else() {
    if !numpy_or_skip() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let notes = dir.path().join("notes.pds");
    std::fs::write(&notes, b"keep me\n").unwrap();
    let folder = dir.path().join("folder.pds");
    std::fs::create_dir(&folder).unwrap();
    let fifo = dir.path().join("pipe.pds");
    mkfifo(&fifo);
    let refused = python(
        "import numpy as np, pds\n\
         for path in sys.argv[1:]:\n\
         \x20   try:\n\
         \x20       pds.write(path, np.zeros((4, 6)), width=2, height=2)\n\
         \x20   except pds.RefusedError as e:\n\
         \x20       print(e)\n\
         \x20   else:\n\
         \x20       print(path, 'written')\n",
        &[&notes, &folder, &fifo],
    );
    let lines: Vec<&str> = refused.lines().collect();
    assert_eq!(lines.len(), 3, "{refused}");
    for (line, (path, what)) in lines.iter().zip([
        (&notes, "is not a dump"),
        (&folder, "is a directory"),
        (&fifo, "is a FIFO"),
    ]) {
        assert!(
            line.starts_with(&format!("{}: ", path.display())) && line.contains(what),
            "{line}"
        );
    }
    assert_eq!(std::fs::read(&notes).unwrap(), b"keep me\n");
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 3, "a temporary was left: {names:?}");

    // A previous dump, even the library's, is replaced.
    let h = header(2, 2, 1);
    let old = write_dump(
        dir.path(),
        "old.pds",
        &h,
        &[Record::new(0.5, 0.5, 0.0, [1.0; 3])],
    );
    python(
        "import numpy as np, pds\n\
         pds.write(sys.argv[1], np.full((4, 6), 0.25), width=2, height=2)\n",
        &[&old],
    );
    let d = DumpReader::open(&old).unwrap();
    assert_eq!(d.header().sample_count, 4);
    assert!(d.records().iter().all(|r| r.rgb() == [0.25; 3]));
    // With an ordinary file's mode (what Rust's own write gives), not the
    // private one of a temporary.
    let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode(&old), mode(&notes));

    // A link is refused even when it names a dump: the rename would
    // replace the link, not the dump.
    let link = dir.path().join("link.pds");
    std::os::unix::fs::symlink(&old, &link).unwrap();
    let said = python(
        "import numpy as np, pds\n\
         try:\n\
         \x20   pds.write(sys.argv[1], np.zeros((4, 6)), width=2, height=2)\n\
         except pds.RefusedError as e:\n\
         \x20   print(e)\n",
        &[&link],
    );
    assert!(said.starts_with(&format!("{}: ", link.display())), "{said}");
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert!(
        DumpReader::open(&old)
            .unwrap()
            .records()
            .iter()
            .all(|r| r.rgb() == [0.25; 3])
    );
}

#[test]
fn the_exporters_refuse_an_output_that_is_an_input_another_output_or_not_theirs() {
    if !numpy_or_skip() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name);
    std::fs::write(p("scene.xml"), b"<scene/>").unwrap();
    std::os::unix::fs::symlink(p("scene.xml"), p("soft.pds")).unwrap();
    std::fs::hard_link(p("scene.xml"), p("hard.pds")).unwrap();
    // A dangling link to another output's name: one file once written.
    std::os::unix::fs::symlink(p("a.exr"), p("alias.exr")).unwrap();
    std::fs::write(p("notes.exr"), b"keep me").unwrap();
    // A valid EXR that another program wrote (no `pathdensity` attribute),
    // and one of ours, which may be replaced.
    python(
        "import numpy as np, exrio\n\
         exrio.write_rgb(sys.argv[2], np.zeros((2, 2, 3)))\n\
         exrio.WRITER_ATTRIBUTE = 'software'\n\
         exrio.write_rgb(sys.argv[1], np.zeros((2, 2, 3)))\n",
        &[&p("theirs.exr"), &p("ours.exr")],
    );
    let theirs = std::fs::read(p("theirs.exr")).unwrap();
    mkfifo(&p("pipe.exr"));
    // Each case: the outputs (dump, then EXRs), and what the refusal says.
    let cases: [(&[&str], &str); 9] = [
        (&["scene.xml"], "scene.xml: is an input"),
        (&["soft.pds"], "soft.pds: is the same file as the input"),
        (&["hard.pds"], "hard.pds: is the same file as the input"),
        (&["a.pds", "a.pds"], "a.pds: is named by two outputs"),
        (
            &["b.pds", "a.exr", "alias.exr"],
            "alias.exr: is the same file as the output",
        ),
        (
            &["b.pds", "notes.exr"],
            "notes.exr: exists and is not an EXR",
        ),
        (
            &["b.pds", "theirs.exr"],
            "theirs.exr: exists and is not an EXR pathdensity wrote",
        ),
        (&["b.pds", "pipe.exr"], "pipe.exr: is a FIFO"),
        // Found before a render, not when writing after it.
        (&["nodir/b.pds"], "nodir/b.pds: its folder"),
    ];
    let script = "from exporter import ExportError, check_outputs\n\
         out = sys.argv[2:]\n\
         try:\n\
         \x20   check_outputs([sys.argv[1]], [(out[0], 'dump')] + [(p, 'exr') for p in out[1:]])\n\
         except ExportError as e:\n\
         \x20   print(e)\n";
    for (outputs, expected) in cases {
        let mut args = vec![p("scene.xml")];
        args.extend(outputs.iter().map(|o| p(o)));
        let refs: Vec<&Path> = args.iter().map(|a| a.as_path()).collect();
        let said = python(script, &refs);
        let want = format!("{}/{expected}", dir.path().display());
        assert!(said.starts_with(&want), "{outputs:?}: {said:?}");
    }
    assert_eq!(std::fs::read(p("scene.xml")).unwrap(), b"<scene/>");
    assert_eq!(std::fs::read(p("notes.exr")).unwrap(), b"keep me");
    assert_eq!(std::fs::read(p("theirs.exr")).unwrap(), theirs);
    let said = python(script, &[&p("scene.xml"), &p("b.pds"), &p("ours.exr")]);
    assert_eq!(said, "", "a previous EXR of ours is replaced");

    // The Cycles exporter refuses before it needs Blender.
    let o = Command::new("python3")
        .arg("tools/cycles/export.py")
        .arg("builtin:caustic")
        .arg("-o")
        .arg(p("c.pds"))
        .args(["--spp", "1", "--reference-spp", "1", "--reference-out"])
        .arg(p("f.exr"))
        .arg("--film-out")
        .arg(p("f.exr"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("f.exr: is named by two outputs"), "{err}");
}
