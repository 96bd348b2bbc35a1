//! `pathdensity sweep`: the filter over a grid of parameters, written as
//! `sweep.csv`, `sweep.json`, three plots, each as SVG and PNG, and
//! `sweep.html` (the HDR viewer, the table and the plots).

use std::path::Path;

use anyhow::{Context, Result, anyhow, bail};

use crate::dump::DumpReader;
use crate::io::atomic::{self, Staging};
use crate::io::exr;
use crate::io::guard::Inputs;
use crate::metrics::Metrics;
use crate::progress::{Progress, Silent};
use crate::report;
use crate::report::sweep::Measure;
use crate::sweep::{self, Sweep, SweepOptions};

/// The dump and the reference, which the sweep's folder must not hold.
fn inputs(o: &SweepOptions) -> Inputs {
    let frames = DumpReader::open(&o.dump).map_or(1, |d| d.header().frames as usize);
    let mut inputs = Inputs::of([&o.dump]);
    for p in exr::reference_files(&o.reference, frames) {
        inputs.add(&p);
    }
    inputs
}

/// Runs `o` with no progress shown.
pub fn sweep(o: &SweepOptions) -> Result<Sweep> {
    sweep_with_progress(o, &Silent)
}

/// Runs the sweep of `o` and writes its files.
pub fn sweep_with_progress(o: &SweepOptions, progress: &dyn Progress) -> Result<Sweep> {
    let staging = Staging::create(&o.out_dir, &inputs(o))?;
    let s = sweep::run(o, progress).with_context(|| o.dump.display().to_string())?;
    // Errors name OUT's files, not the hidden staging folder's.
    write_sweep(&s, staging.path())
        .map_err(|e| anyhow!("{}", staging.in_dest(&format!("{e:#}"))))?;
    staging.commit()?;
    if s.rows.iter().all(|r| r.failure.is_some()) {
        bail!(
            "every configuration failed (the reasons are in {})",
            o.out_dir.join("sweep.csv").display()
        );
    }
    Ok(s)
}

/// Writes the sweep's tables, plots and page into `dir`.
fn write_sweep(s: &Sweep, dir: &Path) -> Result<()> {
    atomic::write_bytes(&dir.join("sweep.csv"), report::sweep::csv(s).as_bytes())?;
    let json = serde_json::to_vec_pretty(s).expect("a sweep serialises");
    atomic::write_bytes(&dir.join("sweep.json"), &json)?;
    let plot = |r: Result<Vec<u8>, String>| r.map_err(|e| anyhow!("cannot draw a plot: {e}"));
    let svg = |r: Result<String, String>| r.map_err(|e| anyhow!("cannot draw a plot: {e}"));
    let mut svgs = Vec::new();
    for (name, svg_text, png) in [
        (
            "rms_vs_time",
            report::sweep::plot_time(s),
            report::sweep::plot_time_png(s),
        ),
        (
            "rms_vs_k",
            report::sweep::plot_k(s, Measure::Rms),
            report::sweep::plot_k_png(s, Measure::Rms),
        ),
        (
            "flip_vs_k",
            report::sweep::plot_k(s, Measure::Flip),
            report::sweep::plot_k_png(s, Measure::Flip),
        ),
    ] {
        let svg_text = svg(svg_text)?;
        atomic::write_bytes(&dir.join(format!("{name}.svg")), svg_text.as_bytes())?;
        atomic::write_bytes(&dir.join(format!("{name}.png")), &plot(png)?)?;
        svgs.push(svg_text);
    }
    let html = report::sweep::page(s, &table(s), &svgs);
    atomic::write_bytes(&dir.join("sweep.html"), html.as_bytes())?;
    Ok(())
}

/// The printed table: one line per configuration, then the baselines.
pub fn table(s: &Sweep) -> String {
    let front = s.pareto();
    let mut t = format!(
        "{:>6} {:>5} {:>8} {:>8} {:>10} {:>9} {:>9} {:>9} {:>11} {:>8} {:>8}\n",
        "space",
        "k",
        "σ_color",
        "σ_image",
        "white",
        "seconds",
        "stored",
        "accepted",
        "RMS",
        "RMS disp",
        "FLIP"
    );
    for (i, r) in s.rows.iter().enumerate() {
        let mark = if front.contains(&i) { "*" } else { " " };
        match (&r.metrics, &r.failure) {
            (Some(m), _) => {
                t += &format!(
                    "{:>6} {:>5} {:>8} {:>8} {:>10.4} {:>9.3} {:>9} {:>8.2}% {:>10.6}{mark} {:>8.5} {:>8.5}\n",
                    r.color_space.name(),
                    r.k,
                    r.sigma_color,
                    r.sigma_image,
                    r.white_value,
                    r.seconds,
                    r.stored,
                    100.0 * r.accepted_fraction,
                    m.rms,
                    m.rms_display,
                    m.flip
                )
            }
            (None, f) => {
                t += &format!(
                    "{:>6} {:>5} {:>8} {:>8} {:>10.4}   failed: {}\n",
                    r.color_space.name(),
                    r.k,
                    r.sigma_color,
                    r.sigma_image,
                    r.white_value,
                    f.as_deref().unwrap_or("")
                )
            }
        }
    }
    for b in &s.baselines {
        t += &format!(
            "{:>41} {:>9.3} {:>30.6}  {:>8.5} {:>8.5}\n",
            b.label, b.seconds, b.metrics.rms, b.metrics.rms_display, b.metrics.flip
        );
    }
    t + "(* on the time–RMS Pareto front)\n"
}

/// `sweep --equal-time`: writes `equal_time.csv` and `equal_time.json`
/// and returns the printed table.
pub fn equal_time(
    o: &SweepOptions,
    render_seconds: f64,
    progress: &dyn Progress,
) -> Result<String> {
    let staging = Staging::create(&o.out_dir, &inputs(o))?;
    let rows = sweep::equal_time(o, render_seconds, progress)
        .with_context(|| o.dump.display().to_string())?;
    let dir = staging.path();
    atomic::write_bytes(
        &dir.join("equal_time.csv"),
        sweep::equal_time_csv(&rows).as_bytes(),
    )?;
    let json = serde_json::to_vec_pretty(&rows).expect("rows serialise");
    atomic::write_bytes(&dir.join("equal_time.json"), &json)?;
    staging.commit()?;
    let mut t = format!(
        "{:>5} {:>9} {:>17} {:>17} | {:>5} {:>9} {:>17} {:>29} | winner (RMS, display)\n",
        "spp", "total s", "filtered", "filtered_energy", "spp", "render s", "mean", "best peer"
    );
    let pair = |m: &Metrics| format!("{:.5}/{:.5}", m.rms, m.rms_display);
    for r in &rows {
        let best_peer = r
            .peers
            .iter()
            .min_by(|a, b| a.1.rms.total_cmp(&b.1.rms))
            .expect("three peers");
        let mut all: Vec<(&str, &Metrics)> = vec![
            ("filtered", &r.filtered),
            ("filtered_energy", &r.filtered_energy),
            ("mean", &r.mean),
        ];
        all.extend(r.peers.iter().map(|(n, m)| (n.as_str(), m)));
        let win = |f: fn(&Metrics) -> f64| {
            all.iter()
                .min_by(|a, b| f(a.1).total_cmp(&f(b.1)))
                .map(|e| e.0)
                .unwrap_or("")
        };
        t += &format!(
            "{:>5} {:>9.3} {:>17} {:>17} | {:>5} {:>9.3} {:>17} {:>29} | {}, {}\n",
            r.spp,
            r.filtered_seconds,
            pair(&r.filtered),
            pair(&r.filtered_energy),
            r.mean_spp,
            r.mean_seconds,
            pair(&r.mean),
            format!("{} {}", best_peer.0, pair(&best_peer.1)),
            win(|m| m.rms),
            win(|m| m.rms_display)
        );
    }
    Ok(t)
}
