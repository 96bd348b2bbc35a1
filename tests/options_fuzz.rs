//! Every numeric option at its extremes: each value either gives finite
//! images for every method or is refused by validation with a reason.
//! The fields are taken from the configuration's own serialisation, so an
//! option added later is fuzzed without touching this test.

use pathdensity::config::{FilterConfig, MethodSet};
use pathdensity::density::ExactSigma;
use pathdensity::dump::{Header, Record};
use pathdensity::pipeline::{self, RunOptions};
use pathdensity::progress::Silent;
use pathdensity::synth::SynthParams;

const FLOATS: [f64; 16] = [
    5e-324,
    1e-310,
    1e-170,
    1e-30,
    1e-9,
    1e-3,
    0.49,
    0.5,
    1.0,
    1.0 + 1e-12,
    3.0,
    1e3,
    1e9,
    1e30,
    1e170,
    1e308,
];
const INTEGERS: [u64; 7] = [0, 1, 2, 33, 1000, 1 << 20, u64::MAX];

fn dump() -> (Header, Vec<Record>) {
    let p = SynthParams {
        width: 12,
        height: 10,
        spp: 6,
        firefly_fraction: 0.02,
        ..SynthParams::default()
    };
    (p.header(), p.records().collect())
}

/// Runs `config` (every method this build has) and returns the name of the
/// first image holding a non-finite value, if any.
fn non_finite_image(config: &FilterConfig, h: &Header, recs: &[Record]) -> Option<String> {
    let run = pipeline::run(
        recs,
        h,
        config,
        &RunOptions {
            threads: 2,
            exact_sigma: ExactSigma::All,
            reference: None,
            progress: &Silent,
            aux: None,
        },
    )
    .ok()?;
    let images = run
        .images
        .iter()
        .map(|e| (e.id().to_string(), &*e.image))
        .chain([("rejected".to_string(), &run.removed)])
        .chain(run.sigma_image.iter().map(|s| ("sigma".to_string(), s)));
    for (name, img) in images {
        if img.data.iter().flatten().any(|v| !v.is_finite()) {
            return Some(name);
        }
    }
    None
}

#[test]
fn every_option_gives_finite_images_or_is_refused() {
    let (h, recs) = dump();
    let mut bad = Vec::new();
    // Every image that needs no OIDN, so that each option meets an image
    // that reads it.
    let every = |c: FilterConfig| FilterConfig {
        methods: MethodSet::NO_OIDN,
        ..c
    };
    for start in [every(FilterConfig::DEFAULT), every(FilterConfig::PAPER)] {
        let json = serde_json::to_value(start).unwrap();
        let fields: Vec<(String, serde_json::Value)> = json
            .as_object()
            .unwrap()
            .iter()
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect();
        let mut tried = 0;
        for (field, value) in fields {
            let values: Vec<serde_json::Value> = if value.is_u64() {
                INTEGERS.iter().map(|&v| v.into()).collect()
            } else if value.is_f64() || field == "white" {
                FLOATS.iter().map(|&v| v.into()).collect()
            } else {
                continue;
            };
            for v in values {
                let mut j = json.clone();
                j[&field] = v.clone();
                // A value serde refuses is refused before the run.
                let Ok(config) = serde_json::from_value::<FilterConfig>(j) else {
                    continue;
                };
                tried += 1;
                if let Err(e) = config.validate() {
                    assert!(
                        !e.problem.is_empty(),
                        "--{field} {v}: refused without a reason"
                    );
                    continue;
                }
                if let Some(image) = non_finite_image(&config, &h, &recs) {
                    bad.push(format!(
                        "--{field} {v}: accepted, but {image} is not finite"
                    ));
                }
            }
        }
        assert!(tried > 100, "only {tried} values tried");
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}
