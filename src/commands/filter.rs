//! `pathdensity filter`: read a dump, run the path-density filter and the
//! baselines, write the images, the decisions and the report.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Result, bail};

use crate::config::{FilterConfig, Method};
use crate::density::ExactSigma;
use crate::dump::{DumpReader, Header};
use crate::io::atomic::{self, Staging};
use crate::io::{exr, png};
use crate::pipeline::{self, RunOptions};
use crate::progress::{Progress, Silent};
use crate::recon::Image;
use crate::report::html::{self, Assets};
use crate::report::plots;
use crate::report::{EnergyRemoved, FilterReport, Provenance, Timing};
use rayon::prelude::*;

#[derive(Clone, Debug)]
pub struct FilterOptions {
    pub dump: PathBuf,
    pub out_dir: PathBuf,
    pub config: FilterConfig,
    pub reference: Option<PathBuf>,
    /// Worker threads; 0 means rayon's default (one per core).
    pub threads: usize,
    pub decisions: Option<PathBuf>,
    pub sigma_map: bool,
    /// Write the PNG previews, σ map, slice plot and `report.html` (turns
    /// the σ map on).
    pub html: bool,
    /// Film row of the slice plot (default: the middle row).
    pub slice_row: Option<u32>,
}

impl FilterOptions {
    /// The default configuration, the HTML report.
    pub fn new(dump: impl Into<PathBuf>, out_dir: impl Into<PathBuf>) -> FilterOptions {
        FilterOptions {
            dump: dump.into(),
            out_dir: out_dir.into(),
            config: FilterConfig::DEFAULT,
            reference: None,
            threads: 0,
            decisions: None,
            sigma_map: false,
            html: true,
            slice_row: None,
        }
    }
}

impl FilterOptions {
    /// Whose exact σ the run computes: every sample's for `sigma.exr`
    /// (`sigma_map`), a share for the HTML report's σ map
    /// ([`ExactSigma::for_map`]), none otherwise.
    pub fn exact_sigma(&self, h: &Header) -> ExactSigma {
        match (self.sigma_map, self.html) {
            (true, _) => ExactSigma::All,
            (false, true) => ExactSigma::for_map(h),
            (false, false) => ExactSigma::None,
        }
    }

    /// XXH3-64 of everything in these options that decides the outputs'
    /// content (the configuration, the HTML report, the σ map, the slice
    /// row), as recorded in `report.json`: equal hashes, equal dumps and
    /// equal references make equal images. Threads and paths are left out.
    pub fn config_hash(&self) -> u64 {
        let decides = serde_json::json!({
            "config": self.config,
            "html": self.html,
            "sigma_map": self.sigma_map,
            "slice_row": self.slice_row,
        });
        xxhash_rust::xxh3::xxh3_64(decides.to_string().as_bytes())
    }
}

/// Checks the decisions file can be written, before any work.
fn check_decisions_path(p: &Path) -> Result<()> {
    if p.is_dir() {
        bail!("{}: --decisions names a directory", p.display());
    }
    if let Some(parent) = p.parent().filter(|d| !d.as_os_str().is_empty())
        && !parent.is_dir()
    {
        bail!("{}: no such directory for --decisions", parent.display());
    }
    Ok(())
}

/// Runs `opts` with no progress shown.
pub fn filter(opts: &FilterOptions) -> Result<FilterReport> {
    filter_with_progress(opts, &Silent)
}

/// Runs the pipeline on the dump of `opts` and writes its outputs.
pub fn filter_with_progress(opts: &FilterOptions, progress: &dyn Progress) -> Result<FilterReport> {
    let t_start = Instant::now();
    let started = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    opts.config.validate()?;
    let dump = DumpReader::open(&opts.dump)?;
    let h = dump.header().clone();
    if let Some(row) = opts.slice_row
        && row >= h.height
    {
        bail!(
            "--slice-row {row} is outside the film (height {})",
            h.height
        );
    }
    let reference = opts
        .reference
        .as_ref()
        .map(|p| exr::read_reference(p, h.width as usize, h.height as usize, h.frames as usize))
        .transpose()?;
    if let Some(p) = &opts.decisions {
        check_decisions_path(p)?;
    }
    // Everything is written into a staging folder and swapped in at the
    // end: OUTDIR holds exactly one complete run at any time.
    let staging = Staging::create(&opts.out_dir)?;
    let open_seconds = t_start.elapsed().as_secs_f64();

    let records = dump.records();
    let exact_sigma = opts.exact_sigma(&h);
    progress.set_length(records.len() as u64);
    let run = pipeline::run(
        records,
        &h,
        &opts.config,
        &RunOptions {
            threads: opts.threads,
            exact_sigma,
            reference: reference.as_ref(),
            progress,
        },
    )?;

    let t_write = Instant::now();
    let dir = staging.path();
    // Every image is written (and previewed) on its own: in parallel.
    let pool = pipeline::thread_pool(opts.threads)?;
    // The dump's hash (for the provenance) beside the images.
    let (exrs, dump_xxh3) = pool.install(|| {
        rayon::join(
            || {
                run.images
                    .iter()
                    .map(|e| (e.name(), &e.image))
                    .chain([("rejected".to_string(), &run.removed)])
                    .collect::<Vec<_>>()
                    .par_iter()
                    .map(|(name, image)| exr::write_image(dir, name, image))
                    .collect::<Result<Vec<Vec<String>>, _>>()
            },
            || dump.content_hash(),
        )
    });
    let exrs = exrs?;
    let mut outputs: Vec<String> = exrs.into_iter().flatten().collect();
    // sigma.exr holds exact values only: the report's map may be an
    // estimate from a share of the samples.
    if let (Some(img), ExactSigma::All) = (&run.sigma_image, exact_sigma) {
        outputs.extend(exr::write_image(dir, "sigma", img)?);
    }
    let slice_row = opts.html.then(|| opts.slice_row.unwrap_or(h.height / 2));
    let sigma_scale = run.sigma_image.as_ref().and_then(plots::sigma_scale);
    let mean = run.image(Method::Mean).expect("every run makes the mean");
    let mut report = FilterReport {
        dump: opts.dump.display().to_string(),
        header: h.clone(),
        config: run.config,
        white: run.white,
        threads: run.threads,
        counts: run.counts.clone(),
        fallback_pixels: run.fallback_pixels,
        empty_pixels: run.empty_pixels,
        timing: Timing {
            open_seconds,
            streaming_seconds: run.streaming_seconds,
            final_pass_seconds: run.final_pass_seconds,
            reconstruct_seconds: run.reconstruct_seconds,
            write_seconds: 0.0,
            total_seconds: 0.0,
        },
        metrics: run.metrics.clone(),
        recommended: pipeline::recommended(&run.images),
        reference: opts.reference.as_ref().map(|p| p.display().to_string()),
        method_seconds: run.images.iter().map(|e| (e.name(), e.seconds)).collect(),
        energy_removed: EnergyRemoved::new(&run.removed, mean),
        sigma_scale,
        sigma_map_one_in: exact_sigma.share(),
        sigma_map_each_pixel: matches!(exact_sigma, ExactSigma::Strata(_)),
        slice_row,
        outputs: Vec::new(),
        warnings: run.warnings.clone(),
        provenance: Provenance {
            program: format!(
                "pathdensity {} (commit {})",
                env!("CARGO_PKG_VERSION"),
                env!("PATHDENSITY_COMMIT")
            ),
            command: std::env::args().collect(),
            dump_xxh3: format!("{dump_xxh3:016x}"),
            config_xxh3: format!("{:016x}", opts.config_hash()),
            reference_xxh3: reference
                .as_ref()
                .map(|r| format!("{:016x}", r.content_hash())),
            started_unix_seconds: started,
        },
    };
    if opts.html {
        let exposure = opts.config.exposure;
        let mut assets = Assets {
            images: Vec::new(),
            reference: None,
            sigma: None,
            slice_svg: None,
        };
        let previews = |name: &str, frames: Vec<image::RgbImage>, outputs: &mut Vec<String>| {
            frames
                .iter()
                .enumerate()
                .map(|(f, img)| {
                    let file = exr::frame_file_name(name, f, frames.len(), "png");
                    let bytes = png::encode(img)?;
                    atomic::write_bytes(&dir.join(&file), &bytes)?;
                    outputs.push(file);
                    Ok(bytes)
                })
                .collect::<Result<Vec<Vec<u8>>>>()
        };
        let tone = |img: &Image| -> Vec<image::RgbImage> {
            (0..img.frames)
                .map(|f| png::tone_map(img, f, exposure))
                .collect()
        };
        if let Some(r) = &reference {
            assets.reference = Some(previews("reference", tone(r), &mut outputs)?);
        }
        // The slice plot (one thread) beside the previews.
        let (pngs, svg) = pool.install(|| {
            rayon::join(
                || {
                    run.images
                        .par_iter()
                        .map(|e| {
                            let mut files = Vec::new();
                            let frames = previews(&e.name(), tone(&e.image), &mut files)?;
                            Ok((e.name(), frames, files))
                        })
                        .collect::<Result<Vec<(String, Vec<Vec<u8>>, Vec<String>)>>>()
                },
                || slice_row.map(|row| plots::slice_svg(records, &h, &run.decisions, row)),
            )
        });
        let pngs = pngs?;
        for (name, frames, files) in pngs {
            assets.images.push((name, frames));
            outputs.extend(files);
        }
        let frames = previews("rejected", tone(&run.removed), &mut outputs)?;
        assets.images.push(("rejected".to_string(), frames));
        if let (Some(img), Some(scale)) = (&run.sigma_image, sigma_scale) {
            let frames = (0..img.frames)
                .map(|f| plots::sigma_png(img, f, scale))
                .collect();
            assets.sigma = Some((previews("sigma", frames, &mut outputs)?, scale));
        }
        if let Some(svg) = svg {
            let svg = svg.map_err(|e| anyhow::anyhow!("cannot draw the slice plot: {e}"))?;
            atomic::write_bytes(&dir.join("slice.svg"), svg.as_bytes())?;
            outputs.push("slice.svg".into());
            assets.slice_svg = Some(svg);
        }
        outputs.push("report.html".into());
        outputs.push("report.json".into());
        report.outputs = outputs;
        atomic::write_bytes(
            &dir.join("report.html"),
            html::render(&report, &assets).as_bytes(),
        )?;
    } else {
        outputs.push("report.json".into());
        report.outputs = outputs;
    }
    report.timing.write_seconds = t_write.elapsed().as_secs_f64();
    report.timing.total_seconds = t_start.elapsed().as_secs_f64();
    let json = serde_json::to_vec_pretty(&report).expect("the report serialises");
    atomic::write_bytes(&dir.join("report.json"), &json)?;
    staging.commit()?;
    // After the swap: the decisions file may be inside OUTDIR.
    if let Some(p) = &opts.decisions {
        atomic::write_bytes(p, &run.decisions)?;
    }
    Ok(report)
}
