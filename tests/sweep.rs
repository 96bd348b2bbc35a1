//! The sweep's bookkeeping: every configuration present, in order, failures
//! recorded with their reason, the baselines once, the files written.

mod common;

use pathdensity::commands::sweep::sweep;
use pathdensity::io::exr;
use pathdensity::joint::white::White;
use pathdensity::sweep::SweepOptions;
use pathdensity::synth::SynthParams;

#[test]
fn every_configuration_is_a_row_and_failures_carry_their_reason() {
    let dir = tempfile::tempdir().unwrap();
    let p = SynthParams {
        width: 16,
        height: 12,
        spp: 8,
        firefly_fraction: 0.02,
        ..SynthParams::default()
    };
    let dump = dir.path().join("d.pds");
    p.write(&dump).unwrap();
    // Reference: the firefly-free field, densely sampled.
    let dense = SynthParams {
        spp: 64,
        firefly_fraction: 0.0,
        seed: 9,
        ..p.clone()
    };
    exr::write_image(dir.path(), "ref", &common::synth_mean(&dense)).unwrap();

    let out = dir.path().join("sweep");
    let mut o = SweepOptions::new(&dump, dir.path().join("ref.exr"), &out);
    o.ks = vec![2, 5, 5000];
    o.sigma_colors = vec![50.0, 100.0];
    o.sigma_images = vec![3.0, 0.0];
    o.whites = vec![White::Fixed(1.0), White::Auto];
    o.mon_groups = vec![3, 11];
    o.rwmc_kappas = vec![2.0, 32.0];
    o.clamps = vec![1.0, 10.0];
    let s = sweep(&o).unwrap();
    assert_eq!(s.rows.len(), 3 * 2 * 2 * 2);
    let mut n = 0;
    for w in ["1", "auto"] {
        for si in [3.0, 0.0] {
            for sc in [50.0, 100.0] {
                for k in [2, 5, 5000] {
                    let r = &s.rows[n];
                    assert_eq!(
                        (r.k, r.sigma_color, r.sigma_image, r.white.as_str()),
                        (k, sc, si, w)
                    );
                    let should_fail = k == 5000 || si == 0.0;
                    assert_eq!(r.failure.is_some(), should_fail, "{r:?}");
                    assert_eq!(r.metrics.is_some(), !should_fail);
                    if k == 5000 {
                        assert!(r.failure.as_ref().unwrap().contains("valid samples"));
                    } else if si == 0.0 {
                        assert!(r.failure.as_ref().unwrap().contains("sigma"), "{r:?}");
                    }
                    n += 1;
                }
            }
        }
    }
    // auto resolves to one white for the whole dump; the fixed one is 1.
    let autos: Vec<f64> = s
        .rows
        .iter()
        .filter(|r| r.white == "auto")
        .map(|r| r.white_value)
        .collect();
    assert!(autos.iter().all(|&v| v == autos[0] && v > 0.0 && v != 1.0));
    let names: Vec<&str> = s.baselines.iter().map(|b| b.label.as_str()).collect();
    // OIDN's baselines join where a library is found (`OIDN_DIR`, …).
    let oidn: &[&str] = match pathdensity::imagespace::oidn::available() {
        true => &["oidn", "oidn_ci"],
        false => &[],
    };
    let head = ["mean", "median", "trimmed", "bilateral"];
    assert_eq!(
        names,
        [
            &head[..],
            oidn,
            &[
                "mon groups=3",
                "gmon groups=3",
                "mon groups=11",
                "gmon groups=11",
                "rwmc kappa=2",
                "rwmc kappa=32",
                "clamp C=1",
                "clamp C=10"
            ]
        ]
        .concat()
    );

    // The labelled peer baselines are the same images `filter` makes with
    // those parameters.
    let mut f = pathdensity::commands::filter::FilterOptions::new(&dump, dir.path().join("f"));
    f.reference = Some(dir.path().join("ref.exr"));
    f.config.methods = [
        pathdensity::config::Method::Median,
        pathdensity::config::Method::Trimmed,
        pathdensity::config::Method::Mon,
        pathdensity::config::Method::Rwmc,
        pathdensity::config::Method::Clamp,
    ]
    .into_iter()
    .collect();
    f.html = false;
    let fr = pathdensity::commands::filter::filter(&f).unwrap();
    let by = |n: &str| s.baselines.iter().find(|b| b.label == n).unwrap().metrics;
    assert_eq!(by("median"), fr.metrics[&common::image("median")].pooled);
    assert_eq!(by("trimmed"), fr.metrics[&common::image("trimmed")].pooled);
    assert_eq!(
        by("mon groups=11"),
        fr.metrics[&common::image("mon")].pooled
    );
    assert_eq!(
        by("rwmc kappa=32"),
        fr.metrics[&common::image("rwmc")].pooled
    );
    assert_ne!(by("rwmc kappa=2"), by("rwmc kappa=32"));
    assert_eq!(by("clamp C=10"), fr.metrics[&common::image("clamp")].pooled);
    assert_ne!(by("clamp C=1"), by("clamp C=10"));
    let csv = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    // Two lines per configuration (filtered, filtered_energy), one per baseline.
    assert_eq!(csv.lines().count(), 1 + 2 * 24 + 12 + oidn.len());
    assert_eq!(csv.matches("failed:").count(), 2 * 16);
    let d = pathdensity::config::FilterConfig::DEFAULT;
    let energy_rows = format!("\nfiltered_energy,{},{},", d.final_pass, d.color_space);
    assert_eq!(csv.matches(&energy_rows).count(), 24);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("sweep.json")).unwrap()).unwrap();
    assert_eq!(json["rows"].as_array().unwrap().len(), 24);
    // Baselines keep their name under "method", their Method is not written.
    assert_eq!(json["baselines"][0]["method"], "mean");
    assert!(json["baselines"][0].get("image").is_none());
    // sweep.html's viewer: the lowest-FLIP row first, named in full, then
    // the reference, the lowest-RMS row (when another) and the mean.
    let html = std::fs::read_to_string(out.join("sweep.html")).unwrap();
    let data = common::viewer_data(&html);
    let names = common::viewer_names(&data);
    let lowest = |of: fn(&pathdensity::metrics::Metrics) -> f64| {
        let (i, r) = s
            .rows
            .iter()
            .enumerate()
            .filter(|(_, r)| r.metrics.is_some())
            .min_by(|a, b| of(&a.1.metrics.unwrap()).total_cmp(&of(&b.1.metrics.unwrap())))
            .unwrap();
        let label = format!(
            "filtered, {} k = {} σ_color = {} σ_image = {} white = {} final pass {}",
            r.color_space, r.k, r.sigma_color, r.sigma_image, r.white, r.final_pass
        );
        (i, label)
    };
    let (flip_row, flip_label) = lowest(|m| m.flip);
    let (rms_row, rms_label) = lowest(|m| m.rms);
    let mut want = vec![format!("lowest FLIP: {flip_label}"), "reference".into()];
    if rms_row != flip_row {
        want.push(format!("lowest RMS: {rms_label}"));
    }
    want.push("mean".into());
    assert_eq!(names, want);
    assert_eq!(data["recommended"], 0);
    assert_eq!(data["reference"], 1);
    for f in ["rms_vs_time.svg", "rms_vs_k.svg", "flip_vs_k.svg"] {
        assert!(
            std::fs::read_to_string(out.join(f))
                .unwrap()
                .contains("<svg")
        );
    }
    // The PNG plots decode, at the plot size, and are not blank.
    for f in ["rms_vs_time.png", "rms_vs_k.png", "flip_vs_k.png"] {
        let img = image::open(out.join(f)).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (800, 500));
        let dark = img.pixels().filter(|p| p.0.iter().all(|&c| c < 80)).count();
        assert!(dark > 1000, "{f}: {dark} dark pixels");
    }
    // The Pareto front: non-empty, only successful rows, none dominated.
    let front = s.pareto();
    assert!(!front.is_empty());
    for &i in &front {
        let (t, e) = (s.rows[i].seconds, s.rows[i].metrics.unwrap().rms);
        assert!(
            !s.rows
                .iter()
                .any(|r| r.metrics.is_some_and(|m| r.seconds < t && m.rms < e))
        );
    }
}

/// `sweep --equal-time`: the first m passes of a pass-major dump are an
/// m-spp render, so every row must equal `filter` run on a dump holding
/// only those passes; the mean's pass count is the most that fits the time.
#[test]
fn equal_time_rows_are_prefix_renders_at_matching_time() {
    use pathdensity::commands::filter::{FilterOptions, filter};
    use pathdensity::config::Method;
    use pathdensity::dump::{DumpReader, DumpWriter};
    let fixture =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/glossy-room-pass");
    let dir = tempfile::tempdir().unwrap();
    let o = SweepOptions::new(
        fixture.join("dump.pds"),
        fixture.join("reference.exr"),
        dir.path().join("eq"),
    );
    let prefix_metrics = |m: u32, name: &str| {
        let dump = DumpReader::open(fixture.join("dump.pds")).unwrap();
        let mut h = dump.header().clone();
        let n = m as usize * h.pixels();
        h.spp = m;
        h.sample_count = n as u64;
        let path = dir.path().join(format!("prefix{m}.pds"));
        let mut w = DumpWriter::create(&path, h).unwrap();
        w.push_all(&dump.records()[..n]).unwrap();
        w.finish().unwrap();
        let mut f = FilterOptions::new(&path, dir.path().join(format!("f{m}")));
        f.reference = Some(fixture.join("reference.exr"));
        f.config.methods = [
            Method::Mean,
            Method::Filtered,
            Method::FilteredEnergy,
            Method::Mon,
            Method::Gmon,
            Method::Rwmc,
            Method::Clamp,
        ]
        .into_iter()
        .collect();
        f.html = false;
        filter(&f).unwrap().metrics[&common::image(name)].pooled
    };

    // OIDN's peers join where a library is found (`OIDN_DIR`, …).
    let oidn: &[&str] = match pathdensity::imagespace::oidn::available() {
        true => &["oidn", "oidn_ci"],
        false => &[],
    };
    // Rendering dominates (1e6 s for 8 passes): the mean gets as many
    // passes as the filter, capped at the dump's 8.
    let slow = pathdensity::sweep::equal_time(&o, 1e6, &pathdensity::progress::Silent).unwrap();
    let spps: Vec<u32> = slow.iter().map(|r| r.spp).collect();
    assert_eq!(spps, [1, 2, 4, 8]);
    for r in &slow {
        assert_eq!(r.mean_spp, r.spp);
        assert_eq!(r.filtered, prefix_metrics(r.spp, "filtered"), "{r:?}");
        assert_eq!(r.mean, prefix_metrics(r.mean_spp, "mean"), "{r:?}");
        assert_eq!(
            r.filtered_energy,
            prefix_metrics(r.spp, "filtered_energy"),
            "{r:?}"
        );
        let names: Vec<&str> = r.peers.iter().map(|p| p.0.as_str()).collect();
        assert_eq!(
            names,
            [
                &[
                    "mon groups=11",
                    "gmon groups=11",
                    "rwmc kappa=32",
                    "clamp C=10"
                ][..],
                oidn
            ]
            .concat()
        );
        for ((_, m), method) in r.peers.iter().zip(["mon", "gmon", "rwmc", "clamp"]) {
            assert_eq!(*m, prefix_metrics(r.mean_spp, method), "{method}");
        }
        assert!(r.mean_seconds <= r.filtered_seconds);
    }
    // Rendering is nearly free: the filter's time buys the mean every pass.
    let fast = pathdensity::sweep::equal_time(&o, 1e-9, &pathdensity::progress::Silent).unwrap();
    assert!(fast.iter().all(|r| r.mean_spp == 8));
    // A pixel-major dump has no prefix renders: refused by name.
    let e = pathdensity::sweep::equal_time(
        &SweepOptions::new(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/glossy-room/dump.pds"),
            fixture.join("reference.exr"),
            dir.path().join("eq2"),
        ),
        1.0,
        &pathdensity::progress::Silent,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("glossy-room/dump.pds") && e.contains("pass-major"),
        "{e}"
    );
}

/// A sweep whose every configuration fails still writes its table (with
/// each reason) but reports failure.
#[test]
fn a_sweep_where_every_configuration_fails_is_an_error() {
    let fixture = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/glossy-room");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sw");
    let mut o = SweepOptions::new(
        fixture.join("dump.pds"),
        fixture.join("reference.exr"),
        &out,
    );
    o.ks = vec![100_000];
    o.sigma_colors = vec![100.0];
    o.sigma_images = vec![3.0];
    let e = sweep(&o).unwrap_err().to_string();
    assert!(e.contains("every configuration failed"), "{e}");
    let csv = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    assert!(csv.contains("valid samples"), "{csv}");
}
