//! The regression fixtures: every stored expectation still holds, a drift
//! is reported readably with a non-zero exit, and `--bless` rewrites it.

use std::path::{Path, PathBuf};
use std::process::Command;

use pathdensity::config::Method;
use pathdensity::regress;

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures")
}

#[test]
fn every_fixture_matches_its_expectations() {
    let all = regress::find(&fixtures()).unwrap();
    assert!(all.len() >= 8, "{all:?}");
    for dir in all {
        let drift = regress::check(&dir).unwrap();
        assert!(drift.is_empty(), "{}: {drift:#?}", dir.display());
    }
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &to.join(e.file_name()));
        } else {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
}

#[test]
fn a_drift_is_reported_and_bless_rewrites_the_expectations() {
    let root = tempfile::tempdir().unwrap();
    let dir = root.path().join("glossy-room");
    copy_dir(&fixtures().join("glossy-room"), &dir);
    // An unintended change: the configuration now says k = 20.
    let manifest = dir.join("manifest.json");
    let text = std::fs::read_to_string(&manifest).unwrap();
    let changed = text.replacen("\"k\": 10", "\"k\": 20", 1);
    assert_ne!(text, changed);
    std::fs::write(&manifest, changed).unwrap();

    // A second fixture whose dump is cut short: reported, and the first
    // is still checked.
    let broken = root.path().join("broken");
    copy_dir(&fixtures().join("sky"), &broken);
    let bytes = std::fs::read(broken.join("dump.pds")).unwrap();
    std::fs::write(broken.join("dump.pds"), &bytes[..bytes.len() - 7]).unwrap();

    let out = Command::new(env!("CARGO_BIN_EXE_pathdensity"))
        .args(["regress", root.path().to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(3), "a drift exits 3");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stdout.contains("glossy-room: DRIFT"), "{stdout}");
    assert!(stdout.contains("counts: stored "), "{stdout}");
    assert!(stdout.contains("broken: DRIFT"), "{stdout}");
    assert!(
        stdout.contains("cannot run") && stdout.contains("bytes"),
        "{stdout}"
    );
    assert!(stdout.contains("filtered: RMS"), "{stdout}");
    assert!(stdout.contains("filtered.exr:"), "{stdout}");
    assert!(stderr.contains("2 of 2 fixtures drifted"), "{stderr}");
    std::fs::remove_dir_all(&broken).unwrap();

    let bless = Command::new(env!("CARGO_BIN_EXE_pathdensity"))
        .args(["regress", root.path().to_str().unwrap(), "--bless"])
        .output()
        .unwrap();
    assert!(bless.status.success());
    assert!(regress::check(&dir).unwrap().is_empty());
}

/// An image the run makes that the manifest does not expect (a method
/// added since the fixture was blessed) is drift, not ignored.
#[test]
fn an_image_produced_but_not_expected_is_drift() {
    let root = tempfile::tempdir().unwrap();
    let dir = root.path().join("sky");
    copy_dir(&fixtures().join("sky"), &dir);
    let manifest = dir.join("manifest.json");
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&manifest).unwrap()).unwrap();
    let expected = &mut m["expected"];
    expected["metrics"].as_object_mut().unwrap().remove("clamp");
    expected["images"]
        .as_array_mut()
        .unwrap()
        .retain(|i| i != "clamp.exr");
    std::fs::write(&manifest, serde_json::to_string(&m).unwrap()).unwrap();
    let drift = regress::check(&dir).unwrap();
    assert_eq!(
        drift,
        [
            "clamp: produced but not expected (--bless adds it)",
            "clamp.exr: written but not expected (--bless adds it)"
        ],
    );
}

/// A method the table gains is under regression only once a fixture pins
/// its image: the `*-default` fixtures together must hold expectations for
/// every method a build without OIDN can make (tools/maint/make_fixtures.sh
/// lists them; add the new one there and run it).
#[test]
fn every_method_without_oidn_is_pinned_by_a_default_fixture() {
    let mut pinned = std::collections::BTreeSet::new();
    for dir in regress::find(&fixtures()).unwrap() {
        if !dir.to_string_lossy().ends_with("-default") {
            continue;
        }
        let text = std::fs::read_to_string(dir.join("manifest.json")).unwrap();
        let manifest: regress::Manifest = serde_json::from_str(&text).unwrap();
        pinned.extend(manifest.expected.metrics.keys().map(|id| id.to_string()));
    }
    let missing: Vec<&str> = Method::ALL
        .iter()
        .filter(|m| !m.needs_oidn())
        .map(|m| m.name())
        .filter(|name| !pinned.contains(*name))
        .collect();
    assert!(
        missing.is_empty(),
        "no default fixture pins {missing:?}: add them to tools/maint/make_fixtures.sh's methods and run it"
    );
}
