//! Our ꟻLIP and HDR-ꟻLIP (`metrics::flip`) against NVIDIA's reference
//! implementation (`flip-evaluator`, run by tools/flip/reference.py), to
//! within 1 %: on every still image of the fixtures (our renderer) and on
//! a Mitsuba 3 scene's images as `filter` writes them, where the numbers
//! compared are the ones `report.json` holds.
//!
//! Needs tools/flip/.venv (`bash tools/flip/setup.sh`) and, for the
//! Mitsuba part, tools/mitsuba/.venv; skipped loudly without them unless
//! `PATHDENSITY_REQUIRE_FLIP` (and `PATHDENSITY_REQUIRE_MITSUBA`) is set.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use pathdensity::image::Image;
use pathdensity::io::exr;
use pathdensity::metrics::flip_pair;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// A venv's python that imports `module`, or a loud skip (a panic when
/// `require` is set).
fn python(venv: &str, module: &str, require: &str, setup: &str) -> Option<PathBuf> {
    let p = Path::new(ROOT).join(venv).join("bin/python");
    let ok = Command::new(&p)
        .args(["-c", &format!("import {module}")])
        .output()
        .is_ok_and(|o| o.status.success());
    if ok {
        return Some(p);
    }
    let why = format!("{module} is not set up ({setup})");
    if std::env::var_os(require).is_some() {
        panic!("{why}, and {require} is set");
    }
    common::skipped(&why);
    None
}

/// tools/flip/.venv's python, with NVIDIA's FLIP.
fn flip_python() -> Option<PathBuf> {
    python(
        "tools/flip/.venv",
        "flip_evaluator",
        "PATHDENSITY_REQUIRE_FLIP",
        "bash tools/flip/setup.sh",
    )
}

fn read(path: &Path) -> Image {
    let (w, h, px) = exr::read_rgb(path, exr::MAX_PIXELS).unwrap();
    let mut img = Image::new(w, h, 1);
    img.data = px;
    img
}

fn raw(img: &Image, path: &Path) {
    let bytes: Vec<u8> = img
        .data
        .iter()
        .flat_map(|p| p.map(|v| v as f32))
        .flat_map(f32::to_le_bytes)
        .collect();
    std::fs::write(path, bytes).unwrap();
}

/// The reference implementation's (LDR, HDR) mean of each pair.
fn reference_flip(py: &Path, pairs: &[(Image, Image)], dir: &Path) -> Vec<(f64, f64)> {
    let mut args = Vec::new();
    for (i, (r, t)) in pairs.iter().enumerate() {
        let (rp, tp) = (dir.join(format!("r{i}.f32")), dir.join(format!("t{i}.f32")));
        raw(r, &rp);
        raw(t, &tp);
        args.extend([
            r.width.to_string(),
            r.height.to_string(),
            "1".into(),
            rp.display().to_string(),
            tp.display().to_string(),
        ]);
    }
    let out = Command::new(py)
        .arg(Path::new(ROOT).join("tools/flip/reference.py"))
        .args(&args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            (v["ldr"].as_f64().unwrap(), v["hdr"].as_f64().unwrap())
        })
        .collect()
}

fn within_1_percent(what: &str, ours: f64, theirs: f64) {
    eprintln!(
        "{what}: ours {ours:.6}, the reference's {theirs:.6} ({:+.4} %)",
        100.0 * (ours / theirs - 1.0)
    );
    assert!(
        (ours - theirs).abs() <= 0.01 * theirs.abs() + 1e-6,
        "{what}: ours {ours:.6}, the reference's {theirs:.6}"
    );
}

#[test]
fn flip_agrees_with_the_reference_on_our_fixtures() {
    let Some(py) = flip_python() else {
        return;
    };
    let mut names = Vec::new();
    let mut pairs = Vec::new();
    for scene in ["glossy-room", "two-lights", "sky", "indirect-room"] {
        let dir = Path::new(ROOT).join("fixtures").join(scene);
        let reference = read(&dir.join("reference.exr"));
        for image in ["mean", "filtered", "median", "filtered_energy", "rwmc"] {
            let path = dir.join("expected").join(format!("{image}.exr"));
            if path.is_file() {
                names.push(format!("{scene}/{image}"));
                pairs.push((reference.clone(), read(&path)));
            }
        }
    }
    assert!(pairs.len() >= 10, "{names:?}");
    let dir = tempfile::tempdir().unwrap();
    let theirs = reference_flip(&py, &pairs, dir.path());
    for ((name, (r, t)), (ldr, hdr)) in names.iter().zip(&pairs).zip(theirs) {
        let (our_ldr, our_hdr) = flip_pair(t, r, 0, 1.0);
        within_1_percent(&format!("{name} FLIP"), our_ldr, ldr);
        within_1_percent(&format!("{name} HDR-FLIP"), our_hdr, hdr);
    }
}

#[test]
fn report_json_holds_the_references_flip_on_a_mitsuba_scene() {
    let Some(py) = flip_python() else {
        return;
    };
    let Some(mitsuba) = python(
        "tools/mitsuba/.venv",
        "mitsuba",
        "PATHDENSITY_REQUIRE_MITSUBA",
        "bash tools/mitsuba/setup.sh",
    ) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (dump, reference, out) = (
        dir.path().join("g.pds"),
        dir.path().join("g_ref.exr"),
        dir.path().join("out"),
    );
    let s = |p: &Path| p.display().to_string();
    let export = Command::new(&mitsuba)
        .arg(Path::new(ROOT).join("tools/mitsuba/export.py"))
        .arg(Path::new(ROOT).join("tools/mitsuba/scenes/glossy-highlight.xml"))
        .args(["-o", &s(&dump), "--spp", "16", "--size", "48x48", "--quiet"])
        .args(["--reference-spp", "256", "--reference-out", &s(&reference)])
        .output()
        .unwrap();
    assert!(
        export.status.success(),
        "{}",
        String::from_utf8_lossy(&export.stderr)
    );
    let filter = Command::new(env!("CARGO_BIN_EXE_pathdensity"))
        .args(["filter", &s(&dump), "-o", &s(&out), "--no-html"])
        .args([
            "--reference",
            &s(&reference),
            "--methods",
            "filtered_energy,clamp,median",
        ])
        .output()
        .unwrap();
    assert!(
        filter.status.success(),
        "{}",
        String::from_utf8_lossy(&filter.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let r = read(&reference);
    let images = ["mean", "filtered", "filtered_energy", "clamp", "median"];
    let pairs: Vec<(Image, Image)> = images
        .iter()
        .map(|i| (r.clone(), read(&out.join(format!("{i}.exr")))))
        .collect();
    let theirs = reference_flip(&py, &pairs, dir.path());
    for (image, (ldr, hdr)) in images.iter().zip(theirs) {
        let m = &report["metrics"][image];
        within_1_percent(&format!("{image} FLIP"), m["flip"].as_f64().unwrap(), ldr);
        within_1_percent(
            &format!("{image} HDR-FLIP"),
            m["hdr_flip"].as_f64().unwrap(),
            hdr,
        );
    }
}
