//! The workspace's arrows point down: the format crate pulls in nothing of
//! the filter, the command line or the plots, and the renderer does not
//! depend on the command layer (this package).

use std::process::Command;

/// The normal (non-dev, non-build) dependencies of `package`, by name.
fn dependencies(package: &str) -> Vec<String> {
    let out = Command::new(env!("CARGO"))
        .args([
            "tree",
            "--offline",
            "-e",
            "normal",
            "--prefix",
            "none",
            "-p",
            package,
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
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
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .collect()
}

#[test]
fn the_format_crate_and_the_renderer_depend_on_nothing_above_them() {
    let format = dependencies("pathdensity-format");
    assert!(format.contains(&"exr".to_string()), "{format:?}");
    for banned in [
        "clap",
        "rayon",
        "plotters",
        "kiddo",
        "indicatif",
        "pathdensity-core",
    ] {
        assert!(
            !format.iter().any(|d| d == banned),
            "format pulls in {banned}"
        );
    }
    let core = dependencies("pathdensity-core");
    for banned in ["clap", "plotters", "indicatif", "image", "pathdensity"] {
        assert!(!core.iter().any(|d| d == banned), "core pulls in {banned}");
    }
    let render = dependencies("pathdensity-render");
    assert!(render.contains(&"pathdensity-format".to_string()));
    for banned in ["pathdensity", "clap", "plotters", "indicatif"] {
        assert!(
            !render.iter().any(|d| d == banned),
            "the renderer pulls in {banned}"
        );
    }
    // Importers share only the format with the rest.
    let import = dependencies("pathdensity-import");
    assert!(import.contains(&"pathdensity-format".to_string()));
    for banned in [
        "pathdensity",
        "pathdensity-core",
        "pathdensity-render",
        "clap",
        "rayon",
    ] {
        assert!(
            !import.iter().any(|d| d == banned),
            "the importers pull in {banned}"
        );
    }
}
