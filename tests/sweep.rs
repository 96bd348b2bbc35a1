//! The sweep's bookkeeping: every configuration present, in order, failures
//! recorded with their reason, the baselines once, the files written.

use pathdensity::commands::sweep::sweep;
use pathdensity::io::exr;
use pathdensity::joint::white::White;
use pathdensity::recon::{Film, ReconFilter};
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
    let h = dense.header();
    let mut film = Film::new(&h, ReconFilter::Box);
    let mut occ = vec![0u32; h.pixels()];
    for r in dense.records() {
        film.splat(&r);
        occ[r.pixel_index(&h)] += 1;
    }
    exr::write_image(dir.path(), "ref", &film.resolve(&occ)).unwrap();

    let out = dir.path().join("sweep");
    let mut o = SweepOptions::new(&dump, dir.path().join("ref.exr"), &out);
    o.ks = vec![2, 5, 5000];
    o.sigma_colors = vec![50.0, 100.0];
    o.sigma_images = vec![3.0, 0.0];
    o.whites = vec![White::Fixed(1.0), White::Auto];
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
    let names: Vec<&str> = s.baselines.iter().map(|b| b.method.as_str()).collect();
    assert_eq!(names, ["mean", "median", "trimmed", "bilateral"]);

    let csv = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 24 + 4);
    assert_eq!(csv.matches("failed:").count(), 16);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("sweep.json")).unwrap()).unwrap();
    assert_eq!(json["rows"].as_array().unwrap().len(), 24);
    for f in ["rms_vs_time.svg", "rms_vs_k.svg"] {
        assert!(
            std::fs::read_to_string(out.join(f))
                .unwrap()
                .contains("<svg")
        );
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
