//! `pathdensity sweep`: the filter over a grid of parameters, written as
//! `sweep.csv`, `sweep.json` and two plots, each as SVG and PNG.

use anyhow::{Result, anyhow};

use crate::io::atomic;
use crate::sweep::{self, Sweep, SweepOptions};

pub fn sweep(o: &SweepOptions) -> Result<Sweep> {
    let configs = o.ks.len() * o.sigma_colors.len() * o.sigma_images.len() * o.whites.len();
    let progress = super::progress_bar(configs as u64, "sweep");
    let s = sweep::run(o, &progress)?;
    let dir = &o.out_dir;
    atomic::write_bytes(&dir.join("sweep.csv"), s.csv().as_bytes())?;
    let json = serde_json::to_vec_pretty(&s).expect("a sweep serialises");
    atomic::write_bytes(&dir.join("sweep.json"), &json)?;
    let plot = |r: Result<Vec<u8>, String>| r.map_err(|e| anyhow!("cannot draw a plot: {e}"));
    let svg = |r: Result<String, String>| plot(r.map(String::into_bytes));
    atomic::write_bytes(&dir.join("rms_vs_time.svg"), &svg(s.plot_time())?)?;
    atomic::write_bytes(&dir.join("rms_vs_time.png"), &plot(s.plot_time_png())?)?;
    atomic::write_bytes(&dir.join("rms_vs_k.svg"), &svg(s.plot_k())?)?;
    atomic::write_bytes(&dir.join("rms_vs_k.png"), &plot(s.plot_k_png())?)?;
    Ok(s)
}

/// The printed table: one line per configuration, then the baselines.
pub fn table(s: &Sweep) -> String {
    let front = s.pareto();
    let mut t = format!(
        "{:>5} {:>8} {:>8} {:>10} {:>9} {:>9} {:>9} {:>11} {:>8}\n",
        "k", "σ_color", "σ_image", "white", "seconds", "stored", "accepted", "RMS", "RMS disp"
    );
    for (i, r) in s.rows.iter().enumerate() {
        let mark = if front.contains(&i) { "*" } else { " " };
        match (&r.metrics, &r.failure) {
            (Some(m), _) => {
                t += &format!(
                    "{:>5} {:>8} {:>8} {:>10.4} {:>9.3} {:>9} {:>8.2}% {:>10.6}{mark} {:>8.5}\n",
                    r.k,
                    r.sigma_color,
                    r.sigma_image,
                    r.white_value,
                    r.seconds,
                    r.stored,
                    100.0 * r.accepted_fraction,
                    m.rms,
                    m.rms_display
                )
            }
            (None, f) => {
                t += &format!(
                    "{:>5} {:>8} {:>8} {:>10.4}   failed: {}\n",
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
            "{:>44} {:>9.3} {:>30.6}  {:>8.5}\n",
            b.method, b.seconds, b.metrics.rms, b.metrics.rms_display
        );
    }
    t + "(* on the time–RMS Pareto front)\n"
}

/// `sweep --equal-time`: writes `equal_time.csv` and `equal_time.json`
/// and returns the printed table.
pub fn equal_time(o: &SweepOptions, render_seconds: f64) -> Result<String> {
    std::fs::create_dir_all(&o.out_dir)?;
    let progress = super::progress_bar(0, "prefixes");
    let rows = sweep::equal_time(o, render_seconds, &progress)?;
    let dir = &o.out_dir;
    atomic::write_bytes(
        &dir.join("equal_time.csv"),
        sweep::equal_time_csv(&rows).as_bytes(),
    )?;
    let json = serde_json::to_vec_pretty(&rows).expect("rows serialise");
    atomic::write_bytes(&dir.join("equal_time.json"), &json)?;
    let mut t = format!(
        "{:>6} {:>12} {:>10} {:>10} | {:>6} {:>12} {:>10} {:>10} | winner\n",
        "spp", "filtered s", "RMS", "RMS disp", "spp", "mean s", "RMS", "RMS disp"
    );
    for r in &rows {
        let win = |a: f64, b: f64| if a < b { "filtered" } else { "mean" };
        t += &format!(
            "{:>6} {:>12.3} {:>10.6} {:>10.5} | {:>6} {:>12.3} {:>10.6} {:>10.5} | RMS: {}, display: {}\n",
            r.spp,
            r.filtered_seconds,
            r.filtered.rms,
            r.filtered.rms_display,
            r.mean_spp,
            r.mean_seconds,
            r.mean.rms,
            r.mean.rms_display,
            win(r.filtered.rms, r.mean.rms),
            win(r.filtered.rms_display, r.mean.rms_display)
        );
    }
    Ok(t)
}
