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

/// The modules of pathdensity-core from the bottom up, after the
/// pipeline: a module may import its own layer and those below it only.
const CORE_LAYERS: &[&[&str]] = &[
    &[
        "dump", "image", "names", "par", "progress", "quantile", "synth",
    ],
    &["joint"],
    &["density"],
    &["recon"],
    &["imagespace"],
    &["metrics"],
    &["method"],
    &["config"],
    &["pipeline"],
];

fn layer_of(module: &str) -> Option<usize> {
    CORE_LAYERS.iter().position(|l| l.contains(&module))
}

/// The top-level modules of `crate::…` paths in `source`, comments left out
/// (a doc link may point anywhere).
fn crate_imports(source: &str) -> Vec<String> {
    let mut found = Vec::new();
    for line in source.lines() {
        let code = line.split("//").next().unwrap_or("");
        let mut rest = code;
        while let Some(at) = rest.find("crate::") {
            rest = &rest[at + "crate::".len()..];
            if let Some(group) = rest.strip_prefix('{') {
                // `crate::{a, b::c}`: the group may continue on later lines;
                // its first line is enough for the imports written here.
                for part in group.split([',', '}']) {
                    let name: String = part
                        .trim()
                        .chars()
                        .take_while(|c| c.is_alphanumeric() || *c == '_')
                        .collect();
                    if !name.is_empty() {
                        found.push(name);
                    }
                }
            } else {
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                found.push(name);
            }
        }
    }
    found
}

fn rust_files(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

#[test]
fn no_module_of_core_imports_one_above_it() {
    let src = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("crates/core/src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut checked = 0;
    let mut upward = Vec::new();
    for file in &files {
        let rel = file.strip_prefix(&src).unwrap();
        let first = rel.iter().next().unwrap().to_str().unwrap();
        let module = first.trim_end_matches(".rs");
        if module == "lib" {
            continue;
        }
        let own = layer_of(module).unwrap_or_else(|| {
            panic!("crates/core/src/{first}: a module CORE_LAYERS does not place")
        });
        for import in crate_imports(&std::fs::read_to_string(file).unwrap()) {
            let layer = layer_of(&import).unwrap_or_else(|| {
                panic!(
                    "{}: imports crate::{import}, which CORE_LAYERS does not place",
                    rel.display()
                )
            });
            checked += 1;
            if layer > own {
                upward.push(format!("{} imports crate::{import}", rel.display()));
            }
        }
    }
    assert!(
        checked > 100,
        "only {checked} imports seen: the scan is broken"
    );
    assert!(
        upward.is_empty(),
        "imports pointing up:\n{}",
        upward.join("\n")
    );
}

#[test]
fn the_layer_scan_sees_grouped_and_inline_paths() {
    let imports = crate_imports(
        "use crate::{joint::JointSpace, par};\n// crate::config in a comment\nlet p = crate::pipeline::run(); /// crate::sweep",
    );
    assert_eq!(imports, ["joint", "par", "pipeline"]);
}
