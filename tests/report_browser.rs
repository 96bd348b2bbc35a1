//! report.html in a real headless browser (Debian's chromium): the page
//! loads from the file system without console errors, every image decodes
//! (the page's own check sets `data-status="ok"` on `<body>`), and a
//! screenshot is taken.
//!
//! Without a browser the test is skipped with a message, unless
//! `PATHDENSITY_REQUIRE_BROWSER` is set (CI sets it and installs chromium).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use base64::Engine;
use pathdensity::commands::filter::{FilterOptions, filter};
use pathdensity::config::MethodSet;
use pathdensity::io::exr;
use pathdensity::sweep::SweepOptions;
use pathdensity::synth::SynthParams;

fn browser() -> Option<PathBuf> {
    if let Ok(p) = std::env::var("PATHDENSITY_BROWSER") {
        return Some(PathBuf::from(p));
    }
    let path = std::env::var_os("PATH")?;
    ["chromium", "chromium-browser", "google-chrome"]
        .iter()
        .flat_map(|b| std::env::split_paths(&path).map(move |d| d.join(b)))
        .find(|p| p.is_file())
}

/// Runs the browser headless on `page` with `args`; returns (stdout, stderr).
fn headless(browser: &Path, page: &Path, args: &[&str]) -> (String, String) {
    let url = format!("file://{}", page.canonicalize().unwrap().display());
    let out = Command::new("timeout")
        .arg("120")
        .arg(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--enable-logging=stderr",
            "--virtual-time-budget=10000",
            "--window-size=1400,1600",
        ])
        .args(args)
        .arg(url)
        .output()
        .expect("the browser runs");
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Fails on an error the page logged to the browser's console.
fn no_console_errors(stderr: &str) {
    for line in stderr.lines() {
        let console_error = line.contains("CONSOLE") && line.contains("rror");
        assert!(
            !console_error && !line.contains("Uncaught"),
            "console error: {line}"
        );
    }
}

/// Loads `html` with tests/browser/viewer_check.js injected (written
/// beside it in `dir`), which drives the viewer by its keys; asserts it
/// passed without a console error, and returns the DOM.
fn viewer_check(browser: &Path, html: &str, dir: &Path) -> String {
    let check = include_str!("browser/viewer_check.js");
    let tested = dir.join("viewer_tested.html");
    std::fs::write(
        &tested,
        html.replace("</body>", &format!("<script>{check}</script>\n</body>")),
    )
    .unwrap();
    let mut attempt = 0;
    let dom = loop {
        attempt += 1;
        let (dom, err) = headless(browser, &tested, &["--dump-dom"]);
        if dom.contains("data-viewer-test=") || attempt == 3 {
            // Pressing the keys raised no error either.
            no_console_errors(&err);
            assert!(dom.contains("data-status=\"ok\""), "{dom:.2000}");
            break dom;
        }
    };
    let result = dom
        .split("data-viewer-test=\"")
        .nth(1)
        .and_then(|s| s.split('"').next())
        .unwrap_or("(no result)");
    assert_eq!(result, "pass", "the viewer's check after {attempt} load(s)");
    dom
}

/// A small synthetic dump with fireflies and a light in `dir` (d.pds), and
/// its firefly-free reference (ref.exr); returns the dump's path.
fn dump_and_reference(dir: &Path, frames: u32) -> PathBuf {
    let p = SynthParams {
        width: 40,
        height: 24,
        frames,
        spp: 8,
        firefly_fraction: 0.02,
        light: Some((5, 5, 3, 20.0)),
        ..SynthParams::default()
    };
    let dump = dir.join("d.pds");
    p.write(&dump).unwrap();
    let dense = SynthParams {
        spp: 128,
        firefly_fraction: 0.0,
        seed: 99,
        ..p.clone()
    };
    exr::write_image(dir, "ref", &common::synth_mean(&dense)).unwrap();
    dump
}

fn check_report(browser: &Path, frames: u32) {
    let dir = tempfile::tempdir().unwrap();
    let dump = dump_and_reference(dir.path(), frames);
    let out = dir.path().join("out");
    let mut o = FilterOptions::new(&dump, &out);
    o.reference = Some(dir.path().join("ref.exr"));
    // Not 1: an exposure applied twice would go unseen at 1.
    o.config.exposure = 0.7;
    o.config.methods = MethodSet::NO_OIDN;
    filter(&o).unwrap();
    let page = out.join("report.html");
    let html = std::fs::read_to_string(&page).unwrap();
    // Nothing fetched: no remote src, href or url() (SVG's xmlns is a name).
    for pat in ["src=\"http", "href=\"http", "url(http", "@import"] {
        assert!(
            !html.contains(pat),
            "the page references the network: {pat}"
        );
    }

    // Image decoding runs off the page's virtual clock, so on a loaded
    // machine the DOM can be dumped before it finishes: a page with no
    // status yet is loaded again (up to 3 times); an error status fails.
    let mut attempt = 0;
    let (dom, err) = loop {
        attempt += 1;
        let (dom, err) = headless(browser, &page, &["--dump-dom"]);
        if dom.contains("data-status=") || attempt == 3 {
            break (dom, err);
        }
    };
    assert!(
        dom.contains("data-status=\"ok\""),
        "page status after {attempt} load(s): {dom:.2000}\n{err}"
    );
    no_console_errors(&err);
    // Every method and the reference are in the viewer, the recommended
    // image first.
    let data = common::viewer_data(&html);
    let names = common::viewer_names(&data);
    for name in [
        "reference",
        "mean",
        "filtered",
        "median",
        "trimmed",
        "bilateral",
        "median3",
        "guided",
        "rejected",
    ] {
        assert!(names.contains(&name), "{name} missing from {names:?}");
    }
    assert_eq!(names[0], "guided");
    assert_eq!(data["recommended"], 0);
    assert_eq!(
        names[data["reference"].as_u64().unwrap() as usize],
        "reference"
    );
    // Each FLIP map is its image's: its mean is report.json's FLIP of that
    // image, within the map's 8-bit rounding.
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let mut mapped = 0;
    for entry in data["images"].as_array().unwrap() {
        let name = entry["name"].as_str().unwrap();
        let Some(want) = report["metrics"][name]["flip"].as_f64() else {
            continue;
        };
        let mut sum = 0.0;
        let mut n = 0;
        for frame in entry["flip"].as_array().expect("a FLIP map") {
            let bytes = base64::engine::general_purpose::STANDARD
                .decode(frame.as_str().unwrap())
                .unwrap();
            sum += bytes.iter().map(|&b| b as f64 / 255.0).sum::<f64>();
            n += bytes.len();
        }
        let mean = sum / n as f64;
        assert!(
            (mean - want).abs() <= 0.5 / 255.0 + 1e-9,
            "{name}: its map's mean FLIP {mean} against report.json's {want}"
        );
        mapped += 1;
    }
    assert!(mapped >= 8, "{mapped} FLIP maps checked");
    assert!(dom.contains("data-name=\"sigma\""), "the σ map");

    // The viewer driven by its keys (tests/browser/viewer_check.js): two
    // methods differ, +1 stop doubles a linear value before the display
    // transform, the reference against itself is zero in every error view,
    // frames and zoom.
    let dom = viewer_check(browser, &html, &out);
    if frames == 1 {
        assert!(
            dom.contains("data-viewer-skipped"),
            "frames are skipped for a still"
        );
    }
    assert!(dom.contains("<svg"), "slice plot inlined");

    let shot = out.join("screenshot.png");
    let arg = format!("--screenshot={}", shot.display());
    headless(browser, &page, &[&arg]);
    let img = image::open(&shot)
        .expect("a screenshot was written")
        .to_rgb8();
    assert_eq!(img.dimensions(), (1400, 1600));
    let distinct: std::collections::HashSet<[u8; 3]> = img.pixels().map(|p| p.0).collect();
    assert!(distinct.len() > 100, "the screenshot shows images");
    if let Ok(keep) = std::env::var("PATHDENSITY_SCREENSHOT_DIR") {
        let _ = std::fs::copy(&shot, Path::new(&keep).join(format!("report_{frames}.png")));
    }
}

#[test]
fn report_html_loads_without_errors_in_a_headless_browser() {
    let Some(b) = browser() else {
        if std::env::var_os("PATHDENSITY_REQUIRE_BROWSER").is_some() {
            panic!("no browser found, and PATHDENSITY_REQUIRE_BROWSER is set");
        }
        common::skipped(
            "report.html in a browser: no chromium on PATH (set PATHDENSITY_BROWSER; .ci/run installs it)",
        );
        return;
    };
    check_report(&b, 1);
    check_report(&b, 3);
}

/// sweep.html's viewer passes the same keyboard check (tests/sweep.rs
/// checks what it shows).
#[test]
fn sweep_html_shows_its_images_in_the_viewer() {
    let Some(b) = browser() else {
        if std::env::var_os("PATHDENSITY_REQUIRE_BROWSER").is_some() {
            panic!("no browser found, and PATHDENSITY_REQUIRE_BROWSER is set");
        }
        common::skipped("sweep.html in a browser: no chromium on PATH");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let dump = dump_and_reference(dir.path(), 1);
    let out = dir.path().join("sweep");
    let mut o = SweepOptions::new(&dump, dir.path().join("ref.exr"), &out);
    o.ks = vec![3, 8, 20];
    o.sigma_colors = vec![25.0, 100.0];
    pathdensity::commands::sweep::sweep(&o).unwrap();
    let html = std::fs::read_to_string(out.join("sweep.html")).unwrap();
    viewer_check(&b, &html, dir.path());
}
