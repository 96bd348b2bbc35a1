//! Runs the pipeline on a dump with the default configuration and every
//! method, and prints a digest line per output: the decisions, the counts
//! and every image, as bits. `tests/sequential.rs` compares the digests of
//! a build with and without the `parallel` feature.
//!
//!     cargo run -p pathdensity-core --example run_bits -- DUMP [THREADS]

use std::hash::{DefaultHasher, Hash, Hasher};

use pathdensity_core::config::{FilterConfig, MethodSet};
use pathdensity_core::dump::DumpReader;
use pathdensity_core::pipeline::{self, RunOptions};
use pathdensity_core::progress::Silent;

fn digest<T: Hash>(v: &T) -> u64 {
    let mut h = DefaultHasher::new();
    v.hash(&mut h);
    h.finish()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dump = DumpReader::open(&args[1]).unwrap_or_else(|e| panic!("{e}"));
    let threads = args.get(2).map_or(0, |t| t.parse().unwrap());
    let options = RunOptions {
        threads,
        exact_sigma: pathdensity_core::density::ExactSigma::All,
        reference: None,
        progress: &Silent,
        aux: None,
    };
    let run = pipeline::run(
        dump.records(),
        dump.header(),
        &FilterConfig {
            methods: MethodSet::NO_OIDN,
            ..FilterConfig::DEFAULT
        },
        &options,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    println!("decisions {:016x}", digest(&run.decisions));
    println!("counts {:?}", run.counts);
    for e in &run.images {
        let bits: Vec<[u64; 3]> = e.image.data.iter().map(|p| p.map(f64::to_bits)).collect();
        println!("{} {:016x}", e.id(), digest(&bits));
    }
    let sigma = run.sigma_image.expect("exact σ asked for");
    let bits: Vec<[u64; 3]> = sigma.data.iter().map(|p| p.map(f64::to_bits)).collect();
    println!("sigma {:016x}", digest(&bits));
}
