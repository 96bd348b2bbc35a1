//! F6a's two ways of finding a stored sample's k nearest among every
//! sample, on one dump with the default configuration: the grid over every
//! sample and the dump streamed past the stored samples. Checks that they
//! decide alike and prints each one's final-pass seconds, alternating
//! (docs/BENCHMARKS.md, "The default run").
//!
//!     cargo run --release --example f6a_paths -- DUMP [K] [ROUNDS]

use pathdensity::config::FilterConfig;
use pathdensity::density::evidence::{AllSamples, final_pass_against_all_with};
use pathdensity::density::{self, ExactSigma, ReplayOptions};
use pathdensity::dump::DumpReader;
use pathdensity::pipeline;
use pathdensity::progress::Silent;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(path) = args.first() else {
        anyhow::bail!("usage: f6a_paths DUMP [K] [ROUNDS]");
    };
    let k: usize = args
        .get(1)
        .map_or(Ok(FilterConfig::DEFAULT.k), |s| s.parse())?;
    let rounds: usize = args.get(2).map_or(Ok(3), |s| s.parse())?;
    let dump = DumpReader::open(path)?;
    let (h, records) = (dump.header().clone(), dump.records());
    let config = FilterConfig {
        k,
        ..FilterConfig::DEFAULT
    };
    let white = pipeline::resolve_white(&config, records, &h)?;
    let space = config.space(white);
    let paper = density::run(
        records,
        &h,
        &space,
        k,
        config.index,
        &ReplayOptions::default(),
        &Silent,
    );
    let mut decisions = Vec::new();
    for round in 0..rounds {
        for how in [AllSamples::Grid, AllSamples::Streamed] {
            let mut r = paper.clone();
            let before = r.final_seconds;
            final_pass_against_all_with(records, &h, &space, k, ExactSigma::None, &mut r, how);
            println!(
                "round {round} {how:?}: final pass {:.3} s",
                r.final_seconds - before
            );
            decisions.push(r.decisions);
        }
    }
    anyhow::ensure!(
        decisions.windows(2).all(|w| w[0] == w[1]),
        "the two paths decided differently"
    );
    println!("the same decisions");
    Ok(())
}
