//! Properties over random small dumps (proptest, fixed seed so CI is
//! reproducible; `PROPTEST_CASES` raises the case count locally):
//! thread-count invariance of every output file, σ_color → ∞ makes the
//! decisions colour-blind, and scaling radiance with the Lab white keeps
//! the decisions.

mod common;

use common::REJECTED;
use pathdensity::commands::filter::{FilterOptions, filter};
use pathdensity::config::{ColorSpace, FilterConfig, FinalPass, MethodSet, White};
use pathdensity::density::{self, Decision, IndexKind, ReplayOptions};
use pathdensity::dump::{Order, Record};
use pathdensity::joint::JointSpace;
use pathdensity::pipeline::{self, RunOptions};
use pathdensity::progress::Silent;
use pathdensity::recon::{ReconFilter, reconstruct};
use pathdensity::synth::SynthParams;
use proptest::prelude::*;
use proptest::test_runner::RngSeed;

fn config(cases: u32) -> ProptestConfig {
    ProptestConfig {
        cases: std::env::var("PROPTEST_CASES")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(cases),
        rng_seed: RngSeed::Fixed(0x5eed),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// Small synthetic dumps: any film from 1 × 1, 1–3 frames, 1–12 spp, either
/// order, jittered or pixel-centre samples, fireflies, sometimes a light.
fn dumps(pixel_centre: impl Strategy<Value = bool>) -> impl Strategy<Value = SynthParams> {
    (
        (1u32..20, 1u32..14, 1u32..4, 1u32..12),
        prop_oneof![Just(Order::PixelMajor), Just(Order::PassMajor)],
        0.0f64..0.1,
        pixel_centre,
        proptest::option::of((0u32..10, 0u32..8, 1u32..4)),
        any::<u64>(),
    )
        .prop_map(
            |((width, height, frames, spp), order, ff, pc, light, seed)| SynthParams {
                width,
                height,
                frames,
                spp,
                order,
                firefly_fraction: ff,
                pixel_centre: pc,
                light: light.map(|(x, y, s)| (x, y, s, 40.0)),
                seed,
                ..SynthParams::default()
            },
        )
}

fn records(p: &SynthParams) -> Vec<Record> {
    p.records().collect()
}

fn decide(recs: &[Record], p: &SynthParams, k: usize, space: &JointSpace) -> Vec<u8> {
    let options = ReplayOptions::default();
    density::run(
        recs,
        &p.header(),
        space,
        k,
        IndexKind::Grid,
        &options,
        &Silent,
    )
    .decisions
}

proptest! {
    #![proptest_config(config(24))]

    /// Every file `filter` writes (all methods, σ map, decisions) has the
    /// same bytes for 1 and 3 threads, and for either index.
    #[test]
    fn every_output_is_identical_for_any_thread_count(
        p in dumps(any::<bool>()),
        k in 1usize..16,
        sigma_color in prop_oneof![Just(100.0), 1.0f64..1000.0],
    ) {
        let dir = tempfile::tempdir().unwrap();
        let dump = dir.path().join("d.pds");
        p.write(&dump).unwrap();
        let run = |threads: usize, index: density::IndexKind, name: &str| {
            let out = dir.path().join(name);
            let mut o = FilterOptions::new(&dump, &out);
            o.config.k = k;
            o.config.sigma_color = sigma_color;
            o.config.index = index;
            o.config.methods = MethodSet::NO_OIDN;
            o.threads = threads;
            o.html = false;
            o.sigma_map = true;
            o.decisions = Some(out.join("decisions.bin"));
            std::fs::create_dir_all(&out).unwrap();
            if let Err(e) = filter(&o) {
                // Fewer valid samples than k + 1: refused, on any thread count.
                assert!(format!("{e:#}").contains("valid samples"), "{e:#}");
                return Vec::new();
            }
            let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(&out)
                .unwrap()
                .map(|e| e.unwrap().path())
                .filter(|f| f.extension().is_some_and(|x| x == "exr" || x == "bin"))
                .map(|f| (f.file_name().unwrap().to_string_lossy().into_owned(), std::fs::read(&f).unwrap()))
                .collect();
            files.sort();
            files
        };
        let one = run(1, density::IndexKind::Grid, "t1");
        let names: Vec<&String> = one.iter().map(|f| &f.0).collect();
        prop_assert!(one.len() >= 8 || one.is_empty(), "{:?}", names);
        prop_assert!(one == run(3, density::IndexKind::Grid, "t3"));
        prop_assert!(one == run(3, density::IndexKind::Kdtree, "kd"));
    }

    /// σ_color → ∞ (10⁹): replacing every colour leaves the decisions
    /// unchanged, and `filtered` equals `mean` on every pixel that lost no
    /// sample. (Not on every pixel: a rejected sample changes its pixel's
    /// average, docs/filter.md §2.) Jittered samples only: with pixel-centre samples,
    /// image distances tie exactly and a σ of exactly 1 can flip on the
    /// colour's 10⁻⁷ contribution.
    #[test]
    fn infinite_sigma_color_makes_decisions_colour_blind(
        p in dumps(Just(false)),
        k in 1usize..16,
        seed in any::<u64>(),
    ) {
        let space = JointSpace { sigma_color: 1e9, ..JointSpace::default() };
        let a = records(&p);
        let mut s = seed | 1;
        let mut u = || { s ^= s << 13; s ^= s >> 7; s ^= s << 17; (s >> 40) as f32 / (1u64 << 24) as f32 };
        let b: Vec<Record> = a
            .iter()
            .map(|r| Record::new(r.x, r.y, r.t, [1e3 * u(), 20.0 * u(), u()]))
            .collect();
        let da = decide(&a, &p, k, &space);
        prop_assert_eq!(&da, &decide(&b, &p, k, &space));
        let h = p.header();
        let rec = reconstruct(&b, &h, ReconFilter::Box, |i| Decision::accepted(da[i]));
        let mut lost = vec![false; h.pixels() * h.frames as usize];
        for (i, r) in b.iter().enumerate() {
            if da[i] == REJECTED {
                lost[r.pixel_index(&h)] = true;
            }
        }
        for (px, lost) in lost.iter().enumerate() {
            if !lost {
                prop_assert_eq!(rec.filtered.data[px], rec.mean.data[px], "pixel {}", px);
            }
        }
    }

    /// Scaling every radiance by 2ⁿ together with Y_w leaves every Lab
    /// coordinate, hence every decision, unchanged. Powers of two are exact
    /// in floating point; another constant moves coordinates by an ulp, which
    /// can flip a sample whose σ is within rounding of 1 (docs/filter.md, the white).
    #[test]
    fn scaling_radiance_with_the_white_keeps_every_decision(
        p in dumps(any::<bool>()),
        k in 1usize..16,
        n in -12i32..12,
        white in 0.05f64..20.0,
    ) {
        let c = 2f32.powi(n);
        let space = JointSpace { white, ..JointSpace::default() };
        let scaled = JointSpace { white: white * c as f64, ..space };
        let a = records(&p);
        let b: Vec<Record> = a.iter().map(|r| Record::new(r.x, r.y, r.t, [r.r * c, r.g * c, r.b * c])).collect();
        prop_assert_eq!(decide(&a, &p, k, &space), decide(&b, &p, k, &scaled));
    }
}

proptest! {
    #![proptest_config(config(48))]

    /// Any k, any finite positive σ over fifty decades, any white: the
    /// pipeline gives a clear error or a result whose decisions are the
    /// plain replay's and whose images are finite. Never a panic, never a
    /// hang (the dumps are small).
    #[test]
    fn any_options_give_a_clear_error_or_an_exact_finite_result(
        p in dumps(any::<bool>()),
        k in 1usize..40,
        log_si in -25.0f64..25.0,
        log_sc in -25.0f64..25.0,
        log_st in -25.0f64..25.0,
        white in prop_oneof![Just(White::Auto), (-10.0f64..10.0).prop_map(|e| White::Fixed(10f64.powf(e)))],
        index in prop_oneof![Just(IndexKind::Grid), Just(IndexKind::Kdtree)],
        color in 0usize..3,
        against_all in any::<bool>(),
    ) {
        let final_pass = if against_all { FinalPass::All } else { FinalPass::Stored };
        let config = FilterConfig {
            k,
            color_space: ColorSpace::ALL[color],
            final_pass,
            sigma_image: 10f64.powf(log_si),
            sigma_color: 10f64.powf(log_sc),
            sigma_time: 10f64.powf(log_st),
            white,
            index,
            methods: MethodSet::NO_OIDN,
            ..FilterConfig::DEFAULT
        };
        let h = p.header();
        let recs = records(&p);
        let options = RunOptions { threads: 2, exact_sigma: pathdensity::density::ExactSigma::None, reference: None, progress: &Silent, aux: None };
        match pipeline::run(&recs, &h, &config, &options) {
            Err(e) => {
                let msg = e.to_string();
                prop_assert!(
                    msg.contains("valid sample") || msg.contains("too small") || msg.contains("positive luminance"),
                    "{msg}"
                );
            }
            Ok(run) => {
                let plain = density::plain::replay_with(&recs, &h, &config.space(run.white), k, final_pass);
                prop_assert_eq!(&run.decisions, &plain.decisions);
                for e in &run.images {
                    prop_assert!(e.image.data.iter().flatten().all(|v| v.is_finite()), "{}", e.method);
                }
            }
        }
    }
}
