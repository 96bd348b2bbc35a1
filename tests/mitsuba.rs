//! tools/mitsuba/export.py: the dump of a Mitsuba 3 scene averages to what
//! Mitsuba's own film renders, every record lies in its pixel, the bytes
//! depend only on the arguments, and bad input gets one line.
//!
//! Needs tools/mitsuba/.venv (`bash tools/mitsuba/setup.sh`); skipped loudly
//! without it, unless `PATHDENSITY_REQUIRE_MITSUBA` is set (CI sets it and
//! runs the setup).

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use pathdensity::dump::{DumpReader, Order, Validity};
use pathdensity::io::exr;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn python() -> Option<PathBuf> {
    common::venv_python(
        "mitsuba",
        "import mitsuba as mi; mi.set_variant('llvm_ad_rgb')",
    )
    .or_else(|| {
        common::missing(
            "PATHDENSITY_REQUIRE_MITSUBA",
            "Mitsuba 3 is not set up (bash tools/mitsuba/setup.sh)",
        )
    })
}

fn tool(py: &Path, script: &str, args: &[&str]) -> Output {
    Command::new(py)
        .arg(Path::new(ROOT).join("tools/mitsuba").join(script))
        .args(args)
        .output()
        .unwrap()
}

fn ok(o: Output) -> Output {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    o
}

fn scene(name: &str) -> String {
    Path::new(ROOT).join(name).to_string_lossy().into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Per-pixel means and variances of the mean from a pass-major still.
fn pixel_moments(d: &DumpReader) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let h = d.header();
    let pixels = (h.width * h.height) as usize;
    let n = h.spp as f64;
    let mut sum = vec![[0.0f64; 3]; pixels];
    let mut sq = vec![[0.0f64; 3]; pixels];
    for (i, r) in d.records().iter().enumerate() {
        for c in 0..3 {
            let v = r.rgb()[c] as f64;
            sum[i % pixels][c] += v;
            sq[i % pixels][c] += v * v;
        }
    }
    let mean: Vec<[f64; 3]> = sum.iter().map(|s| s.map(|v| v / n)).collect();
    let var = (0..pixels)
        .map(|p| std::array::from_fn(|c| (sq[p][c] - n * mean[p][c].powi(2)) / (n - 1.0) / n))
        .collect();
    (mean, var)
}

/// Three standard scores of `mean − other` (both unbiased estimates of the
/// same image if the exporter is right): the image-wide sum (a lost weight or
/// a wrong scale), and the differences projected on the x and y gradients of
/// `other` (a film position shifted by a fraction of a pixel). `var` is the
/// variance of each difference.
fn bias_scores(w: usize, mean: &[[f64; 3]], other: &[[f64; 3]], var: &[[f64; 3]]) -> [f64; 3] {
    let h = mean.len() / w;
    let grad = |p: usize, c: usize, dx: usize| -> f64 {
        let (x, y) = (p % w, p / w);
        let (lo, hi) = if dx == 1 {
            if x > 0 && x + 1 < w {
                (p - 1, p + 1)
            } else {
                (p, p)
            }
        } else {
            if y > 0 && y + 1 < h {
                (p - w, p + w)
            } else {
                (p, p)
            }
        };
        (other[hi][c] - other[lo][c]) / 2.0
    };
    let mut num = [0.0f64; 3];
    let mut den = [0.0f64; 3];
    for p in 0..mean.len() {
        for c in 0..3 {
            let d = mean[p][c] - other[p][c];
            let weights = [1.0, grad(p, c, 1), grad(p, c, 0)];
            for (k, g) in weights.iter().enumerate() {
                num[k] += d * g;
                den[k] += var[p][c] * g * g;
            }
        }
    }
    std::array::from_fn(|k| num[k] / den[k].sqrt())
}

#[test]
fn exported_samples_average_to_mitsubas_own_film() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (dump, film, reference) = (
        dir.path().join("c.pds"),
        dir.path().join("film.exr"),
        dir.path().join("ref.exr"),
    );
    let checker = scene("tests/data/mitsuba/checker.xml");
    let spp = 16;
    ok(tool(
        &py,
        "export.py",
        &[
            &checker,
            "-o",
            s(&dump),
            "--spp",
            "16",
            "--seed",
            "1",
            "--quiet",
        ],
    ));
    ok(tool(
        &py,
        "render_film.py",
        &[&checker, "-o", s(&film), "--spp", "128", "--seed", "9"],
    ));
    ok(tool(
        &py,
        "export.py",
        &[
            &checker,
            "-o",
            s(&dump.with_extension("x")),
            "--spp",
            "1",
            "--seed",
            "2",
            "--quiet",
            "--reference-spp",
            "128",
            "--reference-out",
            s(&reference),
        ],
    ));

    let d = DumpReader::open(&dump).unwrap();
    let h = d.header().clone();
    assert_eq!((h.width, h.height, h.frames, h.spp), (40, 30, 1, spp));
    assert_eq!(h.order, Order::PassMajor);
    assert_eq!(h.sample_count, 40 * 30 * spp as u64);
    assert_eq!(h.seed, 1);
    let pixels = (h.width * h.height) as usize;
    for (i, r) in d.records().iter().enumerate() {
        assert_eq!(r.validity(&h), Validity::Valid, "record {i}: {r:?}");
        let (x, y) = (r.x.floor() as usize, r.y.floor() as usize);
        assert_eq!(
            y * 40 + x,
            i % pixels,
            "record {i} at ({}, {}) is outside its pixel",
            r.x,
            r.y
        );
        assert_eq!(r.t, 0.0);
    }

    let (mean, var_mean) = pixel_moments(&d);
    for (name, path, spp_other) in [
        ("Mitsuba's film", &film, 128.0),
        ("the reference", &reference, 128.0),
    ] {
        let (w, hh, other) = exr::read_rgb(path, exr::MAX_PIXELS).unwrap();
        assert_eq!((w, hh), (40, 30), "{name}");
        // The other image's variance: the same per-sample variance over its count.
        let var: Vec<[f64; 3]> = var_mean
            .iter()
            .map(|v| v.map(|x| x * (1.0 + spp as f64 / spp_other)))
            .collect();
        let scores = bias_scores(w, &mean, &other, &var);
        assert!(
            scores.iter().all(|z| z.abs() < 4.5),
            "{name}: bias scores {scores:?}"
        );
        // The test can fail: half a pixel to the right, or 3 % of the weight lost.
        let half: Vec<[f64; 3]> = (0..other.len())
            .map(|p| {
                let q = if p % w > 0 { p - 1 } else { p };
                std::array::from_fn(|c| (other[p][c] + other[q][c]) / 2.0)
            })
            .collect();
        assert!(
            bias_scores(w, &mean, &half, &var)[1].abs() > 10.0,
            "{name}: a shift went unseen"
        );
        let dim: Vec<[f64; 3]> = other.iter().map(|v| v.map(|x| x * 0.97)).collect();
        assert!(
            bias_scores(w, &mean, &dim, &var)[0].abs() > 6.0,
            "{name}: a lost weight went unseen"
        );
    }
}

#[test]
fn the_same_arguments_give_the_same_bytes_for_any_thread_count_and_either_order() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let caustic = scene("tools/mitsuba/scenes/caustic.xml");
    let out = |name: &str, args: &[&str]| {
        let p = dir.path().join(name);
        let mut all = vec![
            caustic.as_str(),
            "-o",
            s(&p),
            "--size",
            "24x16",
            "--spp",
            "4",
            "--quiet",
        ];
        all.extend_from_slice(args);
        ok(tool(&py, "export.py", &all));
        std::fs::read(&p).unwrap()
    };
    let one = out("t1.pds", &["--threads", "1", "--seed", "5"]);
    let two = out("t2.pds", &["--threads", "2", "--seed", "5"]);
    assert!(one == two, "one thread and two wrote different dumps");
    assert!(
        out("s6.pds", &["--seed", "6"]) != one,
        "another seed wrote the same dump"
    );

    out("pixel.pds", &["--seed", "5", "--order", "pixel"]);
    let pass = DumpReader::open(dir.path().join("t1.pds")).unwrap();
    let pixel = DumpReader::open(dir.path().join("pixel.pds")).unwrap();
    assert_eq!(pixel.header().order, Order::PixelMajor);
    let (pixels, spp) = (24 * 16, 4);
    for (i, r) in pixel.records().iter().enumerate() {
        let (p, pass_index) = (i / spp, i % spp);
        assert_eq!(*r, pass.records()[pass_index * pixels + p], "record {i}");
    }
}

#[test]
fn the_shipped_scenes_export() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    for name in ["caustic", "glossy-highlight", "indirect-room"] {
        let p = dir.path().join(format!("{name}.pds"));
        let xml = scene(&format!("tools/mitsuba/scenes/{name}.xml"));
        ok(tool(
            &py,
            "export.py",
            &[
                &xml,
                "-o",
                s(&p),
                "--size",
                "16x12",
                "--spp",
                "2",
                "--quiet",
            ],
        ));
        let d = DumpReader::open(&p).unwrap();
        assert_eq!((d.header().width, d.header().height), (16, 12), "{name}");
        assert_eq!(d.header().scene, name);
        if name == "glossy-highlight" {
            // OIDN's auxiliary inputs, on the same film: albedo in [0, 1],
            // normals of unit length where something was hit.
            let (a, n) = (dir.path().join("a.exr"), dir.path().join("n.exr"));
            ok(tool(
                &py,
                "export.py",
                &[
                    &xml,
                    "-o",
                    s(&p),
                    "--size",
                    "16x12",
                    "--spp",
                    "1",
                    "--quiet",
                    "--albedo-out",
                    s(&a),
                    "--normal-out",
                    s(&n),
                    "--aux-spp",
                    "4",
                ],
            ));
            let (w, h, albedo) = pathdensity::io::exr::read_rgb(&a, 16 * 12).unwrap();
            assert_eq!((w, h), (16, 12));
            assert!(albedo.iter().flatten().all(|v| (0.0..=1.0).contains(v)));
            assert!(albedo.iter().any(|p| p.iter().any(|&v| v > 0.0)));
            let (_, _, normal) = pathdensity::io::exr::read_rgb(&n, 16 * 12).unwrap();
            let unit = normal
                .iter()
                .filter(|p| p.iter().any(|&v| v != 0.0))
                .filter(|p| ((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 1.0).abs() < 0.05)
                .count();
            assert!(
                unit > normal.len() / 2,
                "{unit} of {} normals are unit",
                normal.len()
            );
        }
        assert!(
            d.records()
                .iter()
                .all(|r| r.validity(d.header()) == Validity::Valid),
            "{name}"
        );
    }
}

#[test]
fn bad_scenes_get_one_line_and_no_dump() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let direct = std::fs::read_to_string(scene("tests/data/mitsuba/checker.xml"))
        .unwrap()
        .replace(
            r#"<integrator type="path">"#,
            r#"<integrator type="direct">"#,
        )
        .replace(r#"<integer name="max_depth" value="2"/>"#, "");
    let cases = [
        (write("notes.xml", "hello, not xml"), "not a Mitsuba scene"),
        (write("other.xml", "<svg></svg>"), "not a Mitsuba scene"),
        (
            write(
                "broken.xml",
                "<scene version=\"3.0.0\"><shape type=\"nosuch\"/></scene>",
            ),
            "cannot load",
        ),
        (write("direct.xml", &direct), "supports path and volpath"),
        (dir.path().join("missing.xml"), "no such file"),
    ];
    for (path, expected) in cases {
        let out = dir.path().join("out.pds");
        let o = tool(
            &py,
            "export.py",
            &[s(&path), "-o", s(&out), "--spp", "1", "--quiet"],
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
            err.contains(s(&path)) && err.contains(expected),
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
}

#[test]
fn an_output_that_is_the_scene_another_output_or_not_ours_is_refused_before_rendering() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name);
    let xml = p("scene.xml");
    std::fs::copy(scene("tests/data/mitsuba/checker.xml"), &xml).unwrap();
    let before = std::fs::read(&xml).unwrap();
    std::fs::write(p("notes.exr"), b"keep me").unwrap();
    let (a, b, n, notes) = (p("a.pds"), p("b.pds"), p("n.exr"), p("notes.exr"));
    // Each case's outputs, and the one its refusal names.
    let cases: [(Vec<&str>, &Path); 4] = [
        (vec!["-o", s(&xml)], &xml),
        (
            vec![
                "-o",
                s(&a),
                "--reference-spp",
                "1",
                "--reference-out",
                s(&a),
            ],
            &a,
        ),
        (
            vec!["-o", s(&b), "--albedo-out", s(&n), "--normal-out", s(&n)],
            &n,
        ),
        (
            vec![
                "-o",
                s(&b),
                "--reference-spp",
                "1",
                "--reference-out",
                s(&notes),
            ],
            &notes,
        ),
    ];
    for (outputs, named) in cases {
        let mut args = vec![s(&xml), "--spp", "1", "--quiet"];
        args.extend(outputs);
        let o = tool(&py, "export.py", &args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
        assert!(
            err.starts_with(&format!("export.py: {}: ", named.display())),
            "{args:?}: {err}"
        );
    }
    assert_eq!(std::fs::read(&xml).unwrap(), before);
    assert_eq!(std::fs::read(&notes).unwrap(), b"keep me");
    // Refused before anything was rendered or written.
    let mut left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    left.sort();
    assert_eq!(left, ["notes.exr", "scene.xml"]);
}
