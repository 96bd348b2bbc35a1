//! statmc (`recon::statmc::denoise`) of every valid sample of a dump on
//! 2 threads: the per-pixel statistics' fold and the window, seconds per
//! round (docs/BENCHMARKS.md, "The removed energy spread in bands").
//!
//!     cargo run --release --example statmc_time -- DUMP [ROUNDS]

use pathdensity::dump::DumpReader;
use pathdensity::pipeline;
use pathdensity::recon::statmc;
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(path) = args.first() else {
        anyhow::bail!("usage: statmc_time DUMP [ROUNDS]");
    };
    let rounds: usize = args.get(1).map_or(Ok(3), |s| s.parse())?;
    let dump = DumpReader::open(path)?;
    let (h, records) = (dump.header().clone(), dump.records());
    let pool = pipeline::thread_pool(2)?;
    for round in 0..rounds {
        let t = Instant::now();
        let img = pool.install(|| statmc::denoise(records, &h, |_| true, None));
        let seconds = t.elapsed().as_secs_f64();
        let sum: f64 = img.data.iter().flatten().sum();
        println!("round {round}: {seconds:.3} s (Σ {sum:.6e})");
    }
    Ok(())
}
