//! Numerical stability at the extremes: absurd radiance, every
//! non-finite field, coordinates on and beyond the edges, extreme k and σ,
//! tiny and empty films, a million identical samples, many frames. Nothing
//! panics, every output pixel is finite, the counts are right, and the
//! decisions on the valid records are the oracle's.

mod common;

use std::path::Path;

use common::*;
use pathdensity::commands::filter::{FilterOptions, filter};
use pathdensity::config::{FilterConfig, FinalPass, MethodSet, White};
use pathdensity::density::{self, IndexKind, ReplayOptions};
use pathdensity::dump::{Header, Record};
use pathdensity::io::exr::{self, read_rgb};
use pathdensity::joint::JointSpace;
use pathdensity::progress::Silent;
use pathdensity::report::FilterReport;

/// Runs `filter` with every method and the HTML report, and checks the
/// invariants every case shares. Returns the report and the decisions.
fn run(h: &Header, recs: &[Record], k: usize, space: JointSpace) -> (FilterReport, Vec<u8>) {
    let dir = tempfile::tempdir().unwrap();
    let dump = write_dump(dir.path(), "d.pds", h, recs);
    let out = dir.path().join("out");
    let mut o = FilterOptions::new(&dump, &out);
    o.config.k = k;
    o.config.sigma_image = space.sigma_image;
    o.config.sigma_color = space.sigma_color;
    o.config.sigma_time = space.sigma_time;
    o.config.white = White::Fixed(space.white);
    o.config.color_space = space.color;
    o.config.methods = MethodSet::NO_OIDN;
    // The oracle is the paper's replay.
    o.config.final_pass = FinalPass::Stored;
    o.decisions = Some(dir.path().join("dec"));
    let report = filter(&o).unwrap();
    let decisions = std::fs::read(dir.path().join("dec")).unwrap();
    assert_eq!(decisions.len(), recs.len());
    // Decisions and counts are the oracle's.
    let (want, _) = oracle(recs, h, k, &space);
    assert_eq!(decisions, want, "decisions differ from the oracle");
    let c = &report.counts;
    let count = |b: u8| decisions.iter().filter(|&&d| d == b).count() as u64;
    assert_eq!(c.records, recs.len() as u64);
    assert_eq!(c.valid + c.invalid.total(), c.records);
    assert_eq!(c.invalid.total(), count(0));
    assert_eq!(c.accepted_streaming, count(1));
    assert_eq!(c.accepted_final, count(2));
    assert_eq!(c.rejected, count(3));
    all_exr_finite(&out);
    (report, decisions)
}

fn all_exr_finite(dir: &Path) {
    let mut n = 0;
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "exr") {
            let (_, _, px) = read_rgb(&p, exr::MAX_PIXELS).unwrap();
            assert!(
                px.iter().flatten().all(|v| v.is_finite()),
                "{} holds a non-finite pixel",
                p.display()
            );
            n += 1;
        }
    }
    assert!(n >= 7, "every image written");
}

/// A dense field of `n` samples per pixel with values from `value`.
fn field(w: u32, h: u32, n: u32, mut value: impl FnMut(u32) -> [f32; 3]) -> Vec<Record> {
    let mut rng = Rng(7);
    let mut v = Vec::new();
    for j in 0..h {
        for i in 0..w {
            for s in 0..n {
                let (x, y) = (i as f32 + rng.f32() * 0.99, j as f32 + rng.f32() * 0.99);
                v.push(Record::new(x, y, 0.0, value(s)));
            }
        }
    }
    v
}

#[test]
fn absurd_radiance_is_filtered_and_every_output_stays_finite() {
    let h = header(6, 5, 1);
    let values = [
        1e-30,
        f32::from_bits(1), // the smallest subnormal
        1.0e-40,
        0.5,
        1e30,
        3.4e38,
        f32::MAX,
        -1.0,
        -3.0e38,
        -f32::MAX,
    ];
    let recs = field(6, 5, 12, |s| {
        let v = values[s as usize % values.len()];
        [v, 0.5 * v, -v]
    });
    let (report, _) = run(&h, &recs, 10, JointSpace::PAPER);
    assert_eq!(report.counts.valid, recs.len() as u64);
}

#[test]
fn a_non_finite_value_in_any_field_makes_the_record_invalid() {
    let h = header(4, 4, 1);
    let mut recs = field(4, 4, 8, |_| [0.5, 0.4, 0.3]);
    let mut bad = 0;
    for field in 0..6 {
        for v in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let mut r = Record::new(1.5, 1.5, 0.0, [0.5, 0.4, 0.3]);
            let mut f = [r.x, r.y, r.t, r.r, r.g, r.b];
            f[field] = v;
            r = Record::new(f[0], f[1], f[2], [f[3], f[4], f[5]]);
            recs.insert(3 * bad + 1, r);
            bad += 1;
        }
    }
    let (report, _) = run(&h, &recs, 10, JointSpace::PAPER);
    assert_eq!(report.counts.invalid.non_finite, 18);
    assert_eq!(report.counts.invalid.total(), 18);
}

#[test]
fn coordinates_on_and_beyond_the_film_and_time_edges() {
    let h = header(3, 2, 2);
    let w = 3.0f32;
    let below = |v: f32| v.next_down();
    let cases = [
        // (x, y, t, valid?)
        (0.0, 0.0, 0.0, true),
        (-0.0, -0.0, -0.0, true),
        (below(w), below(2.0), below(2.0), true),
        (w, 0.5, 0.5, false),
        (0.5, 2.0, 0.5, false),
        (0.5, 0.5, 2.0, false),
        (-1e-45, 0.5, 0.5, false),
        (0.5, -1e-45, 0.5, false),
        (0.5, 0.5, -1e-45, false),
        (1e30, 0.5, 0.5, false),
    ];
    let mut recs = Vec::new();
    for _ in 0..3 {
        for &(x, y, t, _) in &cases {
            recs.push(Record::new(x, y, t, [0.2, 0.2, 0.2]));
        }
    }
    let (report, dec) = run(&h, &recs, 2, JointSpace::PAPER);
    for (i, &(_, _, _, valid)) in cases.iter().cycle().take(recs.len()).enumerate() {
        assert_eq!(dec[i] != 0, valid, "case {i}");
    }
    assert_eq!(report.counts.invalid.outside_film, 3 * 5);
    assert_eq!(report.counts.invalid.outside_time, 3 * 2);
}

#[test]
fn k_of_one_and_k_above_the_sample_count() {
    let h = header(5, 5, 1);
    let recs = field(5, 5, 4, |s| [0.3 + 0.01 * s as f32, 0.3, 0.2]);
    run(&h, &recs, 1, JointSpace::PAPER);
    // k ≥ N: every σ is +∞, so the replay stores and rejects every sample…
    let options = ReplayOptions::default();
    let space = JointSpace::PAPER;
    let dec = density::run(&recs, &h, &space, 1000, IndexKind::Grid, &options, &Silent);
    assert!(dec.decisions.iter().all(|&d| d == 3));
    // … which `filter` refuses before any work, naming k and the count.
    let e = filter_error(&h, &recs, 100);
    assert!(e.contains("k 100 needs more than 100 valid samples"), "{e}");
}

/// Runs `filter` on `recs` with `k`, expecting a refusal; returns it.
fn filter_error(h: &Header, recs: &[Record], k: usize) -> String {
    let dir = tempfile::tempdir().unwrap();
    let dump = write_dump(dir.path(), "d.pds", h, recs);
    let mut o = FilterOptions::new(&dump, dir.path().join("out"));
    o.config.k = k;
    let e = format!("{:#}", filter(&o).unwrap_err());
    assert!(!dir.path().join("out").exists(), "nothing written");
    e
}

#[test]
fn extreme_sigmas() {
    let h = header(5, 4, 1);
    let recs = field(5, 4, 6, |s| [0.1 * s as f32, 0.2, 0.05 * s as f32]);
    for si in [1e-6, 1e9] {
        for sc in [1e-6, 1e9] {
            let space = JointSpace {
                sigma_image: si,
                sigma_color: sc,
                ..JointSpace::PAPER
            };
            run(&h, &recs, 3, space);
        }
    }
}

#[test]
fn tiny_and_empty_films() {
    let one = header(1, 1, 1);
    run(
        &one,
        &field(1, 1, 5, |_| [1.0, 1.0, 1.0]),
        2,
        JointSpace::PAPER,
    );
    let e = filter_error(&one, &[Record::new(0.5, 0.5, 0.0, [2.0, 1.0, 0.0])], 10);
    assert!(e.contains("needs more than 1 valid samples"), "{e}");
    // A dump with no valid sample is an error, not a black image.
    let e = filter_error(&header(4, 3, 1), &[], 10);
    assert!(e.contains("no valid sample"), "{e}");
    let nan = [Record::new(0.5, 0.5, 0.0, [f32::NAN, 1.0, 0.0]); 20];
    let e = filter_error(&one, &nan, 10);
    assert!(e.contains("no valid sample"), "{e}");
}

#[test]
fn a_million_identical_samples_reject_exactly_k() {
    let h = header(2, 2, 1);
    let recs = vec![Record::new(0.5, 0.5, 0.0, [0.7, 0.1, 0.9]); 1_000_000];
    let dir = tempfile::tempdir().unwrap();
    let dump = write_dump(dir.path(), "d.pds", &h, &recs);
    let mut o = FilterOptions::new(&dump, dir.path().join("out"));
    o.html = false;
    // The paper's final pass: the first k stored never see k others.
    o.config = FilterConfig {
        methods: MethodSet::NO_OIDN,
        ..FilterConfig::PAPER
    };
    let report = filter(&o).unwrap();
    assert_eq!(report.counts.rejected, 10);
    assert_eq!(report.counts.stored, 10);
    assert_eq!(report.counts.accepted_streaming, 1_000_000 - 10);
    all_exr_finite(&dir.path().join("out"));
}

#[test]
fn one_frame_and_many_frames() {
    let mut recs = Vec::new();
    let mut rng = Rng(3);
    for f in 0..300u32 {
        for _ in 0..4 {
            recs.push(Record::new(
                rng.f32(),
                rng.f32(),
                f as f32 + 0.5,
                [0.5, 0.5, 0.5],
            ));
        }
    }
    let (report, _) = run(&header(1, 1, 300), &recs, 5, JointSpace::PAPER);
    assert_eq!(report.metrics.len(), 0);
    assert_eq!(report.counts.valid, 1200);
}
