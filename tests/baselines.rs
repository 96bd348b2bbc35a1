//! The baselines of docs/filter.md §3 through the `filter` command: hand-computed
//! values read back from the EXRs, results independent of the dump's
//! order, and animations reconstructed frame by frame.

mod common;

use common::*;
use pathdensity::commands::filter::{FilterOptions, filter};
use pathdensity::config::Method;
use pathdensity::dump::Record;
use pathdensity::io::exr::{self, read_rgb};
use pathdensity::synth::SynthParams;

fn run(dump: &std::path::Path, out: &std::path::Path, alpha: f64) {
    let mut o = FilterOptions::new(dump, out);
    o.config.alpha = alpha;
    // The hand-made dumps hold fewer than the default k + 1 valid samples,
    // which `filter` refuses; the baselines do not depend on k.
    o.config.k = 2;
    o.html = false;
    o.config.methods = [Method::Median, Method::Trimmed, Method::Median3]
        .into_iter()
        .collect();
    filter(&o).unwrap();
}

fn pixels(path: &std::path::Path) -> Vec<[f64; 3]> {
    read_rgb(path, exr::MAX_PIXELS).unwrap().2
}

#[test]
fn median_and_trimmed_images_match_hand_computed_values() {
    let dir = tempfile::tempdir().unwrap();
    let h = header(2, 1, 1);
    // Pixel 0: red samples 1, 2, 4, 10, 20 (odd count); pixel 1: 1, 3, 5,
    // 100 (even count). An invalid record in between is ignored.
    let mut recs: Vec<Record> = [1.0, 2.0, 4.0, 10.0, 20.0]
        .iter()
        .map(|&v| Record::new(0.5, 0.5, 0.0, [v, 0.0, 0.0]))
        .collect();
    recs.push(Record::new(f32::NAN, 0.5, 0.0, [1e9, 0.0, 0.0]));
    recs.extend(
        [1.0, 3.0, 5.0, 100.0]
            .iter()
            .map(|&v| Record::new(1.5, 0.5, 0.0, [v, 0.0, 0.0])),
    );
    let dump = write_dump(dir.path(), "d.pds", &h, &recs);
    let out = dir.path().join("out");
    run(&dump, &out, 0.2);
    let median = pixels(&out.join("median.exr"));
    assert_eq!(median[0][0], 4.0);
    assert_eq!(median[1][0], 4.0); // (3 + 5) / 2
    let trimmed = pixels(&out.join("trimmed.exr"));
    // n = 5, ⌊0.2 · 5⌋ = 1 per end: (2 + 4 + 10) / 3; n = 4: ⌊0.8⌋ = 0.
    assert_eq!(trimmed[0][0], (16.0f64 / 3.0) as f32 as f64);
    assert_eq!(trimmed[1][0], 109.0 / 4.0);
    // The 3 × 3 median of a 2-pixel image: each window is both pixels.
    let mean = pixels(&out.join("mean.exr"));
    let m3 = pixels(&out.join("median3.exr"));
    let both = ((mean[0][0] + mean[1][0]) / 2.0) as f32 as f64;
    assert_eq!(m3[0][0], both);
    assert_eq!(m3[1][0], both);
    // α = 0: the trimmed mean is the mean.
    run(&dump, &out, 0.0);
    assert_eq!(
        pixels(&out.join("trimmed.exr")),
        pixels(&out.join("mean.exr"))
    );
}

#[test]
fn robust_images_do_not_depend_on_the_dump_order() {
    let dir = tempfile::tempdir().unwrap();
    let mut p = SynthParams {
        width: 24,
        height: 16,
        frames: 2,
        spp: 9,
        firefly_fraction: 0.05,
        ..SynthParams::default()
    };
    let a = dir.path().join("pixel.pds");
    p.write(&a).unwrap();
    p.order = pathdensity::dump::Order::PassMajor;
    let b = dir.path().join("pass.pds");
    p.write(&b).unwrap();
    let (oa, ob) = (dir.path().join("a"), dir.path().join("b"));
    run(&a, &oa, 0.1);
    run(&b, &ob, 0.1);
    for f in 0..2 {
        for name in ["median", "trimmed", "median3"] {
            let file = format!("{name}_{f:04}.exr");
            assert_eq!(
                std::fs::read(oa.join(&file)).unwrap(),
                std::fs::read(ob.join(&file)).unwrap(),
                "{file}"
            );
        }
    }
}

#[test]
fn bad_baseline_parameters_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let dump = write_dump(dir.path(), "d.pds", &header(1, 1, 1), &[]);
    for alpha in [0.5, -0.1, f64::NAN] {
        let mut o = FilterOptions::new(&dump, dir.path().join("o"));
        o.config.alpha = alpha;
        let e = filter(&o).unwrap_err().to_string();
        // The library names the field; the command line spells it --alpha.
        assert!(e.contains("alpha"), "{e}");
    }
    let mut o = FilterOptions::new(&dump, dir.path().join("o"));
    o.config.bilateral_sigma_r = 0.0;
    assert!(filter(&o).is_err());
}
