//! The filter benchmark of docs/BENCHMARKS.md: samples/s of the replay on
//! the synthetic 256 × 256 × 64-spp dump (0.5% fireflies), pixel- and
//! pass-major, for each index, k and thread count, plus the mean-only
//! reconstruction as the floor. Medians of `PD_BENCH_RUNS` runs (default 3;
//! the kd-tree runs once: it is the slow oracle). The 1- and 2-thread runs
//! of a row alternate, round by round, so that the 1 → 2 thread ratio
//! compares runs of one period: this machine's speed drifts by ±20% over
//! minutes, more than the effect measured.
//!
//!     cargo bench --bench filter            # everything
//!     cargo bench --bench filter -- grid    # only rows whose label matches

use std::time::Instant;

use pathdensity::density::{self, IndexKind, ReplayOptions};
use pathdensity::dump::{DumpReader, Order};
use pathdensity::joint::JointSpace;
use pathdensity::progress::Silent;
use pathdensity::recon::{self, ReconFilter};
use pathdensity::synth::SynthParams;

/// Median wall time of `runs` calls of `f`.
fn median(mut t: Vec<f64>) -> f64 {
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

fn seconds(f: impl FnOnce()) -> f64 {
    let t0 = Instant::now();
    f();
    t0.elapsed().as_secs_f64()
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
    println!("| order | index | k | threads | median s | M samples/s | stored |T| | × 1 thread |");
    println!("|---|---|---|---|---|---|---|---|");
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
            let m = median(
                (0..runs)
                    .map(|_| {
                        seconds(|| {
                            let r = recon::reconstruct(recs, &h, ReconFilter::Box, |_| true);
                            std::hint::black_box(r.mean.data[0]);
                        })
                    })
                    .collect(),
            );
            println!(
                "| {order:?} | mean-only floor | – | 1 | {m:.3} | {:.2} | – | – |",
                n / m / 1e6
            );
        }
        for index in [IndexKind::Grid, IndexKind::Kdtree] {
            for k in [10, 50] {
                let threads: Vec<usize> = [1, 2]
                    .into_iter()
                    .filter(|t| wanted(&format!("{order:?} {index:?} k{k} t{t}")))
                    .collect();
                if threads.is_empty() {
                    continue;
                }
                let pools: Vec<_> = threads
                    .iter()
                    .map(|&t| {
                        rayon::ThreadPoolBuilder::new()
                            .num_threads(t)
                            .build()
                            .unwrap()
                    })
                    .collect();
                let (space, options) = (JointSpace::default(), ReplayOptions::default());
                let reps = if index == IndexKind::Kdtree { 1 } else { runs };
                // On the grid with both thread counts, a third contender:
                // two 1-thread replays at once, the machine's own 1 → 2
                // core throughput, which bounds the 2-thread ratio.
                let pair = index == IndexKind::Grid && threads.len() == 2;
                let contenders = threads.len() + pair as usize;
                // Its own pool: two installs on one 1-thread pool take turns.
                let second = rayon::ThreadPoolBuilder::new()
                    .num_threads(1)
                    .build()
                    .unwrap();
                let mut times = vec![Vec::new(); contenders];
                let mut stored = 0;
                let replay = |pool: &rayon::ThreadPool| {
                    pool.install(|| density::run(recs, &h, &space, k, index, &options, &Silent))
                        .counts
                        .stored
                };
                for rep in 0..reps {
                    // Alternate which contender goes first.
                    for i in 0..contenders {
                        let j = (i + rep) % contenders;
                        times[j].push(seconds(|| {
                            if j < threads.len() {
                                stored = replay(&pools[j]);
                            } else {
                                std::thread::scope(|s| {
                                    let other = s.spawn(|| replay(&second));
                                    replay(&pools[0]);
                                    other.join().unwrap();
                                });
                            }
                        }));
                    }
                }
                let medians: Vec<f64> = times.into_iter().map(median).collect();
                for (i, &m) in medians.iter().enumerate() {
                    let (label, speedup, samples) = match i {
                        0 => (threads[0].to_string(), "–".to_string(), n),
                        1 => (threads[1].to_string(), format!("{:.2}", medians[0] / m), n),
                        _ => (
                            "1 + 1 at once".to_string(),
                            format!("{:.2}", 2.0 * medians[0] / m),
                            2.0 * n,
                        ),
                    };
                    println!(
                        "| {order:?} | {index:?} | {k} | {label} | {m:.3} | {:.2} | {stored} | {speedup} |",
                        samples / m / 1e6
                    );
                }
            }
        }
    }
}
