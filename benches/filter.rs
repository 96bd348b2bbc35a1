//! The filter benchmark of docs/BENCHMARKS.md: samples/s of the replay on
//! the synthetic 256 × 256 × 64-spp dump (0.5% fireflies), pixel- and
//! pass-major, for each index, k and thread count, plus the mean-only
//! reconstruction as the floor. Medians of `PD_BENCH_RUNS` runs (default 3;
//! the kd-tree runs once: it is the slow oracle).
//!
//!     cargo bench --bench filter            # everything
//!     cargo bench --bench filter -- grid    # only rows whose label matches

use std::time::Instant;

use indicatif::ProgressBar;
use pathdensity::density::{self, FilterParams, IndexKind};
use pathdensity::dump::{DumpReader, Order};
use pathdensity::recon::{self, ReconFilter};
use pathdensity::synth::SynthParams;

/// Median wall time of `runs` calls of `f`.
fn median_seconds(runs: usize, mut f: impl FnMut()) -> f64 {
    let mut t: Vec<f64> = (0..runs)
        .map(|_| {
            let t0 = Instant::now();
            f();
            t0.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

fn main() {
    let filter_arg = std::env::args()
        .skip(1)
        .find(|a| !a.starts_with('-'))
        .map(|a| a.to_lowercase());
    // Rows run when their label contains the argument (any case).
    let wanted = |label: &str| {
        filter_arg
            .as_ref()
            .is_none_or(|f| label.to_lowercase().contains(f.as_str()))
    };
    let runs: usize = std::env::var("PD_BENCH_RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3);
    let dir = tempfile::tempdir().unwrap();
    println!("| order | index | k | threads | median s | M samples/s | stored |T| |");
    println!("|---|---|---|---|---|---|---|");
    for order in [Order::PixelMajor, Order::PassMajor] {
        let p = SynthParams {
            order,
            ..SynthParams::default()
        };
        let path = dir.path().join(format!("{order:?}.pds"));
        p.write(&path).unwrap();
        let dump = DumpReader::open(&path).unwrap();
        let (h, recs) = (dump.header().clone(), dump.records());
        let n = recs.len() as f64;
        if wanted(&format!("{order:?} mean-only")) {
            let m = median_seconds(runs, || {
                let r = recon::reconstruct(recs, &h, ReconFilter::Box, |_| true);
                std::hint::black_box(r.mean.data[0]);
            });
            println!(
                "| {order:?} | mean-only floor | – | 1 | {m:.3} | {:.2} | – |",
                n / m / 1e6
            );
        }
        for index in [IndexKind::Grid, IndexKind::Kdtree] {
            for k in [10, 50] {
                for threads in [1, 2] {
                    if !wanted(&format!("{order:?} {index:?} k{k} t{threads}")) {
                        continue;
                    }
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap();
                    let params = FilterParams {
                        k,
                        index,
                        ..FilterParams::default()
                    };
                    let reps = if index == IndexKind::Kdtree { 1 } else { runs };
                    let mut stored = 0;
                    let m = median_seconds(reps, || {
                        let r = pool
                            .install(|| density::run(recs, &h, &params, &ProgressBar::hidden()));
                        stored = r.counts.stored;
                    });
                    println!(
                        "| {order:?} | {index:?} | {k} | {threads} | {m:.3} | {:.2} | {stored} |",
                        n / m / 1e6
                    );
                }
            }
        }
    }
}
