//! `pathdensity filter`: read a dump, run the path-density filter, write
//! the images, the decisions and the report.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};

use crate::density::{self, Decision, FilterParams};
use crate::dump::DumpReader;
use crate::io::{atomic, exr, png};
use crate::metrics;
use crate::recon::{self, ReconFilter};
use crate::report::{FilterReport, Timing};

#[derive(Clone, Debug)]
pub struct FilterOptions {
    pub dump: PathBuf,
    pub out_dir: PathBuf,
    pub params: FilterParams,
    pub recon: ReconFilter,
    pub reference: Option<PathBuf>,
    /// Exposure applied before display metrics.
    pub exposure: f64,
    /// Worker threads; 0 means rayon's default (one per core).
    pub threads: usize,
    pub decisions: Option<PathBuf>,
    pub sigma_map: bool,
}

impl FilterOptions {
    pub fn new(dump: impl Into<PathBuf>, out_dir: impl Into<PathBuf>) -> FilterOptions {
        FilterOptions {
            dump: dump.into(),
            out_dir: out_dir.into(),
            params: FilterParams::default(),
            recon: ReconFilter::Box,
            reference: None,
            exposure: 1.0,
            threads: 0,
            decisions: None,
            sigma_map: false,
        }
    }
}

/// Fails early, before any work, when `dir` cannot take our files.
fn prepare_out_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create output directory", dir.display()))?;
    let probe = atomic::AtomicFile::new(dir.join("probe"));
    probe
        .create()
        .with_context(|| format!("{}: output directory is not writable", dir.display()))?;
    Ok(())
}

pub fn filter(opts: &FilterOptions) -> Result<FilterReport> {
    let t_start = Instant::now();
    let mut params = opts.params.clone();
    params.exact_sigma |= opts.sigma_map;
    if params.k == 0 {
        bail!("--k must be at least 1");
    }
    params.space.validate().map_err(anyhow::Error::msg)?;
    if let ReconFilter::Gaussian { s, radius } = opts.recon
        && !(s > 0.0 && s.is_finite() && radius >= 0.0 && radius.is_finite())
    {
        bail!("the gaussian filter needs s > 0 and a finite radius ≥ 0");
    }
    let dump = DumpReader::open(&opts.dump)?;
    let h = dump.header().clone();
    let reference = opts
        .reference
        .as_ref()
        .map(|p| exr::read_reference(p, h.width as usize, h.height as usize, h.frames as usize))
        .transpose()?;
    prepare_out_dir(&opts.out_dir)?;
    let open_seconds = t_start.elapsed().as_secs_f64();

    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(opts.threads)
        .build()
        .context("cannot start the worker threads")?;
    let records = dump.records();
    let progress = super::progress_bar(records.len() as u64, "filter");
    let result = pool.install(|| density::run(records, &h, &params, &progress));
    progress.finish_and_clear();

    let t_recon = Instant::now();
    let rec = recon::reconstruct(records, &h, opts.recon, |i| {
        Decision::accepted(result.decisions[i])
    });
    let sigma_img = result
        .sigma
        .as_ref()
        .map(|s| recon::sigma_map(records, &h, s));
    let mut metrics_by_image = BTreeMap::new();
    if let Some(r) = &reference {
        metrics_by_image.insert("mean".into(), metrics::compare(&rec.mean, r, opts.exposure));
        metrics_by_image.insert(
            "filtered".into(),
            metrics::compare(&rec.filtered, r, opts.exposure),
        );
    }
    let reconstruct_seconds = t_recon.elapsed().as_secs_f64();

    let t_write = Instant::now();
    let dir = &opts.out_dir;
    let mut outputs = Vec::new();
    for (name, img) in [("filtered", &rec.filtered), ("mean", &rec.mean)] {
        outputs.extend(exr::write_image(dir, name, img)?);
        outputs.extend(png::write_previews(dir, name, img, opts.exposure)?);
    }
    if let Some(img) = &sigma_img {
        outputs.extend(exr::write_image(dir, "sigma", img)?);
    }
    if let Some(p) = &opts.decisions {
        atomic::write_bytes(p, &result.decisions)?;
    }
    outputs.push("report.json".into());
    let mut report = FilterReport {
        dump: opts.dump.display().to_string(),
        header: h,
        parameters: params,
        recon: opts.recon,
        threads: pool.current_num_threads(),
        counts: result.counts,
        fallback_pixels: rec.fallback_pixels,
        empty_pixels: rec.empty_pixels,
        timing: Timing {
            open_seconds,
            streaming_seconds: result.streaming_seconds,
            final_pass_seconds: result.final_seconds,
            reconstruct_seconds,
            write_seconds: 0.0,
            total_seconds: 0.0,
        },
        metrics: metrics_by_image,
        reference: opts.reference.as_ref().map(|p| p.display().to_string()),
        outputs,
    };
    report.timing.write_seconds = t_write.elapsed().as_secs_f64();
    report.timing.total_seconds = t_start.elapsed().as_secs_f64();
    let json = serde_json::to_vec_pretty(&report).expect("the report serialises");
    atomic::write_bytes(&dir.join("report.json"), &json)?;
    Ok(report)
}
