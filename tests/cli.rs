//! The `pathdensity` binary end to end: outputs, bit-identical results for
//! any thread count, and bad input reported as one clear line.

mod common;

use std::path::Path;
use std::process::Command;

use common::*;
use pathdensity::config::MethodSet;
use pathdensity::dump::Record;
use pathdensity::synth::SynthParams;

/// What a default `filter --sigma-map` writes, sorted: each default
/// method's EXR and PNG, the removed energy, the σ map, the slice plot,
/// the reports and the folder's marker.
fn default_outputs() -> Vec<String> {
    let mut names: Vec<String> = MethodSet::default_here()
        .iter()
        .map(|m| m.name())
        .chain(["rejected", "sigma"])
        .flat_map(|n| [format!("{n}.exr"), format!("{n}.png")])
        .chain(
            [
                ".pathdensity-output",
                "report.html",
                "report.json",
                "slice.svg",
            ]
            .map(String::from),
        )
        .collect();
    names.sort();
    names
}

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_pathdensity"))
}

fn run_ok(args: &[&str]) -> String {
    let out = bin().args(args).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{args:?} failed: {err}");
    String::from_utf8(out.stdout).unwrap()
}

/// Runs a command expected to fail; returns its stderr.
fn run_err(args: &[&str]) -> String {
    run_err_code(args).1
}

/// Runs a command expected to fail; returns its exit code and stderr.
fn run_err_code(args: &[&str]) -> (Option<i32>, String) {
    let out = bin().args(args).output().unwrap();
    assert!(!out.status.success(), "{args:?} should fail");
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    (out.status.code(), err)
}

fn files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .map(|rd| {
            rd.map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

fn report(out_dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(out_dir.join("report.json")).unwrap()).unwrap()
}

fn synth(dir: &Path, name: &str, p: &SynthParams) -> String {
    let path = dir.join(name);
    p.write(&path).unwrap();
    path.to_str().unwrap().to_string()
}

#[test]
fn filter_writes_images_decisions_and_a_report() {
    let dir = tempfile::tempdir().unwrap();
    let p = SynthParams {
        width: 24,
        height: 16,
        spp: 8,
        ..SynthParams::default()
    };
    let dump = synth(dir.path(), "d.pds", &p);
    let out = dir.path().join("out");
    let dec = dir.path().join("dec.bin");
    let stdout = run_ok(&[
        "filter",
        &dump,
        "-o",
        out.to_str().unwrap(),
        "--decisions",
        dec.to_str().unwrap(),
        "--sigma-map",
    ]);
    assert!(stdout.contains("accepted streaming"));
    assert_eq!(files(&out), default_outputs());
    let rep = report(&out);
    let c = &rep["counts"];
    let n = |k: &str| c[k].as_u64().unwrap();
    assert_eq!(n("records"), p.sample_count());
    assert_eq!(
        n("accepted_streaming") + n("accepted_final") + n("rejected"),
        n("valid")
    );
    let decisions = std::fs::read(&dec).unwrap();
    assert_eq!(decisions.len() as u64, p.sample_count());
    assert_eq!(
        decisions.iter().filter(|&&d| d == REJECTED).count() as u64,
        n("rejected")
    );
    assert_eq!(
        decisions.iter().filter(|&&d| d == FINAL).count() as u64,
        n("accepted_final")
    );
}

#[test]
fn every_output_is_bit_identical_for_1_2_and_8_threads() {
    let dir = tempfile::tempdir().unwrap();
    let p = SynthParams {
        width: 48,
        height: 32,
        spp: 16,
        firefly_fraction: 0.02,
        order: pathdensity::dump::Order::PassMajor,
        ..SynthParams::default()
    };
    let dump = synth(dir.path(), "d.pds", &p);
    let outputs: Vec<Vec<Vec<u8>>> = [1, 2, 8]
        .iter()
        .map(|t| {
            let out = dir.path().join(format!("out{t}"));
            let dec = dir.path().join(format!("dec{t}"));
            run_ok(&[
                "filter",
                &dump,
                "-o",
                out.to_str().unwrap(),
                "--threads",
                &t.to_string(),
                "--sigma-map",
                "--decisions",
                dec.to_str().unwrap(),
            ]);
            // Every image, preview and plot; the reports hold wall times,
            // so only their counts and metrics are compared.
            let names: Vec<String> = files(&out)
                .into_iter()
                .filter(|f| !f.starts_with("report."))
                .collect();
            assert_eq!(names.len(), default_outputs().len() - 2);
            let mut v: Vec<Vec<u8>> = names
                .iter()
                .map(|f| std::fs::read(out.join(f)).unwrap())
                .collect();
            v.push(std::fs::read(dec).unwrap());
            let r = report(&out);
            v.push(r["counts"].to_string().into_bytes());
            v.push(r["metrics"].to_string().into_bytes());
            v
        })
        .collect();
    assert!(outputs[0] == outputs[1] && outputs[1] == outputs[2]);
}

/// At 64 spp the report's σ map is the mean over one sample in 32 of each
/// pixel's (exact σ, the same samples for any thread count) and no
/// sigma.exr is written.
#[test]
fn the_reports_sigma_map_estimate_is_the_same_for_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let p = SynthParams {
        width: 24,
        height: 16,
        spp: 64,
        firefly_fraction: 0.02,
        order: pathdensity::dump::Order::PassMajor,
        ..SynthParams::default()
    };
    let dump = synth(dir.path(), "d.pds", &p);
    let maps: Vec<Vec<u8>> = [1, 2]
        .iter()
        .map(|t| {
            let out = dir.path().join(format!("out{t}"));
            run_ok(&[
                "filter",
                &dump,
                "-o",
                out.to_str().unwrap(),
                "--threads",
                &t.to_string(),
            ]);
            assert!(
                !out.join("sigma.exr").exists(),
                "sigma.exr is exact or absent"
            );
            let r = report(&out);
            assert_eq!(r["sigma_map_one_in"], 32);
            assert_eq!(r["sigma_map_each_pixel"], true);
            std::fs::read(out.join("sigma.png")).unwrap()
        })
        .collect();
    assert_eq!(maps[0], maps[1]);
    let html = std::fs::read_to_string(dir.path().join("out1/report.html")).unwrap();
    assert!(html.contains("Estimated from one sample in 32 of each pixel's"));
}

#[test]
fn an_animation_writes_every_image_per_frame() {
    let dir = tempfile::tempdir().unwrap();
    let p = SynthParams {
        width: 8,
        height: 8,
        frames: 3,
        spp: 4,
        ..SynthParams::default()
    };
    let dump = synth(dir.path(), "a.pds", &p);
    let out = dir.path().join("out");
    let o = out.to_str().unwrap();
    run_ok(&[
        "filter",
        &dump,
        "-o",
        o,
        "--methods",
        "trimmed",
        "--no-html",
    ]);
    let mut expected: Vec<String> = ["filtered", "mean", "rejected", "trimmed"]
        .iter()
        .flat_map(|n| (0..3).map(move |f| format!("{n}_{f:04}.exr")))
        .collect();
    expected.push("report.json".into());
    expected.push(".pathdensity-output".into());
    expected.sort();
    assert_eq!(files(&out), expected);
}

#[test]
fn the_mean_against_itself_as_reference_has_zero_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = SynthParams {
        width: 16,
        height: 16,
        spp: 8,
        ..SynthParams::default()
    };
    let dump = synth(dir.path(), "d.pds", &p);
    let a = dir.path().join("a");
    run_ok(&["filter", &dump, "-o", a.to_str().unwrap()]);
    let b = dir.path().join("b");
    let r = a.join("mean.exr");
    run_ok(&[
        "filter",
        &dump,
        "-o",
        b.to_str().unwrap(),
        "--reference",
        r.to_str().unwrap(),
    ]);
    let rep = report(&b);
    assert_eq!(rep["metrics"]["mean"]["rms"].as_f64().unwrap(), 0.0);
    assert_eq!(
        rep["metrics"]["mean"]["energy_ratio"].as_f64().unwrap(),
        1.0
    );
    assert!(rep["metrics"]["filtered"]["rms"].as_f64().unwrap() > 0.0);
}

#[test]
fn bad_input_is_one_line_naming_the_file_and_leaves_no_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = out.to_str().unwrap();
    let missing = dir.path().join("missing.pds");
    let (code, e) = run_err_code(&["filter", missing.to_str().unwrap(), "-o", o]);
    assert!(e.contains("missing.pds"), "{e}");
    assert_eq!(code, Some(1), "bad input exits 1");

    let junk = dir.path().join("junk.pds");
    std::fs::write(&junk, b"PDSDUMP2 and then some bytes").unwrap();
    let e = run_err(&["filter", junk.to_str().unwrap(), "-o", o]);
    assert!(e.contains("junk.pds") && e.contains("magic"), "{e}");

    let h = header(4, 4, 1);
    let good = write_dump(
        dir.path(),
        "good.pds",
        &h,
        &[Record::new(1.0, 1.0, 0.0, [1.0; 3]); 4],
    );
    let mut bytes = std::fs::read(&good).unwrap();
    bytes.truncate(bytes.len() - 5);
    let short = dir.path().join("short.pds");
    std::fs::write(&short, &bytes).unwrap();
    let e = run_err(&["filter", short.to_str().unwrap(), "-o", o]);
    assert!(e.contains("short.pds") && e.contains("bytes"), "{e}");
    let e = run_err(&["info", short.to_str().unwrap()]);
    assert!(e.contains("short.pds"), "{e}");
    assert!(files(&out).is_empty());

    // An output directory that cannot be created (its parent is a file).
    let bad_out = good.join("out");
    let e = run_err(&[
        "filter",
        good.to_str().unwrap(),
        "-o",
        bad_out.to_str().unwrap(),
    ]);
    assert!(e.contains("good.pds/out"), "{e}");

    let (code, e) = run_err_code(&["filter", good.to_str().unwrap(), "-o", o, "--k", "0"]);
    assert!(e.contains("--k"), "{e}");
    assert_eq!(code, Some(2), "an option value refused is a usage error");
    let (code, e) = run_err_code(&[
        "filter",
        good.to_str().unwrap(),
        "-o",
        o,
        "--sigma-color",
        "0",
    ]);
    assert!(e.contains("sigma-color"), "{e}");
    assert_eq!(code, Some(2));
    assert!(files(&out).iter().all(|f| !f.contains(".tmp")));
}

#[test]
fn info_reports_counts_and_exact_percentiles() {
    let dir = tempfile::tempdir().unwrap();
    let h = header(10, 1, 1);
    // Red channel 1..=1000; plus two invalid records.
    let mut recs: Vec<Record> = (1..=1000)
        .map(|i| Record::new((i % 10) as f32, 0.5, 0.0, [i as f32, 0.0, -1.0]))
        .collect();
    recs.push(Record::new(f32::NAN, 0.0, 0.0, [0.0; 3]));
    recs.push(Record::new(1.0, 0.5, 2.0, [0.0; 3]));
    let p = write_dump(dir.path(), "i.pds", &h, &recs);
    let json = run_ok(&["info", p.to_str().unwrap(), "--json"]);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v["valid"], 1000);
    assert_eq!(v["invalid"]["non_finite"], 1);
    assert_eq!(v["invalid"]["outside_time"], 1);
    let r = &v["channels"][0];
    assert_eq!(r["min"], 1.0);
    assert_eq!(r["p50"], 500.0);
    assert_eq!(r["p99"], 990.0);
    assert_eq!(r["p99_9"], 999.0);
    assert_eq!(r["max"], 1000.0);
    assert_eq!(v["channels"][2]["p50"], -1.0);
    let text = run_ok(&["info", p.to_str().unwrap()]);
    assert!(text.contains("1000 valid"));
}

/// A re-run into a folder that holds an earlier run (other methods, the
/// HTML report) leaves exactly the new run's files: never a mix.
#[test]
fn a_rerun_replaces_the_whole_output_folder() {
    let dir = tempfile::tempdir().unwrap();
    let p = SynthParams {
        width: 12,
        height: 8,
        spp: 6,
        ..SynthParams::default()
    };
    let dump = synth(dir.path(), "a.pds", &p);
    let out = dir.path().join("out");
    let o = out.to_str().unwrap();
    run_ok(&["filter", &dump, "-o", o, "--k", "10"]);
    assert!(files(&out).contains(&"report.html".to_string()));
    let first = report(&out)["provenance"].clone();
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(
        html.contains("accepted while streaming"),
        "the counts are on the page"
    );
    run_ok(&[
        "filter",
        &dump,
        "-o",
        o,
        "--k",
        "5",
        "--methods",
        "trimmed",
        "--no-html",
    ]);
    let want = [
        ".pathdensity-output",
        "filtered.exr",
        "mean.exr",
        "rejected.exr",
        "report.json",
        "trimmed.exr",
    ];
    assert_eq!(files(&out), want);
    assert_eq!(report(&out)["config"]["k"], 5);
    // The report says what it was made from: the same dump, the same hash.
    let second = report(&out)["provenance"].clone();
    assert_eq!(first["dump_xxh3"].as_str().unwrap().len(), 16);
    assert_eq!(first["dump_xxh3"], second["dump_xxh3"]);
    assert!(
        second["command"].to_string().contains("trimmed"),
        "{second}"
    );
    // Nothing hidden is left beside it either.
    assert_eq!(files(dir.path()), ["a.pds", "out"]);
    // An output path that is a file is refused, by name.
    let e = run_err(&["filter", &dump, "-o", &dump]);
    assert!(e.contains("a.pds") && e.contains("not a directory"), "{e}");
}
