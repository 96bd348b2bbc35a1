//! How far the HTML report's σ map (the mean exact σ of one sample in n,
//! `ExactSigma::for_map`) is from the exact one (every
//! sample's σ), per dump, with the default configuration (docs/BENCHMARKS.md,
//! "The default run").
//!
//!     cargo run --release --example sigma_map_error -- DUMP [N …]
//!
//! For each N, one sample in N picked by a hash of its record index and,
//! in a pixel- or pass-major dump, one in N of each pixel's (default: the
//! share the report uses, `ExactSigma::for_map`): the median
//! and 90th percentile of the per-pixel relative error, the correlation of
//! the two maps' logarithms, and how far the estimate moves a pixel along
//! the report's colour ramp (log scale from the exact map's 1st to 99th
//! percentile, as `report::plots::sigma_scale`): mean and 99th percentile,
//! as a fraction of the ramp.

use pathdensity::config::FilterConfig;
use pathdensity::density::sigma_map;
use pathdensity::density::{ExactSigma, Strata};
use pathdensity::dump::DumpReader;
use pathdensity::pipeline;
use pathdensity::progress::Silent;
use pathdensity::recon::Image;
use pathdensity::report::plots::sigma_scale;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(path) = args.first() else {
        anyhow::bail!("usage: sigma_map_error DUMP [N …]");
    };
    let dump = DumpReader::open(path)?;
    let (h, records) = (dump.header().clone(), dump.records());
    let config = FilterConfig::DEFAULT;
    let white = pipeline::resolve_white(&config, records, &h)?;
    let map = |exact: ExactSigma| -> Image {
        let r = pipeline::replay(records, &h, &config, white, exact, &Silent);
        sigma_map(records, &h, r.sigma.as_ref().expect("σ kept"))
    };
    let truth = map(ExactSigma::All);
    let scale = sigma_scale(&truth).expect("a σ map with positive values");
    let ramp = |s: f64| {
        ((s.max(1e-300).ln() - scale.low.ln()) / (scale.high.ln() - scale.low.ln())).clamp(0.0, 1.0)
    };
    let mut shares = Vec::new();
    for n in &args[1..] {
        let n: u32 = n.parse()?;
        shares.push((format!("one in {n} (hash)"), ExactSigma::OneIn(n)));
        if let Some(s) = Strata::new(&h, n) {
            shares.push((format!("one in {n} of each pixel"), ExactSigma::Strata(s)));
        }
    }
    if shares.is_empty() {
        shares.push(("the report's".into(), ExactSigma::for_map(&h)));
    }
    for (label, share) in shares {
        let est = map(share);
        let (mut rel, mut shift, mut logs) = (Vec::new(), Vec::new(), Vec::new());
        let mut empty = 0;
        for (t, e) in truth.data.iter().zip(&est.data) {
            let (t, e) = (t[0], e[0]);
            if t <= 0.0 || !t.is_finite() {
                continue;
            }
            if e <= 0.0 || !e.is_finite() {
                empty += 1;
                continue;
            }
            rel.push((e - t).abs() / t);
            shift.push((ramp(e) - ramp(t)).abs());
            logs.push((t.ln(), e.ln()));
        }
        let q = |v: &mut Vec<f64>, p: f64| {
            v.sort_by(f64::total_cmp);
            v[((v.len() - 1) as f64 * p).round() as usize]
        };
        let n = logs.len() as f64;
        let (mt, me) = logs
            .iter()
            .fold((0.0, 0.0), |a, l| (a.0 + l.0 / n, a.1 + l.1 / n));
        let (mut c, mut vt, mut ve) = (0.0, 0.0, 0.0);
        for &(t, e) in &logs {
            c += (t - mt) * (e - me);
            vt += (t - mt).powi(2);
            ve += (e - me).powi(2);
        }
        let mean_shift = shift.iter().sum::<f64>() / shift.len().max(1) as f64;
        println!(
            "{path} {label}: relative error median {:.4} p90 {:.4}; corr(log) {:.4}; ramp shift mean {:.4} p99 {:.4}; pixels without an estimate {empty} (ramp {:.3}..{:.3})",
            q(&mut rel, 0.5),
            q(&mut rel, 0.9),
            c / (vt * ve).sqrt(),
            mean_shift,
            q(&mut shift, 0.99),
            scale.low,
            scale.high,
        );
    }
    Ok(())
}
