//! OIDN as a method, loaded at run time: with `OIDN_DIR` naming the
//! pyoidn wheel's library (tools/oidn/.venv, `bash tools/oidn/setup.sh`)
//! `oidn` and `METHOD+oidn` equal what the reference library gives
//! through pyoidn for the same input, to 1e-5 relative, on every run, and
//! report.json names the library; without a library OIDN is refused in
//! one line and the default run falls back to the statistical denoiser.
//! Skipped loudly without the venv, unless `PATHDENSITY_REQUIRE_OIDN` is
//! set (CI sets it).

mod common;

use std::path::Path;
use std::process::Command;

use pathdensity::io::exr;

use common::oidn;

/// The binary with `OIDN_DIR` set for it (the library is found at run
/// time: no OIDN build).
fn pathdensity(oidn_dir: &str) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_pathdensity"));
    c.env("OIDN_DIR", oidn_dir).env_remove("VIRTUAL_ENV");
    c
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The reference library's RT filter (HDR) on `input`, through pyoidn.
fn pyoidn(py: &Path, input: &Path, dir: &Path) -> Vec<[f64; 3]> {
    let (w, h, px) = exr::read_rgb(input, exr::MAX_PIXELS).unwrap();
    let raw_in = dir.join("in.f32");
    let raw_out = dir.join("out.f32");
    let bytes: Vec<u8> = px
        .iter()
        .flatten()
        .flat_map(|&v| (v as f32).to_le_bytes())
        .collect();
    std::fs::write(&raw_in, bytes).unwrap();
    let script = format!(
        "import numpy as np, pyoidn\n\
         a = np.fromfile({:?}, '<f4').reshape({h}, {w}, 3)\n\
         pyoidn.denoise(a, hdr=True).astype('<f4').tofile({:?})\n",
        s(&raw_in),
        s(&raw_out)
    );
    let st = Command::new(py).args(["-c", &script]).status().unwrap();
    assert!(st.success());
    std::fs::read(&raw_out)
        .unwrap()
        .chunks_exact(12)
        .map(|c| {
            std::array::from_fn(|k| {
                f32::from_le_bytes(c[4 * k..4 * k + 4].try_into().unwrap()) as f64
            })
        })
        .collect()
}

#[test]
fn oidn_images_equal_the_reference_librarys_and_runs_repeat() {
    let Some((py, dir)) = oidn() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let dump = tmp.path().join("s.pds");
    let st = Command::new(env!("CARGO_BIN_EXE_pathdensity"))
        .args([
            "synth",
            "-o",
            s(&dump),
            "--width",
            "48",
            "--height",
            "40",
            "--spp",
            "16",
            "--fireflies",
            "0.01",
        ])
        .args(["--light", "10,12,3,50"])
        .status()
        .unwrap();
    assert!(st.success());
    let run = |out: &Path, threads: &str| {
        let o = pathdensity(&dir)
            .args([
                "filter",
                s(&dump),
                "-o",
                s(out),
                "--methods",
                "clamp,oidn,oidn_ci",
                "--denoise",
                "oidn",
                "--no-html",
            ])
            .args(["--threads", threads])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    let table = run(&a, "2");
    for name in ["oidn", "filtered+oidn", "clamp+oidn", "oidn_ci"] {
        assert!(table.contains(name), "{name} is missing from\n{table}");
    }
    assert!(
        !a.join("oidn_ci+oidn.exr").exists(),
        "oidn_ci is denoised already"
    );
    assert!(
        !a.join("mean+oidn.exr").exists(),
        "mean+oidn duplicates oidn"
    );
    for (input, output) in [
        ("mean", "oidn"),
        ("filtered", "filtered+oidn"),
        ("clamp", "clamp+oidn"),
    ] {
        let want = pyoidn(&py, &a.join(format!("{input}.exr")), tmp.path());
        let (_, _, got) = exr::read_rgb(&a.join(format!("{output}.exr")), exr::MAX_PIXELS).unwrap();
        let worst = got
            .iter()
            .flatten()
            .zip(want.iter().flatten())
            .map(|(g, w)| (g - w).abs() / w.abs().max(1e-3))
            .fold(0.0, f64::max);
        assert!(
            worst <= 1e-5,
            "{output}: relative difference {worst:e} from pyoidn"
        );
        assert!(got.iter().flatten().any(|&v| v > 0.0), "{output} is black");
    }
    // oidn_ci is OIDN's image moved towards each pixel's mean, never past
    // it, and the light's pixels (whose samples agree) are moved.
    let read = |name: &str| {
        exr::read_rgb(&a.join(format!("{name}.exr")), exr::MAX_PIXELS)
            .unwrap()
            .2
    };
    let (mean, oidn, ci) = (read("mean"), read("oidn"), read("oidn_ci"));
    let (mut moved, mut err_oidn, mut err_ci) = (0, 0.0, 0.0);
    for ((m, o), c) in mean
        .iter()
        .flatten()
        .zip(oidn.iter().flatten())
        .zip(ci.iter().flatten())
    {
        let (lo, hi) = (o.min(*m), o.max(*m));
        assert!(
            (lo - 1e-6..=hi + 1e-6).contains(c),
            "oidn_ci {c} outside [{lo}, {hi}]"
        );
        moved += usize::from(c != o);
        err_oidn += (o - m).abs();
        err_ci += (c - m).abs();
    }
    assert!(
        moved > 0 && err_ci < err_oidn,
        "oidn_ci moved {moved} channels"
    );
    run(&b, "1");
    for name in ["oidn", "filtered+oidn", "clamp+oidn", "oidn_ci"] {
        let file = format!("{name}.exr");
        assert!(
            std::fs::read(a.join(&file)).unwrap() == std::fs::read(b.join(&file)).unwrap(),
            "{file} differs between runs"
        );
    }
}

/// When OIDN is found the default run makes guided_oidn, not guided, and
/// recommends it: first row of the table, `"recommended"` in report.json, and the
/// summary and report.json name the library.
#[test]
fn a_found_oidn_makes_guided_oidn_the_recommended_image() {
    let Some((_, dir)) = oidn() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let dump = tmp.path().join("s.pds");
    let synth = Command::new(env!("CARGO_BIN_EXE_pathdensity"))
        .args(["synth", "-o", s(&dump), "--width", "24", "--height", "20"])
        .args(["--spp", "8", "--light", "5,6,2,40"])
        .status()
        .unwrap();
    assert!(synth.success());
    let out = tmp.path().join("o");
    let o = pathdensity(&dir)
        .args(["filter", s(&dump), "-o", s(&out), "--no-html"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let table = String::from_utf8_lossy(&o.stdout);
    let first = table
        .lines()
        .skip_while(|l| !l.trim_start().starts_with("image"))
        .nth(1)
        .unwrap_or_else(|| panic!("no table in\n{table}"));
    assert!(first.contains("guided_oidn (use)"), "{table}");
    // One recommended image: guided_oidn in guided's place, no comparison
    // images.
    for name in ["guided_oidn", "filtered_energy"] {
        assert!(out.join(format!("{name}.exr")).is_file(), "{name}");
    }
    for name in ["guided", "statmc", "oidn_ci", "median"] {
        assert!(!out.join(format!("{name}.exr")).exists(), "{name}");
    }
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["recommended"], "guided_oidn");
    let denoiser = report["denoiser"].as_str().unwrap_or_default();
    assert!(
        denoiser.starts_with("OIDN 2.") && denoiser.contains("libOpenImageDenoise"),
        "report.json's denoiser: {denoiser:?}"
    );
    assert!(table.contains(&format!("denoiser: {denoiser}")), "{table}");
    assert!(
        !out.join("oidn.exr").exists(),
        "plain oidn is not a default"
    );

    // With the renderer's albedo and normal: OIDN's image changes, and
    // report.json says which were given and how OIDN took them; `fast`
    // (as they are) and `accurate` (the default: prefiltered) differ.
    let (w, h) = (24, 20);
    let mut albedo = pathdensity::image::Image::new(w, h, 1);
    for (p, px) in albedo.data.iter_mut().enumerate() {
        *px = [if p % w < w / 2 { 0.2 } else { 0.9 }; 3];
    }
    let normal = pathdensity::image::Image {
        data: vec![[0.0, 0.0, 1.0]; w * h],
        ..albedo.clone()
    };
    pathdensity::io::exr::write_image(tmp.path(), "albedo", &albedo).unwrap();
    pathdensity::io::exr::write_image(tmp.path(), "normal", &normal).unwrap();
    let runs: Vec<Vec<u8>> = [None, Some(None), Some(Some("fast"))]
        .iter()
        .map(|&aux| {
            let out = tmp.path().join(format!("aux-{aux:?}"));
            let mut c = pathdensity(&dir);
            c.args([
                "filter",
                s(&dump),
                "-o",
                s(&out),
                "--no-html",
                "--methods",
                "oidn",
            ]);
            if let Some(prefilter) = aux {
                c.args(["--albedo", s(&tmp.path().join("albedo.exr"))]);
                c.args(["--normal", s(&tmp.path().join("normal.exr"))]);
                if let Some(p) = prefilter {
                    c.args(["--aux-prefilter", p]);
                }
            }
            let o = c.output().unwrap();
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            let report: serde_json::Value =
                serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
            assert_eq!(report["albedo"].is_string(), aux.is_some());
            let prefilter = aux.map(|p| p.unwrap_or("accurate"));
            assert_eq!(report["aux_prefilter"].as_str(), prefilter);
            // The denoiser's phrase says how OIDN took them.
            let denoiser = report["denoiser"].as_str().unwrap_or_default();
            let said = prefilter.map(|p| format!("albedo and normal (--aux-prefilter {p})"));
            assert_eq!(
                said.is_some_and(|s| denoiser.ends_with(&s)),
                aux.is_some(),
                "{denoiser}"
            );
            assert!(denoiser.starts_with("OIDN 2."), "{denoiser}");
            std::fs::read(out.join("oidn.exr")).unwrap()
        })
        .collect();
    assert_ne!(runs[0], runs[1], "the albedo changes OIDN's image");
    assert_ne!(runs[1], runs[2], "the prefilter changes OIDN's image");
}

/// Without a library (`OIDN_DIR` naming a folder without one) every
/// OIDN option is refused in one line that says where it looked, and the
/// default run recommends `guided`, made with the statistical denoiser,
/// and says so; the renderer's albedo is taken, and guides statmc.
#[test]
fn without_oidn_its_options_are_refused_and_guided_is_recommended() {
    let tmp = tempfile::tempdir().unwrap();
    let empty = tmp.path().join("no-oidn");
    std::fs::create_dir(&empty).unwrap();
    let dump = tmp.path().join("s.pds");
    let st = Command::new(env!("CARGO_BIN_EXE_pathdensity"))
        .args(["synth", "-o", s(&dump), "--width", "48", "--height", "40"])
        .args(["--spp", "4", "--light", "3,4,1,40"])
        .status()
        .unwrap();
    assert!(st.success());
    for args in [
        ["--methods", "oidn"],
        ["--methods", "oidn_ci"],
        ["--denoise", "oidn"],
    ] {
        let o = pathdensity(s(&empty))
            .args(["filter", s(&dump), "-o", s(&tmp.path().join("o"))])
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(
            err.contains("OIDN_DIR") && err.contains(s(&empty)) && err.contains(args[0]),
            "{err}"
        );
        assert!(!tmp.path().join("o").exists(), "a refused run wrote {err}");
    }
    let out = tmp.path().join("d");
    let o = pathdensity(s(&empty))
        .args(["filter", s(&dump), "-o", s(&out), "--no-html"])
        .output()
        .unwrap();
    let table = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["recommended"], "guided", "{table}");
    let denoiser = report["denoiser"].as_str().unwrap_or_default();
    assert!(
        denoiser.starts_with("statmc") && denoiser.contains("OIDN_DIR"),
        "report.json's denoiser: {denoiser:?}"
    );
    assert!(table.contains(&format!("denoiser: {denoiser}")), "{table}");
    assert!(!out.join("guided_oidn.exr").exists() && out.join("guided.exr").exists());

    // A checkered albedo: no two neighbours alike. (The synthetic field
    // at 4 samples a pixel is smooth enough that statmc averages
    // neighbours without it.)
    let (w, h) = (48, 40);
    let mut albedo = pathdensity::image::Image::new(w, h, 1);
    for (p, px) in albedo.data.iter_mut().enumerate() {
        *px = [if (p % w + p / w) % 2 == 0 { 0.2 } else { 0.9 }; 3];
    }
    pathdensity::io::exr::write_image(tmp.path(), "albedo", &albedo).unwrap();
    let guided = out.join("guided.exr");
    let out = tmp.path().join("a");
    let o = pathdensity(s(&empty))
        .args(["filter", s(&dump), "-o", s(&out), "--no-html"])
        .args(["--albedo", s(&tmp.path().join("albedo.exr"))])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_ne!(
        std::fs::read(&guided).unwrap(),
        std::fs::read(out.join("guided.exr")).unwrap(),
        "the albedo guides statmc"
    );
}

/// OIDN's image of the mean is made once for the run: `oidn` (made
/// beside the replay) and `guided_oidn` (after it) share it. Counted by
/// the channels OIDN's input had set to 0: one pixel's mean is negative
/// on red, so one channel, whichever images start from that image
/// (`--denoise oidn` adds `oidn` beside the images it denoises).
#[test]
fn oidn_denoises_the_mean_once_for_every_image() {
    let Some((_, dir)) = oidn() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let (w, h) = (12u32, 10u32);
    let mut records = Vec::new();
    for pass in 0..8u32 {
        for y in 0..h {
            for x in 0..w {
                let v = 0.5 + 0.01 * ((x * 7 + y * 3 + pass * 5) % 11) as f32;
                let r = if (x, y) == (3, 4) { -0.2 } else { v };
                let (fx, fy) = (x as f32 + 0.5, y as f32 + 0.5);
                records.push(pathdensity::dump::Record::new(fx, fy, 0.0, [r, v, v]));
            }
        }
    }
    let mut header = common::header(w, h, 1);
    header.spp = 8;
    let dump = common::write_dump(tmp.path(), "neg.pds", &header, &records);
    let zeroed = |methods: &str| {
        let (methods, denoise) = methods.split_once(' ').unwrap_or((methods, "none"));
        let out = tmp
            .path()
            .join(format!("{}_{denoise}", methods.replace(',', "_")));
        let o = pathdensity(&dir)
            .args(["filter", s(&dump), "-o", s(&out), "--no-html"])
            .args([
                "--methods",
                methods,
                "--held-out",
                "false",
                "--denoise",
                denoise,
            ])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
        report["warnings"].to_string()
    };
    // `--denoise oidn` adds `oidn` and denoises `filtered` too, whose
    // pixel is negative as well: one channel more.
    let runs = [
        ("mean,oidn", 1),
        ("mean,guided_oidn", 1),
        ("mean,oidn,oidn_ci,guided_oidn", 1),
        ("mean,guided_oidn oidn", 2),
    ];
    for (methods, negative) in runs {
        let warnings = zeroed(methods);
        let counted = format!("0 non-finite and {negative} negative channels");
        assert!(warnings.contains(&counted), "{methods}: {warnings}");
    }
}
