//! tools/cycles/export.py: a dump of Cycles' own samples (one
//! `sample_offset` per render, film positions from a direction AOV)
//! averages to Cycles' own N-sample render to float rounding, every record
//! lies in its own pixel at a spread-out position, the bytes do not depend
//! on the thread count, the filter takes the dump, and a camera the
//! exporter cannot model gets one line.
//!
//! Needs tools/cycles/.venv (`bash tools/cycles/setup.sh`); skipped loudly
//! without it, unless `PATHDENSITY_REQUIRE_CYCLES` is set (CI sets it and
//! runs the setup).

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Instant;

use pathdensity::dump::{DumpReader, Order, Validity};
use pathdensity::io::exr;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn python() -> Option<PathBuf> {
    common::venv_python("cycles", "import bpy, numpy").or_else(|| {
        common::missing(
            "PATHDENSITY_REQUIRE_CYCLES",
            "Blender Cycles (bpy) is not set up (bash tools/cycles/setup.sh)",
        )
    })
}

fn export(py: &Path, args: &[&str]) -> Output {
    Command::new(py)
        .arg(Path::new(ROOT).join("tools/cycles/export.py"))
        .args(args)
        .output()
        .unwrap()
}

fn ok(o: Output) -> Output {
    assert!(
        o.status.success(),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Per-pixel means of a pass-major still, in f64.
fn pixel_means(d: &DumpReader) -> Vec<[f64; 3]> {
    let h = d.header();
    let pixels = (h.width * h.height) as usize;
    let mut sum = vec![[0.0f64; 3]; pixels];
    for (i, r) in d.records().iter().enumerate() {
        for (s, v) in sum[i % pixels].iter_mut().zip(r.rgb()) {
            *s += v as f64;
        }
    }
    sum.iter().map(|v| v.map(|x| x / h.spp as f64)).collect()
}

/// The largest |a − b| over (|b| + the image's mean |b|): relative, with a
/// floor so that black pixels do not divide by zero.
fn worst_relative(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let floor = b.iter().flatten().map(|v| v.abs()).sum::<f64>() / (3 * b.len()) as f64;
    a.iter()
        .flatten()
        .zip(b.iter().flatten())
        .map(|(x, y)| (x - y).abs() / (y.abs() + floor))
        .fold(0.0, f64::max)
}

#[test]
fn cycles_own_samples_average_to_its_render_and_lie_in_their_pixels() {
    let Some(py) = python() else { return };
    let start = Instant::now();
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n);
    let (dump, film, reference) = (p("t.pds"), p("film.exr"), p("ref.exr"));
    let (albedo, normal) = (p("albedo.exr"), p("normal.exr"));
    let (w, hh, spp) = (32usize, 32usize, 16u32);
    let o = ok(export(
        &py,
        &[
            "builtin:textured",
            "-o",
            s(&dump),
            "--spp",
            "16",
            "--size",
            "32x32",
            "--seed",
            "3",
            "--film-out",
            s(&film),
            "--reference-spp",
            "64",
            "--reference-out",
            s(&reference),
            "--albedo-out",
            s(&albedo),
            "--normal-out",
            s(&normal),
        ],
    ));
    eprintln!("{}", String::from_utf8_lossy(&o.stderr).trim_end());

    let d = DumpReader::open(&dump).unwrap();
    let h = d.header().clone();
    assert_eq!((h.width, h.height, h.frames, h.spp), (32, 32, 1, spp));
    assert_eq!(h.order, Order::PassMajor);
    assert_eq!(h.sample_count, (w * hh) as u64 * spp as u64);
    assert_eq!(h.seed, 3);
    assert_eq!(h.scene, "textured");

    // (a) The mean of the N one-sample renders is Cycles' own N-sample
    // render of the same seed, to float rounding, not to noise.
    let (fw, fh, own) = exr::read_rgb(&film, exr::MAX_PIXELS).unwrap();
    assert_eq!((fw, fh), (w, hh));
    let mean = pixel_means(&d);
    let err = worst_relative(&mean, &own);
    eprintln!("dump mean against Cycles' {spp}-sample render: worst relative {err:.2e}");
    assert!(
        err < 1e-5,
        "the dump's mean is {err:.2e} from Cycles' render"
    );
    // The check can fail: another seed's render is far off.
    let (_, _, other) = exr::read_rgb(&reference, exr::MAX_PIXELS).unwrap();
    let noise = worst_relative(&mean, &other);
    assert!(
        noise > 1e-2,
        "another seed's render is only {noise:.2e} away"
    );

    // (b) Every record lies in its own pixel; sample 0 sits at the pixel
    // centre (to Cycles' filter table), the others spread over the pixel.
    let pixels = w * hh;
    let (mut n, mut sum, mut sq) = (0.0f64, [0.0f64; 2], [0.0f64; 2]);
    for (i, r) in d.records().iter().enumerate() {
        assert_eq!(r.validity(&h), Validity::Valid, "record {i}: {r:?}");
        let (px, py_) = (r.x.floor() as usize, r.y.floor() as usize);
        assert_eq!(py_ * w + px, i % pixels, "record {i} at ({}, {})", r.x, r.y);
        assert_eq!(r.t, 0.0);
        let frac = [r.x.fract() as f64, r.y.fract() as f64];
        if i < pixels {
            assert!(
                frac.iter().all(|f| (f - 0.5).abs() < 1e-3),
                "sample 0 of pixel {i} at {frac:?}"
            );
        } else {
            n += 1.0;
            for a in 0..2 {
                sum[a] += frac[a];
                sq[a] += frac[a] * frac[a];
            }
        }
    }
    for a in 0..2 {
        let (m, sd) = (sum[a] / n, (sq[a] / n - (sum[a] / n).powi(2)).sqrt());
        eprintln!("fractional position, axis {a}: mean {m:.4}, std {sd:.4} (uniform: 0.5, 0.2887)");
        assert!(
            (m - 0.5).abs() < 0.01 && (sd - 0.2887).abs() < 0.01,
            "{m} {sd}"
        );
    }

    // OIDN's auxiliary inputs on the same film: albedo in [0, 1], unit normals.
    let (_, _, a) = exr::read_rgb(&albedo, pixels).unwrap();
    assert!(a.iter().flatten().all(|v| (0.0..=1.0 + 1e-6).contains(v)));
    assert!(a.iter().any(|p| p.iter().any(|&v| v > 0.05)));
    let (_, _, nn) = exr::read_rgb(&normal, pixels).unwrap();
    let unit = nn
        .iter()
        .filter(|p| ((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 1.0).abs() < 0.02)
        .count();
    assert!(unit > pixels / 2, "{unit} of {pixels} normals are unit");

    // (d) The filter takes the dump.
    let out = p("out");
    let o = Command::new(env!("CARGO_BIN_EXE_pathdensity"))
        .args([
            "filter",
            s(&dump),
            "-o",
            s(&out),
            "--reference",
            s(&reference),
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.join("filtered.exr").exists());
    eprintln!("took {:.1} s", start.elapsed().as_secs_f64());
}

#[test]
fn the_bytes_do_not_depend_on_threads_and_the_orders_agree() {
    let Some(py) = python() else { return };
    let start = Instant::now();
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, args: &[&str]| {
        let p = dir.path().join(name);
        let mut all = vec![
            "builtin:caustic",
            "-o",
            s(&p),
            "--size",
            "24x16",
            "--spp",
            "4",
            "--seed",
            "5",
            "--quiet",
        ];
        all.extend_from_slice(args);
        ok(export(&py, &all));
        std::fs::read(&p).unwrap()
    };
    // (c) One and two threads write the same bytes.
    let one = run("t1.pds", &["--threads", "1"]);
    let two = run("t2.pds", &["--threads", "2"]);
    assert!(one == two, "one thread and two wrote different dumps");
    run("pixel.pds", &["--order", "pixel"]);
    let pass = DumpReader::open(dir.path().join("t1.pds")).unwrap();
    let pixel = DumpReader::open(dir.path().join("pixel.pds")).unwrap();
    assert_eq!(pixel.header().order, Order::PixelMajor);
    let (pixels, spp) = (24 * 16, 4);
    for (i, r) in pixel.records().iter().enumerate() {
        assert_eq!(
            *r,
            pass.records()[(i % spp) * pixels + i / spp],
            "record {i}"
        );
    }
    // The positions come from a probe render (the scene hidden from the
    // camera); measured instead from an AOV in every material of the
    // scene's own renders, they agree to float rounding, with the same values.
    run("aov.pds", &["--positions", "aov"]);
    let aov = DumpReader::open(dir.path().join("aov.pds")).unwrap();
    for (i, (a, p)) in aov.records().iter().zip(pass.records()).enumerate() {
        assert_eq!(a.rgb(), p.rgb(), "record {i}");
        assert!(
            (a.x - p.x).abs() < 1e-4 && (a.y - p.y).abs() < 1e-4,
            "record {i}: {a:?} {p:?}"
        );
    }
    // The seed route: every record at its pixel's centre.
    run("seed.pds", &["--route", "seed"]);
    let seed = DumpReader::open(dir.path().join("seed.pds")).unwrap();
    for (i, r) in seed.records().iter().enumerate() {
        let p = i % pixels;
        assert_eq!(
            (r.x, r.y),
            ((p % 24) as f32 + 0.5, (p / 24) as f32 + 0.5),
            "record {i}"
        );
    }
    assert!(seed.records() != pass.records());
    eprintln!("took {:.1} s", start.elapsed().as_secs_f64());
}

#[test]
fn a_camera_the_exporter_cannot_model_gets_one_line_and_no_dump() {
    let Some(py) = python() else { return };
    let start = Instant::now();
    let dir = tempfile::tempdir().unwrap();
    let blend = |name: &str, change: &str| {
        let p = dir.path().join(name);
        let script = format!(
            "import sys; sys.path.insert(0, {tools:?})\n\
             import bpy, scenes\n\
             scenes.build('caustic')\n\
             s = bpy.context.scene\n\
             {change}\n\
             bpy.ops.wm.save_as_mainfile(filepath={path:?})\n",
            tools = format!("{ROOT}/tools/cycles"),
            path = s(&p),
        );
        let o = Command::new(&py).args(["-c", &script]).output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        p
    };
    let cases = [
        (
            blend("dof.blend", "s.camera.data.dof.use_dof = True"),
            "depth of field",
        ),
        (
            blend("blur.blend", "s.render.use_motion_blur = True"),
            "motion blur",
        ),
        (
            blend("ortho.blend", "s.camera.data.type = 'ORTHO'"),
            "--route seed",
        ),
        (dir.path().join("missing.blend"), "no such file"),
    ];
    for (path, expected) in &cases {
        let out = dir.path().join("out.pds");
        let o = export(
            &py,
            &[s(path), "-o", s(&out), "--spp", "2", "--size", "8x8"],
        );
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{}: {err}", path.display());
        assert_eq!(
            err.trim_end().lines().count(),
            1,
            "{}: {err}",
            path.display()
        );
        assert!(
            err.contains(s(path)) && err.contains(expected),
            "{}: {err}",
            path.display()
        );
        assert!(!out.exists(), "{}: a dump was written", path.display());
        let leftovers: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().contains(".tmp-"))
            .collect();
        assert!(leftovers.is_empty(), "{leftovers:?}");
    }
    // The seed route takes the orthographic camera.
    let out = dir.path().join("ortho.pds");
    ok(export(
        &py,
        &[
            s(&cases[2].0),
            "-o",
            s(&out),
            "--spp",
            "2",
            "--size",
            "8x8",
            "--route",
            "seed",
        ],
    ));
    assert!(out.exists());
    // A file that is not a dump is not overwritten.
    let text = dir.path().join("notes.txt");
    std::fs::write(&text, "keep me").unwrap();
    let o = export(
        &py,
        &[
            "builtin:caustic",
            "-o",
            s(&text),
            "--spp",
            "1",
            "--size",
            "4x4",
        ],
    );
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(std::fs::read_to_string(&text).unwrap(), "keep me");
    eprintln!("took {:.1} s", start.elapsed().as_secs_f64());
}
