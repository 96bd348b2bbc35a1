//! `pathdensity batch`: shards then `--merge` give one process's summary;
//! a killed batch resumes to the same outputs; a rerun with nothing
//! changed filters nothing; bad dumps fail their own rows; the farm
//! recipes of docs/farm.md run as written.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

use pathdensity::synth::SynthParams;

const BIN: &str = env!("CARGO_BIN_EXE_pathdensity");
const RENDER: &str = env!("CARGO_BIN_EXE_render");

fn run(args: &[&str]) -> Output {
    Command::new(BIN).args(args).output().unwrap()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Renders `scene` small, with a reference `{stem}_ref.exr` beside it.
fn render(dir: &Path, scene: &str, name: &str, frames: u32) {
    let out = dir.join(format!("{name}.pds"));
    let reference = dir.join(format!("{name}_ref.exr"));
    let o = Command::new(RENDER)
        .args([
            "--scene", scene, "--width", "32", "--height", "24", "--spp", "8",
        ])
        .args(["--frames", &frames.to_string(), "--reference-spp", "32"])
        .arg("--reference-out")
        .arg(&reference)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
}

/// Five rendered dumps with references (one an animation), one without a
/// reference, one truncated.
fn shots(dir: &Path) -> PathBuf {
    let shots = dir.join("shots");
    std::fs::create_dir_all(&shots).unwrap();
    for (scene, name) in [
        ("glossy-room", "a_glossy"),
        ("sky", "b_sky"),
        ("two-lights", "c_lights"),
        ("indirect-room", "d_indirect"),
    ] {
        render(&shots, scene, name, 1);
    }
    render(&shots, "moving", "e_moving", 3);
    render(&shots, "diffuse-room", "f_noref", 1);
    std::fs::remove_file(shots.join("f_noref_ref.exr")).unwrap();
    let whole = std::fs::read(shots.join("a_glossy.pds")).unwrap();
    std::fs::write(shots.join("g_cut.pds"), &whole[..whole.len() / 2]).unwrap();
    shots
}

/// Every EXR of every dump folder, by relative path.
fn images(out: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v = Vec::new();
    for d in std::fs::read_dir(out).unwrap() {
        let d = d.unwrap().path();
        if !d.is_dir() || d.file_name().unwrap().to_string_lossy().starts_with('.') {
            continue;
        }
        for f in std::fs::read_dir(&d).unwrap() {
            let f = f.unwrap().path();
            if f.extension().is_some_and(|e| e == "exr") {
                let rel = f.strip_prefix(out).unwrap().display().to_string();
                v.push((rel, std::fs::read(&f).unwrap()));
            }
        }
    }
    v.sort();
    v
}

#[test]
fn shards_then_merge_give_one_process_summary_and_bad_dumps_fail_their_rows() {
    let dir = tempfile::tempdir().unwrap();
    let shots = shots(dir.path());
    let pattern = format!("{}/*.pds", shots.display());
    let reference = "{dir}/{stem}_ref.exr";
    let one = dir.path().join("one");
    let o = run(&[
        "batch",
        &pattern,
        "-o",
        one.to_str().unwrap(),
        "--reference",
        reference,
        "--no-html",
    ]);
    assert_eq!(o.status.code(), Some(4), "{}{}", stdout(&o), stderr(&o));
    let text = stdout(&o);
    assert!(
        text.contains("7 dumps: 6 filtered, 0 skipped (up to date), 1 failed"),
        "{text}"
    );
    assert!(
        text.contains("g_cut: ") && text.contains("g_cut.pds: file size"),
        "{text}"
    );
    assert!(text.contains("f_noref: no metrics: no reference"), "{text}");

    // Two shards as two processes at once, into one folder, then merged.
    let two = dir.path().join("two");
    let shard = |i: usize| {
        Command::new(BIN)
            .args(["batch", &pattern, "-o", two.to_str().unwrap()])
            .args([
                "--reference",
                reference,
                "--no-html",
                "--shard",
                &format!("{i}/2"),
            ])
            .spawn()
            .unwrap()
    };
    let (mut s0, mut s1) = (shard(0), shard(1));
    let codes = [s0.wait().unwrap().code(), s1.wait().unwrap().code()];
    assert!(
        codes.contains(&Some(0)) && codes.contains(&Some(4)),
        "{codes:?}"
    );
    assert!(
        !two.join("summary.csv").exists(),
        "a shard writes no summary"
    );
    let m = run(&["batch", "--merge", two.to_str().unwrap()]);
    assert_eq!(m.status.code(), Some(4), "{}", stderr(&m));

    assert_eq!(
        common::deterministic_csv(&one),
        common::deterministic_csv(&two)
    );
    assert_eq!(images(&one), images(&two));
    let csv = std::fs::read_to_string(one.join("summary.csv")).unwrap();
    // Seven dumps, three more rows for the animation's frames.
    assert_eq!(csv.lines().count(), 1 + 7 + 3, "{csv}");
    let header = csv.lines().next().unwrap();
    for col in [
        "filtered.rms_display",
        "mean.energy",
        "filtered.temporal_rms_display",
        "filtered.flip",
        "mean.hdr_flip",
        "total_seconds",
    ] {
        assert!(header.split(',').any(|c| c == col), "{col} in {header}");
    }
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(one.join("summary.json")).unwrap()).unwrap();
    assert_eq!(
        (json["dumps"].as_u64(), json["failed"].as_u64()),
        (Some(7), Some(1))
    );
    let moving = &json["results"][4];
    assert_eq!(moving["name"], "e_moving");
    assert!(
        moving["metrics"]["filtered"]["temporal"]["rms_display"]
            .as_f64()
            .unwrap()
            > 0.0
    );
    assert!(moving["metrics"]["filtered"]["flip"].as_f64().unwrap() > 0.0);
    let html = std::fs::read_to_string(one.join("summary.html")).unwrap();
    assert!(html.contains("<svg") && html.contains("Temporal stability"));
    assert!(html.contains("<h2>FLIP of each image"), "the FLIP plot");

    // A merge before every shard is done, and one of mixed batches.
    let partial = dir.path().join("partial");
    let o = run(&[
        "batch",
        &pattern,
        "-o",
        partial.to_str().unwrap(),
        "--no-html",
        "--shard",
        "1/3",
    ]);
    assert!(
        o.status.code().is_some_and(|c| c == 0 || c == 4),
        "{}",
        stderr(&o)
    );
    let m = run(&["batch", "--merge", partial.to_str().unwrap()]);
    assert_eq!(m.status.code(), Some(1));
    assert!(
        stderr(&m).contains("shard(s) 0/3, 2/3 have not finished"),
        "{}",
        stderr(&m)
    );
}

#[test]
fn a_rerun_filters_only_what_changed() {
    let dir = tempfile::tempdir().unwrap();
    let shots = dir.path().join("shots");
    std::fs::create_dir_all(&shots).unwrap();
    for seed in 1..=3 {
        let p = SynthParams {
            width: 40,
            height: 30,
            spp: 8,
            seed,
            ..SynthParams::default()
        };
        p.write(&shots.join(format!("s{seed}.pds"))).unwrap();
    }
    let pattern = format!("{}/*.pds", shots.display());
    let out = dir.path().join("out");
    let batch = |extra: &[&str]| {
        let mut args = vec!["batch", &pattern, "-o", out.to_str().unwrap()];
        args.extend(extra);
        let o = run(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        stdout(&o)
    };
    assert!(batch(&[]).contains("3 filtered, 0 skipped"));
    let report = out.join("s2/report.json");
    let before = std::fs::read(&report).unwrap();
    assert!(
        batch(&[]).contains("0 filtered, 3 skipped"),
        "nothing changed"
    );
    assert_eq!(
        std::fs::read(&report).unwrap(),
        before,
        "a skipped dump is left alone"
    );

    // Another dump under the same name: only it is redone.
    let p = SynthParams {
        width: 40,
        height: 30,
        spp: 8,
        seed: 99,
        ..SynthParams::default()
    };
    p.write(&shots.join("s2.pds")).unwrap();
    assert!(batch(&[]).contains("1 filtered, 2 skipped"));
    // A missing output: redone.
    std::fs::remove_file(out.join("s3/filtered_energy.exr")).unwrap();
    assert!(batch(&[]).contains("1 filtered, 2 skipped"));
    // Another configuration, or --force: all redone.
    assert!(batch(&["--k", "7"]).contains("3 filtered, 0 skipped"));
    assert!(batch(&["--k", "7"]).contains("0 filtered, 3 skipped"));
    assert!(batch(&["--k", "7", "--force"]).contains("3 filtered, 0 skipped"));
    // A manifest line's override is that dump's configuration.
    let manifest = dir.path().join("list.txt");
    std::fs::write(
        &manifest,
        "# the three shots\nshots/s1.pds --k 7\nshots/s2.pds --k 7\nshots/s3.pds --k 9\n",
    )
    .unwrap();
    let o = run(&[
        "batch",
        "--manifest",
        manifest.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--k",
        "7",
    ]);
    assert!(
        stdout(&o).contains("1 filtered, 2 skipped"),
        "{}{}",
        stdout(&o),
        stderr(&o)
    );
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("s3/report.json")).unwrap()).unwrap();
    assert_eq!(r["config"]["k"], 9);
}

#[test]
fn a_killed_batch_resumes_to_the_outputs_of_an_uninterrupted_one() {
    let dir = tempfile::tempdir().unwrap();
    let shots = dir.path().join("shots");
    std::fs::create_dir_all(&shots).unwrap();
    for seed in 1..=8 {
        let p = SynthParams {
            width: 128,
            height: 96,
            spp: 16,
            seed,
            ..SynthParams::default()
        };
        p.write(&shots.join(format!("s{seed}.pds"))).unwrap();
    }
    let pattern = format!("{}/*.pds", shots.display());
    let whole = dir.path().join("whole");
    let o = run(&[
        "batch",
        &pattern,
        "-o",
        whole.to_str().unwrap(),
        "--no-html",
        "--threads",
        "1",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));

    let out = dir.path().join("out");
    let mut child = Command::new(BIN)
        .args([
            "batch",
            &pattern,
            "-o",
            out.to_str().unwrap(),
            "--no-html",
            "--threads",
            "1",
        ])
        .spawn()
        .unwrap();
    // Kill it once some dump is done and before all are.
    let t0 = Instant::now();
    while !out.join("s2/report.json").exists() && t0.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(5));
    }
    Command::new("kill")
        .args(["-KILL", &child.id().to_string()])
        .status()
        .unwrap();
    child.wait().unwrap();
    let done: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !n.starts_with('.'))
        .collect();
    assert!(done.len() < 8, "killed too late: {done:?}");
    // Every dump folder under its final name is complete.
    for d in &done {
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join(d).join("report.json")).unwrap())
                .unwrap();
        for f in report["outputs"].as_array().unwrap() {
            assert!(out.join(d).join(f.as_str().unwrap()).is_file(), "{d}/{f}");
        }
    }
    let o = run(&[
        "batch",
        &pattern,
        "-o",
        out.to_str().unwrap(),
        "--no-html",
        "--threads",
        "2",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains(&format!("{} skipped", done.len())), "{text}");
    assert_eq!(images(&out), images(&whole));
    assert_eq!(
        common::deterministic_csv(&out),
        common::deterministic_csv(&whole)
    );
}

#[test]
fn bad_batches_stop_with_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o_str = out.to_str().unwrap();
    let a = dir.path().join("a.pds");
    SynthParams {
        width: 8,
        height: 8,
        spp: 2,
        ..SynthParams::default()
    }
    .write(&a)
    .unwrap();
    std::fs::create_dir_all(dir.path().join("b")).unwrap();
    std::fs::copy(&a, dir.path().join("b/a.pds")).unwrap();
    let manifest = dir.path().join("m.txt");
    std::fs::write(&manifest, "a.pds\na.pds --sigma-colour 3\n").unwrap();
    let nowhere = format!("{}/*.nothing", dir.path().display());
    let cases: Vec<(Vec<String>, i32, &str)> = vec![
        (vec![nowhere], 1, "matches no file"),
        (vec![], 1, "no dump to filter"),
        (
            vec![
                a.display().to_string(),
                dir.path().join("b/a.pds").display().to_string(),
            ],
            1,
            "would both write OUTDIR/a",
        ),
        (
            vec!["--manifest".into(), manifest.display().to_string()],
            1,
            "m.txt:2: --sigma-colour is not an option",
        ),
        (
            vec![a.display().to_string(), "--shard".into(), "2/2".into()],
            2,
            "I/N",
        ),
        (
            vec![a.display().to_string(), "--k".into(), "0".into()],
            2,
            "--k ",
        ),
    ];
    for (args, code, says) in cases {
        let mut all = vec!["batch".to_string(), "-o".into(), o_str.into()];
        all.extend(args);
        let o = Command::new(BIN).args(&all).output().unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(code), "{all:?}: {err}");
        assert!(err.contains(says), "{all:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    // A hostile file among good ones fails its row only.
    let hostile = dir.path().join("h.pds");
    std::fs::write(&hostile, b"PDSAMPLE\xff\xff\xff\xff garbage").unwrap();
    let o = run(&[
        "batch",
        a.to_str().unwrap(),
        hostile.to_str().unwrap(),
        "-o",
        o_str,
        "--no-html",
    ]);
    assert_eq!(o.status.code(), Some(4), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("1 filtered, 0 skipped (up to date), 1 failed"),
        "{}",
        stdout(&o)
    );
    assert!(out.join("a/report.json").is_file() && !out.join("h").exists());
    let m = run(&["batch", "--merge", dir.path().to_str().unwrap()]);
    assert_eq!(m.status.code(), Some(1));
    assert!(
        stderr(&m).contains("no batch-shard-*.json"),
        "{}",
        stderr(&m)
    );
}

/// The Slurm array script as two array tasks (the variables Slurm sets,
/// counted from 1), and docs/farm.md's GNU parallel line: each gives one
/// process's summary.
#[test]
fn the_farm_recipes_run_as_documented() {
    let dir = tempfile::tempdir().unwrap();
    let shots = dir.path().join("shots");
    std::fs::create_dir_all(&shots).unwrap();
    for seed in 1..=5 {
        SynthParams {
            width: 24 + 8 * seed as u32,
            height: 24,
            spp: 4,
            seed,
            ..SynthParams::default()
        }
        .write(&shots.join(format!("s{seed}.pds")))
        .unwrap();
    }
    let pattern = format!("{}/*.pds", shots.display());
    let one = dir.path().join("one");
    assert!(
        run(&["batch", &pattern, "-o", one.to_str().unwrap(), "--no-html"])
            .status
            .success()
    );

    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let slurm = dir.path().join("slurm");
    let tasks: Vec<_> = (1..=2)
        .map(|id| {
            Command::new("bash")
                .arg(root.join("tools/farm/slurm_array.sh"))
                .args([&pattern, slurm.to_str().unwrap(), "--no-html"])
                .env("PATHDENSITY", BIN)
                .env("SLURM_ARRAY_TASK_ID", id.to_string())
                .env("SLURM_ARRAY_TASK_MIN", "1")
                .env("SLURM_ARRAY_TASK_COUNT", "2")
                .env("SLURM_CPUS_PER_TASK", "1")
                .spawn()
                .unwrap()
        })
        .collect();
    for mut t in tasks {
        assert!(t.wait().unwrap().success());
    }
    assert!(
        slurm.join("batch-shard-0-of-2.json").is_file()
            && slurm.join("batch-shard-1-of-2.json").is_file()
    );
    assert!(
        run(&["batch", "--merge", slurm.to_str().unwrap()])
            .status
            .success()
    );
    assert_eq!(
        common::deterministic_csv(&slurm),
        common::deterministic_csv(&one)
    );

    let has_parallel = Command::new("parallel")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_parallel {
        common::skipped(
            "GNU parallel is not installed: docs/farm.md's parallel line not run (.ci/run installs it)",
        );
        assert!(
            std::env::var_os("PATHDENSITY_REQUIRE_PARALLEL").is_none(),
            "PATHDENSITY_REQUIRE_PARALLEL is set"
        );
        return;
    }
    let doc = std::fs::read_to_string(root.join("docs/farm.md")).unwrap();
    let line = doc
        .lines()
        .find(|l| l.starts_with("parallel "))
        .expect("a parallel line in docs/farm.md");
    let par = dir.path().join("par");
    let bin_dir = Path::new(BIN).parent().unwrap();
    let path = format!(
        "{}:{}",
        bin_dir.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let o = Command::new("bash")
        .args(["-c", line])
        .env("PATH", path)
        .env("DUMPS", &pattern)
        .env("OUT", &par)
        .env("N", "3")
        .env("T", "1")
        .output()
        .unwrap();
    assert!(o.status.success(), "{line}: {}", stderr(&o));
    assert_eq!(
        common::deterministic_csv(&par),
        common::deterministic_csv(&one)
    );
}
