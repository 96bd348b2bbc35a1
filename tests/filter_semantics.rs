//! docs/filter.md §2 behaviours, each pinned by a small dump with a known answer,
//! and every index checked against the brute-force oracle.

mod common;

use common::*;
use pathdensity::density::{self, ExactSigma, IndexKind, ReplayOptions};
use pathdensity::dump::{Order, Record};
use pathdensity::joint::JointSpace;
use pathdensity::progress::Silent;
use pathdensity::synth::SynthParams;

const INDEXES: [IndexKind; 2] = [IndexKind::Grid, IndexKind::Kdtree];

/// What one replay runs with.
struct Params {
    k: usize,
    space: JointSpace,
    index: IndexKind,
    options: ReplayOptions,
}

fn params(k: usize, space: JointSpace, index: IndexKind, exact: bool) -> Params {
    let exact = if exact {
        ExactSigma::All
    } else {
        ExactSigma::None
    };
    sampled(k, space, index, exact)
}

fn sampled(k: usize, space: JointSpace, index: IndexKind, exact: ExactSigma) -> Params {
    let options = ReplayOptions {
        exact_sigma: exact,
        batch: 300,
        deferral: None,
    };
    Params {
        k,
        space,
        index,
        options,
    }
}

fn run(recs: &[Record], h: &pathdensity::dump::Header, p: &Params) -> density::FilterResult {
    density::run(recs, h, &p.space, p.k, p.index, &p.options, &Silent)
}

/// A smooth grey field, `spp` jittered samples per pixel, in pixel-major order.
fn smooth_field(w: u32, h: u32, spp: u32, seed: u64) -> Vec<Record> {
    let mut rng = Rng(seed);
    let mut v = Vec::new();
    for j in 0..h {
        for i in 0..w {
            for _ in 0..spp {
                let c = 0.5 + 0.05 * rng.f32();
                v.push(Record::new(
                    i as f32 + rng.f32(),
                    j as f32 + rng.f32(),
                    0.0,
                    [c, c, c],
                ));
            }
        }
    }
    v
}

#[test]
fn a_lone_firefly_in_a_dense_smooth_field_is_rejected() {
    let h = header(24, 24, 1);
    let mut recs = smooth_field(24, 24, 16, 1);
    let at = recs.len() / 2;
    recs.insert(at, Record::new(12.3, 12.6, 0.0, [80.0, 75.0, 60.0]));
    for index in INDEXES {
        let r = run(&recs, &h, &params(10, JointSpace::default(), index, false));
        assert_eq!(r.decisions[at], REJECTED, "{index:?}");
        // The smooth field is almost entirely kept.
        assert!(r.counts.rejected < 40, "{index:?}: {:?}", r.counts);
    }
}

#[test]
fn a_dense_bright_patch_is_kept() {
    // A 3 × 3-pixel light of radiance 20 (L* ≈ 330) seen by 64 spp: far
    // from its surroundings in colour, but dense.
    let p = SynthParams {
        width: 32,
        height: 32,
        spp: 64,
        firefly_fraction: 0.0,
        light: Some((14, 14, 3, 20.0)),
        ..SynthParams::default()
    };
    let h = p.header();
    let recs: Vec<Record> = p.records().collect();
    let r = run(
        &recs,
        &h,
        &params(10, JointSpace::default(), IndexKind::Grid, false),
    );
    let light: Vec<usize> = (0..recs.len()).filter(|&i| recs[i].r > 10.0).collect();
    assert_eq!(light.len(), 9 * 64);
    let kept = light
        .iter()
        .filter(|&&i| r.decisions[i] != REJECTED)
        .count();
    assert!(
        kept >= light.len() - 10,
        "kept {kept} of {} light samples",
        light.len()
    );
}

#[test]
fn with_huge_sigma_color_decisions_ignore_colour_and_filtered_equals_mean_where_nothing_was_lost() {
    let h = header(16, 16, 1);
    let a = smooth_field(16, 16, 12, 7);
    let mut rng = Rng(99);
    let b: Vec<Record> = a
        .iter()
        .map(|r| {
            let g = if rng.f32() < 0.05 { 500.0 } else { 1.0 };
            Record::new(
                r.x,
                r.y,
                r.t,
                [r.r * g * rng.f32(), r.g * g, r.b * 3.0 * rng.f32()],
            )
        })
        .collect();
    let space = JointSpace {
        sigma_color: 1e9,
        ..JointSpace::default()
    };
    let p = params(10, space, IndexKind::Grid, false);
    let ra = run(&a, &h, &p);
    let rb = run(&b, &h, &p);
    assert_eq!(ra.decisions, rb.decisions);
    assert!(
        rb.counts.rejected > 0,
        "some samples must be lost for the test to bite"
    );
    let rec = pathdensity::recon::reconstruct(&b, &h, pathdensity::recon::ReconFilter::Box, |i| {
        density::Decision::accepted(rb.decisions[i])
    });
    let mut lost = vec![false; 256];
    for (i, r) in b.iter().enumerate() {
        if rb.decisions[i] == REJECTED {
            lost[r.pixel_index(&h)] = true;
        }
    }
    let mut compared = 0;
    for (px, &lost) in lost.iter().enumerate() {
        if !lost {
            assert_eq!(rec.filtered.data[px], rec.mean.data[px], "pixel {px}");
            compared += 1;
        }
    }
    assert!(compared > 100);
}

#[test]
fn n_identical_copies_of_an_isolated_sample_reject_exactly_k() {
    let h = header(64, 64, 1);
    for (n, k) in [(11, 10), (25, 10), (60, 50), (4, 3), (2, 1)] {
        let recs = vec![Record::new(20.5, 30.5, 0.0, [0.3, 0.2, 0.1]); n];
        for index in INDEXES {
            let r = run(&recs, &h, &params(k, JointSpace::default(), index, true));
            assert_eq!(r.counts.rejected, k as u64, "n={n} k={k} {index:?}");
            assert_eq!(r.counts.stored, k as u64);
            // The first k were stored; the rest were accepted at σ = 0.
            assert!(r.decisions[..k].iter().all(|&d| d == REJECTED));
            assert!(r.decisions[k..].iter().all(|&d| d == STREAM));
        }
    }
}

/// σ_image = 1 and colour ignored: joint distances are pixel distances.
fn line_space() -> JointSpace {
    JointSpace {
        sigma_image: 1.0,
        sigma_color: 1e12,
        ..JointSpace::default()
    }
}

#[test]
fn sigma_is_the_mean_over_exactly_the_k_nearest() {
    // Points on a line at known distances.
    let h = header(64, 1, 1);
    let space = line_space();
    let at = |x: f32| Record::new(x, 0.5, 0.0, [0.5, 0.5, 0.5]);
    // T = {10, 11.5, 14}; the query at 10.25 has distances 0.25, 1.25, 3.75.
    // k = 2: σ = 0.75 < 1 (accepted); k = 3: σ = 1.75 (stored).
    let recs = [at(10.0), at(11.5), at(14.0), at(10.25)];
    for index in INDEXES {
        let r2 = run(&recs, &h, &params(2, space, index, true));
        let s2 = r2.sigma.as_ref().unwrap().to_dense(recs.len());
        assert_eq!(r2.decisions[3], STREAM, "{index:?}");
        assert_eq!(s2[3], (0.25 + 1.25) / 2.0);
        let r3 = run(&recs, &h, &params(3, space, index, true));
        let s3 = r3.sigma.as_ref().unwrap().to_dense(recs.len());
        // Stored, then judged in the final pass against {10, 11.5, 14}.
        assert_eq!(s3[3], (0.25 + 1.25 + 3.75) / 3.0);
        assert_eq!(r3.decisions[3], REJECTED);
        // The first sample's final-pass σ is over the three others only.
        assert_eq!(s3[0], (0.25 + 1.5 + 4.0) / 3.0);
    }
}

#[test]
fn the_final_pass_excludes_the_sample_itself() {
    // k = 1: s0 is stored (T empty); s1 lies 0.5 away and is accepted.
    // In the final pass s0 sees T \ {s0} = ∅, so σ = +∞ and it is rejected;
    // counting itself at distance 0 would wrongly accept it.
    let h = header(16, 1, 1);
    let space = line_space();
    let recs = [
        Record::new(3.0, 0.5, 0.0, [1.0; 3]),
        Record::new(3.5, 0.5, 0.0, [1.0; 3]),
    ];
    for index in INDEXES {
        let r = run(&recs, &h, &params(1, space, index, true));
        assert_eq!(r.decisions, vec![REJECTED, STREAM], "{index:?}");
        assert_eq!(r.sigma.as_ref().unwrap().get(0), f64::INFINITY);
    }
}

#[test]
fn the_last_sample_inserted_is_always_rejected() {
    let h = header(8, 8, 1);
    let mut rng = Rng(5);
    for trial in 0..20 {
        let recs: Vec<Record> = (0..200)
            .map(|_| {
                let c = rng.f32() * 3.0;
                Record::new(rng.f32() * 8.0, rng.f32() * 8.0, 0.0, [c, c * 0.5, 0.2])
            })
            .collect();
        let r = run(
            &recs,
            &h,
            &params(5, JointSpace::default(), IndexKind::Grid, false),
        );
        let last_stored = (0..recs.len())
            .rev()
            .find(|&i| r.decisions[i] == REJECTED || r.decisions[i] == FINAL)
            .unwrap();
        assert_eq!(r.decisions[last_stored], REJECTED, "trial {trial}");
        assert!(r.counts.rejected >= 1);
    }
}

#[test]
fn invalid_records_are_counted_by_reason_and_ignored() {
    let h = header(16, 16, 1);
    let clean = smooth_field(16, 16, 8, 3);
    let bad = [
        Record::new(f32::NAN, 1.0, 0.0, [1.0; 3]),
        Record::new(1.0, 1.0, 0.0, [f32::INFINITY, 0.0, 0.0]),
        Record::new(16.0, 1.0, 0.0, [1.0; 3]),
        Record::new(-0.001, 1.0, 0.0, [1.0; 3]),
        Record::new(1.0, 1.0, 1.0, [1.0; 3]),
        Record::new(1.0, 1.0, -1e-30, [1.0; 3]),
    ];
    let mut mixed = Vec::new();
    let mut bad_at = Vec::new();
    for (i, r) in clean.iter().enumerate() {
        if i % 300 == 0 && bad_at.len() < bad.len() {
            bad_at.push(mixed.len());
            mixed.push(bad[bad_at.len() - 1]);
        }
        mixed.push(*r);
    }
    let p = params(10, JointSpace::default(), IndexKind::Grid, false);
    let rc = run(&clean, &h, &p);
    let rm = run(&mixed, &h, &p);
    assert_eq!(rm.counts.invalid.non_finite, 2);
    assert_eq!(rm.counts.invalid.outside_film, 2);
    assert_eq!(rm.counts.invalid.outside_time, 2);
    assert_eq!(rm.counts.valid, clean.len() as u64);
    let kept: Vec<u8> = rm
        .decisions
        .iter()
        .enumerate()
        .filter(|(i, _)| !bad_at.contains(i))
        .map(|(_, &d)| d)
        .collect();
    assert_eq!(kept, rc.decisions);
    assert!(bad_at.iter().all(|&i| rm.decisions[i] == INVALID));
}

/// Random dumps in both orders, stills and animations: every index, in
/// both goals, agrees with the oracle on every decision and every σ.
#[test]
fn every_index_matches_the_brute_force_oracle() {
    for (seed, frames, order, centre, k) in [
        (1, 1, Order::PixelMajor, false, 10),
        (2, 1, Order::PassMajor, false, 10),
        (3, 3, Order::PixelMajor, false, 5),
        (4, 1, Order::PixelMajor, true, 50),
        (5, 2, Order::PassMajor, true, 20),
    ] {
        let p = SynthParams {
            width: 20,
            height: 14,
            frames,
            spp: 9,
            order,
            firefly_fraction: 0.03,
            pixel_centre: centre,
            seed,
            ..SynthParams::default()
        };
        let h = p.header();
        let recs: Vec<Record> = p.records().collect();
        // Every colour space, in turn.
        let space = JointSpace {
            sigma_image: 1.5,
            sigma_color: 40.0,
            sigma_time: 1.0,
            white: 1.0,
            color: pathdensity::joint::ColorSpace::ALL[seed as usize % 3],
        };
        let (od, os) = oracle(&recs, &h, k, &space);
        // The library's plain replay (the specification) is the oracle's.
        let plain = density::plain::replay(&recs, &h, &space, k);
        assert_eq!(plain.decisions, od, "seed {seed} plain");
        let ps = plain.sigma.as_ref().unwrap().to_dense(recs.len());
        assert!(ps.iter().zip(&os).all(|(a, b)| a.to_bits() == b.to_bits()));
        for index in INDEXES {
            let exact = run(&recs, &h, &params(k, space, index, true));
            assert_eq!(exact.counts, plain.counts, "seed {seed} {index:?} counts");
            assert_eq!(exact.decisions, od, "seed {seed} {index:?} exact");
            let s = exact.sigma.unwrap().to_dense(recs.len());
            for i in 0..recs.len() {
                assert!(
                    s[i].to_bits() == os[i].to_bits(),
                    "seed {seed} {index:?}: σ of record {i}: {} vs oracle {}",
                    s[i],
                    os[i]
                );
            }
            let fast = run(&recs, &h, &params(k, space, index, false));
            assert_eq!(fast.decisions, od, "seed {seed} {index:?} decide");
            // The report's σ map: exact σ of one record in 3, NaN elsewhere.
            let share = ExactSigma::OneIn(3);
            let some = run(&recs, &h, &sampled(k, space, index, share));
            assert_eq!(some.decisions, od, "seed {seed} {index:?} one in 3");
            let s = some.sigma.unwrap().to_dense(recs.len());
            let wanted = (0..recs.len()).filter(|&i| share.wants(i)).count();
            assert!(
                wanted > recs.len() / 4 && wanted < recs.len() / 2,
                "{wanted}"
            );
            for i in 0..recs.len() {
                let want = if share.wants(i) { os[i] } else { f64::NAN };
                assert_eq!(
                    s[i].to_bits(),
                    want.to_bits(),
                    "seed {seed} {index:?} record {i}"
                );
            }
        }
    }
}

#[test]
fn pixel_centre_dumps_filter_identically_on_every_index() {
    // More than a kiddo bucket (32) of stored samples share each (x, y).
    let p = SynthParams {
        width: 6,
        height: 6,
        spp: 120,
        pixel_centre: true,
        firefly_fraction: 0.02,
        ..SynthParams::default()
    };
    let h = p.header();
    let recs: Vec<Record> = p.records().collect();
    let space = JointSpace {
        sigma_color: 5.0,
        ..JointSpace::default()
    };
    let (od, _) = oracle(&recs, &h, 50, &space);
    for index in INDEXES {
        let r = run(&recs, &h, &params(50, space, index, false));
        assert_eq!(r.decisions, od, "{index:?}");
        assert!(r.counts.stored > 32 * 4, "{:?}", r.counts);
        assert!(r.counts.accepted_streaming > 0);
    }
}

/// A small pass-major dump with 2% fireflies: every parallel path (lagging
/// T, rechecks, deferrals, seed caches) is exercised within a few batches.
fn small_pass_major() -> SynthParams {
    SynthParams {
        width: 40,
        height: 30,
        spp: 16,
        order: Order::PassMajor,
        firefly_fraction: 0.02,
        ..SynthParams::default()
    }
}

/// Runs `f` on a rayon pool of `threads` threads.
fn on_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

/// Neither the thread count, the batch size nor the share of searches the
/// in-order pass takes over (none, all, or adapted to the timings) changes
/// a bit of the result: the parallel path (search the lagging T, recheck
/// in order) and the in-order one (search the current T) are both exact.
#[test]
fn results_do_not_depend_on_the_thread_count_batch_size_or_deferral() {
    let p = small_pass_major();
    let h = p.header();
    let recs: Vec<Record> = p.records().collect();
    for exact in [true, false] {
        let mut base = None;
        for threads in [1, 2, 8] {
            for batch in [256, 5000] {
                for deferral in [None, Some(0.0), Some(0.5), Some(1.0)] {
                    let mut prm = params(10, JointSpace::default(), IndexKind::Grid, exact);
                    prm.options.batch = batch;
                    prm.options.deferral = deferral;
                    let r = on_threads(threads, || run(&recs, &h, &prm));
                    let bits: Option<Vec<u64>> = r
                        .sigma
                        .map(|s| s.to_dense(recs.len()).iter().map(|s| s.to_bits()).collect());
                    let got = (r.decisions, bits, r.counts);
                    match &base {
                        None => {
                            // The first run is the plain replay's.
                            let plain = density::plain::replay(&recs, &h, &prm.space, 10);
                            assert_eq!(got.0, plain.decisions);
                            assert_eq!(got.2, plain.counts);
                            if let Some(bits) = &got.1 {
                                // Every σ the replay kept is the plain
                                // replay's, bit for bit (and every later
                                // run must equal this one).
                                let want = plain.sigma.as_ref().unwrap().to_dense(recs.len());
                                assert_eq!(bits.len(), want.len());
                                assert!(bits.iter().zip(&want).all(|(a, b)| *a == b.to_bits()));
                            }
                            base = Some(got)
                        }
                        Some(b) => assert!(
                            b == &got,
                            "exact {exact} threads {threads} batch {batch} deferral {deferral:?}"
                        ),
                    }
                }
            }
        }
    }
}

/// Seeds are cached by pixel on small films and by grid cell on large ones
/// (pixels × k over 2^25, or fewer than two samples a pixel: both hold for
/// the large film here, which holds the records in its corner): the same
/// records give the same decisions either way, on any thread count.
#[test]
fn decisions_do_not_depend_on_how_seeds_are_cached() {
    let p = small_pass_major();
    let small = p.header();
    let mut large = small.clone();
    (large.width, large.height) = (4096, 1024);
    let recs: Vec<Record> = p.records().collect();
    let prm = params(10, JointSpace::default(), IndexKind::Grid, false);
    let mut base = None;
    for h in [&small, &large] {
        for threads in [1, 2, 8] {
            let r = on_threads(threads, || run(&recs, h, &prm));
            let got = (r.decisions, r.counts);
            match &base {
                None => base = Some(got),
                Some(b) => assert!(b == &got, "{}x{} threads {threads}", h.width, h.height),
            }
        }
    }
}

#[test]
fn synthetic_samples_lie_inside_their_pixel_for_any_seed() {
    // Near x = 8192 the f32 spacing is 2^-10, so a jitter above 1 − 2^-11
    // rounds i + jitter up to i + 1 unless the generator prevents it (it
    // did not: the benchmark dump held one record outside the film). A
    // seed near 2^64 used to overflow the stream key.
    for seed in [1, u64::MAX] {
        let p = SynthParams {
            width: 8192,
            height: 1,
            frames: 2,
            seed,
            ..SynthParams::default()
        };
        for i in 8000..8192 {
            for s in 0..64 {
                let r = p.sample(1, i, 0, s);
                assert_eq!(r.x.floor() as u32, i, "pixel {i} sample {s}: {r:?}");
                assert_eq!(r.t.floor(), 1.0, "pixel {i} sample {s}: {r:?}");
            }
        }
    }
}
