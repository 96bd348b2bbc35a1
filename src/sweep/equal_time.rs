//! The equal-time comparison on a pass-major still: the first m passes are
//! an m-spp render, so the filtered image of m passes can be set against
//! the mean of the most passes that cost no more in total.

use std::time::Instant;

use anyhow::{Result, bail};

use super::SweepOptions;
use crate::config::{FilterConfig, Method};
use crate::density::{Decision, ExactSigma};
use crate::dump::{DumpReader, Order};
use crate::io::exr;
use crate::method::Role;
use crate::metrics::{self, Metrics};
use crate::pipeline::estimate::{Estimators, Shared};
use crate::pipeline::{self, thread_pool};
use crate::progress::{Progress, Silent};
use crate::recon::Image;

/// One prefix of the equal-time comparison.
#[derive(Clone, Debug, serde::Serialize)]
pub struct EqualTimeRow {
    /// Passes (samples per pixel) the filter used.
    pub spp: u32,
    /// Render time of those passes plus the filter and reconstruction.
    pub filtered_seconds: f64,
    pub filtered: Metrics,
    /// The pass count whose render time alone is closest to, and not above,
    /// `filtered_seconds` (at most the dump's spp).
    pub mean_spp: u32,
    pub mean_seconds: f64,
    pub mean: Metrics,
    /// The energy-aware filter at `spp` passes (its spread costs a few
    /// milliseconds, counted in `filtered_seconds`).
    pub filtered_energy: Metrics,
    /// mon, gmon and rwmc at `mean_spp` passes: their cost is a small
    /// fraction of the render time, so equal time is (nearly) equal samples.
    pub peers: Vec<(String, Metrics)>,
}

/// The equal-time comparison for one configuration (each list's single
/// value, else the base configuration's): for m = 1, 2, 4, … and the full
/// count, the filtered image of m passes against the mean of the most
/// passes that cost no more in total, with render time
/// `render_seconds / spp` per pass.
pub fn equal_time(
    o: &SweepOptions,
    render_seconds: f64,
    progress: &dyn Progress,
) -> Result<Vec<EqualTimeRow>> {
    let dump = DumpReader::open(&o.dump)?;
    let h = dump.header().clone();
    if h.order != Order::PassMajor || h.frames != 1 || h.spp == 0 {
        bail!(
            "{}: --equal-time needs a pass-major still with a uniform spp",
            o.dump.display()
        );
    }
    if !(render_seconds > 0.0 && render_seconds.is_finite()) {
        bail!("--render-seconds must be positive");
    }
    let reference = exr::read_reference(&o.reference, h.width as usize, h.height as usize, 1)?;
    let pool = thread_pool(o.threads)?;
    let per_pass = render_seconds / h.spp as f64;
    let pixels = h.pixels();
    let prefix = |m: u32| {
        let mut ph = h.clone();
        ph.spp = m;
        ph.sample_count = m as u64 * pixels as u64;
        (ph, &dump.records()[..m as usize * pixels])
    };
    let compare = |img: &Image| metrics::compare(img, &reference, o.config.exposure).pooled;
    // One configuration: a single value given is used, a list (such as
    // the default grid) means the base configuration's.
    let one = |v: &[f64], default: f64| if v.len() == 1 { v[0] } else { default };
    let base = &o.config;
    let config = FilterConfig {
        k: if o.ks.len() == 1 { o.ks[0] } else { base.k },
        sigma_image: one(&o.sigma_images, base.sigma_image),
        sigma_color: one(&o.sigma_colors, base.sigma_color),
        white: if o.whites.len() == 1 {
            o.whites[0]
        } else {
            base.white
        },
        mon_groups: *o.mon_groups.first().unwrap_or(&base.mon_groups),
        rwmc_kappa: *o.rwmc_kappas.first().unwrap_or(&base.rwmc_kappa),
        clamp: *o.clamps.first().unwrap_or(&base.clamp),
        ..*base
    };
    pipeline::check(&config, dump.records(), &h)?;
    let white = pipeline::resolve_white(&config, dump.records(), &h)?;
    // The mean and the peer estimators of the first m passes.
    let plain = |m: u32| {
        let (ph, recs) = prefix(m);
        let core = pipeline::reconstruct(recs, &ph, &config, |_| true, 0.0);
        let shared = Shared::new(recs, &ph);
        let est = Estimators::new(&shared, &config, white, &core);
        let peers = Method::with_role(|r| matches!(r, Role::Peer(_) | Role::EqualTime))
            .map(|m| match m.row().role {
                Role::Peer(param) => (m, super::peer_label(m, param, &config)),
                _ => (m, m.name().to_string()),
            })
            .map(|(m, label)| match est.image(m) {
                Ok((img, _)) => Ok((label, compare(&img))),
                Err(e) => Err(anyhow::anyhow!("{label}: {e}")),
            })
            .collect::<Result<Vec<_>>>()?;
        Ok::<_, anyhow::Error>((compare(&core.reconstruction.mean), peers))
    };
    let mut ms: Vec<u32> = std::iter::successors(Some(1u32), |m| m.checked_mul(2))
        .take_while(|&m| m < h.spp)
        .collect();
    ms.push(h.spp);
    progress.set_length(ms.len() as u64);
    let mut rows = Vec::new();
    for m in ms {
        let (ph, recs) = prefix(m);
        let t = Instant::now();
        let (filtered, filter_secs, energy_aware) = pool.install(|| {
            let result = pipeline::replay(recs, &ph, &config, white, ExactSigma::None, &Silent);
            let accepted = |i: usize| Decision::accepted(result.decisions[i]);
            let core = pipeline::reconstruct(recs, &ph, &config, accepted, 0.0);
            let secs = t.elapsed().as_secs_f64();
            let shared = Shared::new(recs, &ph);
            let est = Estimators::new(&shared, &config, white, &core);
            let (energy_aware, _) = est
                .image(Method::FilteredEnergy)
                .map_err(anyhow::Error::msg)?;
            drop(est);
            Ok::<_, anyhow::Error>((core.reconstruction.filtered, secs, energy_aware))
        })?;
        let filtered_seconds = m as f64 * per_pass + filter_secs;
        let mean_spp = ((filtered_seconds / per_pass).floor() as u32).clamp(1, h.spp);
        let (mean, peers) = pool.install(|| plain(mean_spp))?;
        rows.push(EqualTimeRow {
            spp: m,
            filtered_seconds,
            filtered: compare(&filtered),
            mean_spp,
            mean_seconds: mean_spp as f64 * per_pass,
            mean,
            filtered_energy: compare(&energy_aware),
            peers,
        });
        progress.inc(1);
    }
    progress.finish();
    dump.intact()?;
    Ok(rows)
}

/// The equal-time table as text (also written as `equal_time.csv`).
pub fn equal_time_csv(rows: &[EqualTimeRow]) -> String {
    let mut s = String::from("spp,method,seconds,rms,rms_display\n");
    let line = |spp: u32, name: &str, secs: f64, m: &Metrics| {
        format!("{spp},{name},{secs},{},{}\n", m.rms, m.rms_display)
    };
    for r in rows {
        s += &line(r.spp, "filtered", r.filtered_seconds, &r.filtered);
        s += &line(
            r.spp,
            "filtered_energy",
            r.filtered_seconds,
            &r.filtered_energy,
        );
        s += &line(r.mean_spp, "mean", r.mean_seconds, &r.mean);
        for (name, m) in &r.peers {
            s += &line(r.mean_spp, name, r.mean_seconds, m);
        }
    }
    s
}
