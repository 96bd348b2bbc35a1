//! The removed energy spread back (`recon::energy::energy_aware`, the
//! filtered_energy and guided images' step) on a synthetic 1920 × 1080
//! frame where one pixel in a hundred lost energy, as a 1080p × 64-spp
//! frame's rejected samples leave it: seconds at 1 and 2 threads
//! (docs/BENCHMARKS.md, "The removed energy spread in bands").
//!
//!     cargo run --release --example energy_spread -- [ROUNDS]

use pathdensity::pipeline;
use pathdensity::recon::{Image, energy};
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let rounds: usize = std::env::args().nth(1).map_or(Ok(3), |s| s.parse())?;
    let (w, h) = (1920, 1080);
    let filtered = Image::new(w, h, 1);
    let mut removed = Image::new(w, h, 1);
    // A fixed stream (a linear congruential generator) picks the pixels.
    let mut state = 1u64;
    for px in removed.data.iter_mut() {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        if (state >> 33).is_multiple_of(100) {
            *px = [1.0, 2.0, 3.0];
        }
    }
    let occupancy = vec![1u32; w * h];
    for round in 0..rounds {
        for threads in [1, 2] {
            let pool = pipeline::thread_pool(threads)?;
            let t = Instant::now();
            let out = pool.install(|| energy::energy_aware(&filtered, &removed, &occupancy, 8.0));
            let seconds = t.elapsed().as_secs_f64();
            std::hint::black_box(out);
            println!("round {round}, {threads} threads: {seconds:.3} s");
        }
    }
    Ok(())
}
