//! `pathdensity filter`: read a dump, run the path-density filter and the
//! baselines, write the images, the decisions and the report.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result, bail};

use crate::config::{FilterConfig, Method};
use crate::density::{Decision, ExactSigma};
use crate::dump::{DumpReader, Header};
use crate::imagespace::aux::{Aux, AuxPrefilter};
use crate::io::atomic::{self, Staging};
use crate::io::guard::Inputs;
use crate::io::{exr, png};
use crate::par::prelude::*;
use crate::pipeline::{self, RunOptions};
use crate::progress::{Progress, Silent};
use crate::recon::Image;
use crate::report::html::{self, Assets};
use crate::report::plots;
use crate::report::viewer::{self, Kind, Shown};
use crate::report::{EnergyRemoved, FilterReport, Provenance, Timing};

#[derive(Clone, Debug)]
pub struct FilterOptions {
    pub dump: PathBuf,
    pub out_dir: PathBuf,
    pub config: FilterConfig,
    pub reference: Option<PathBuf>,
    /// The renderer's albedo and normal images: OIDN's auxiliary inputs
    /// and statmc's guide (a normal only with an albedo).
    pub albedo: Option<PathBuf>,
    pub normal: Option<PathBuf>,
    /// How OIDN treats them.
    pub aux_prefilter: AuxPrefilter,
    /// Worker threads; 0 means one per core.
    pub threads: usize,
    pub decisions: Option<PathBuf>,
    pub sigma_map: bool,
    /// Write the PNG previews, σ map, slice plot and `report.html` (turns
    /// the σ map on).
    pub html: bool,
    /// Film row of the slice plot (default: the middle row).
    pub slice_row: Option<u32>,
    /// Files besides the dump and the reference that the outputs must not
    /// replace or hold (a batch's other dumps), shared by a batch's runs.
    pub protect: Arc<Inputs>,
}

impl FilterOptions {
    /// The default configuration, the HTML report.
    pub fn new(dump: impl Into<PathBuf>, out_dir: impl Into<PathBuf>) -> FilterOptions {
        FilterOptions {
            dump: dump.into(),
            out_dir: out_dir.into(),
            config: FilterConfig::DEFAULT,
            reference: None,
            albedo: None,
            normal: None,
            aux_prefilter: AuxPrefilter::default(),
            threads: 0,
            decisions: None,
            sigma_map: false,
            html: true,
            slice_row: None,
            protect: Arc::default(),
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

/// Checks the decisions file can be written, before any work: its folder
/// exists, it is no input, and it replaces only a previous decisions file.
fn check_decisions_path(p: &Path, inputs: &Inputs) -> Result<()> {
    if p.is_dir() {
        bail!("{}: --decisions names a directory", p.display());
    }
    if let Some(parent) = p.parent().filter(|d| !d.as_os_str().is_empty())
        && !parent.is_dir()
    {
        bail!("{}: no such directory for --decisions", parent.display());
    }
    // A decisions file is one byte a record, each a `Decision`.
    let decision_bytes = |head: &[u8]| head.iter().all(|&b| b <= Decision::Rejected as u8);
    Ok(inputs.check_file(p, decision_bytes)?)
}

/// Every file the run reads, which no output may be or hold.
fn inputs(opts: &FilterOptions, frames: usize) -> Inputs {
    let mut inputs = Inputs::of([&opts.dump]);
    for r in [&opts.reference, &opts.albedo, &opts.normal]
        .into_iter()
        .flatten()
    {
        for p in exr::reference_files(r, frames) {
            inputs.add(&p);
        }
    }
    inputs
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
    let film = |p: &PathBuf| {
        exr::read_reference(p, h.width as usize, h.height as usize, h.frames as usize)
    };
    let reference = opts.reference.as_ref().map(film).transpose()?;
    let aux = read_aux(opts, film)?;
    let inputs = inputs(opts, h.frames as usize);
    if let Some(p) = &opts.decisions {
        check_decisions_path(p, &inputs)?;
    }
    // Everything is written into a staging folder and swapped in at the
    // end: OUTDIR holds exactly one complete run at any time, and is
    // replaced only when it is ours or new.
    let staging = Staging::create(&opts.out_dir, &inputs)?;
    opts.protect.check_dir(&opts.out_dir)?;
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
            aux: aux.as_ref(),
        },
    );
    // A refusal or a failure leaves no bar above its message.
    progress.finish();
    dump.intact()?;
    // A property of the dump (no valid sample, too large a film) names it.
    let run = run.with_context(|| opts.dump.display().to_string())?;
    let clock = Clock {
        start: t_start,
        started,
        open_seconds,
    };
    // Errors name OUTDIR's files, not the hidden staging folder's.
    let report = write_outputs(
        opts,
        &dump,
        &run,
        reference.as_ref(),
        aux.as_ref(),
        staging.path(),
        &clock,
    )
    .map_err(|e| anyhow::anyhow!("{}", staging.in_dest(&format!("{e:#}"))))?;
    // The hash and the slice plot read the records too.
    dump.intact()?;
    staging.commit()?;
    // After the swap: the decisions file may be inside OUTDIR.
    if let Some(p) = &opts.decisions {
        atomic::write_bytes(p, &run.decisions)?;
    }
    Ok(report)
}

/// The renderer's albedo and normal, OIDN's auxiliary images and statmc's
/// guide, read with `film` (sized to the dump's film).
fn read_aux(
    opts: &FilterOptions,
    film: impl Fn(&PathBuf) -> std::result::Result<Image, pathdensity_format::Error>,
) -> Result<Option<Aux>> {
    let Some(albedo) = &opts.albedo else {
        if opts.normal.is_some() {
            bail!("--normal needs --albedo (a normal is taken only with an albedo)");
        }
        return Ok(None);
    };
    let albedo = film(albedo)?;
    let normal = opts.normal.as_ref().map(film).transpose()?;
    Ok(Some(
        Aux::new(&albedo, normal.as_ref()).with_prefilter(opts.aux_prefilter),
    ))
}

/// When the run started, and how long opening it took.
struct Clock {
    start: Instant,
    started: u64,
    open_seconds: f64,
}

/// The viewer's images in display order: the recommended one, the
/// reference, the other images as the run made them, and `rejected`.
fn shown<'a>(
    report: &FilterReport,
    run: &'a pipeline::Run,
    reference: Option<&'a Image>,
) -> Vec<Shown<'a>> {
    let named = |name: String, kind, image| Shown {
        caption: html::caption(report, &name),
        name,
        kind,
        image,
    };
    let recommended = run
        .images
        .iter()
        .find(|e| Some(e.id()) == report.recommended);
    let mut shown: Vec<Shown> = recommended
        .map(|e| named(e.id().to_string(), Kind::Recommended, &e.image))
        .into_iter()
        .collect();
    shown.extend(reference.map(|r| named("reference".into(), Kind::Reference, r)));
    for e in run
        .images
        .iter()
        .filter(|e| Some(e.id()) != report.recommended)
    {
        let kind = if e.denoised {
            Kind::Denoised
        } else {
            Kind::Method
        };
        shown.push(named(e.id().to_string(), kind, &e.image));
    }
    shown.push(named("rejected".into(), Kind::Diagnostic, &run.removed));
    shown
}

/// Writes every output of `run` into `dir` and returns the report.
fn write_outputs(
    opts: &FilterOptions,
    dump: &DumpReader,
    run: &pipeline::Run,
    reference: Option<&Image>,
    aux: Option<&Aux>,
    dir: &Path,
    clock: &Clock,
) -> Result<FilterReport> {
    let (t_start, started, open_seconds) = (clock.start, clock.started, clock.open_seconds);
    let h = dump.header();
    let records = dump.records();
    let exact_sigma = opts.exact_sigma(h);
    let t_write = Instant::now();
    // Every image is written (and previewed) on its own: in parallel.
    let pool = pipeline::thread_pool(opts.threads)?;
    // The dump's hash (for the provenance) beside the images.
    let (exrs, dump_xxh3) = pool.install(|| {
        crate::par::join(
            || {
                run.images
                    .iter()
                    .map(|e| (e.id().to_string(), &*e.image))
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
        denoiser: crate::report::denoiser(&run.config, aux),
        albedo: opts.albedo.as_ref().map(|p| p.display().to_string()),
        normal: opts.normal.as_ref().map(|p| p.display().to_string()),
        aux_prefilter: opts
            .albedo
            .as_ref()
            .map(|_| opts.aux_prefilter.name().to_string()),
        method_seconds: run.images.iter().map(|e| (e.id(), e.seconds)).collect(),
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
            viewer: String::new(),
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
            previews("reference", tone(r), &mut outputs)?;
        }
        // The slice plot (one thread) beside the previews.
        let (pngs, svg) = pool.install(|| {
            crate::par::join(
                || {
                    run.images
                        .par_iter()
                        .map(|e| {
                            let mut files = Vec::new();
                            let frames = previews(&e.id().to_string(), tone(&e.image), &mut files)?;
                            Ok((e.id().to_string(), frames, files))
                        })
                        .collect::<Result<Vec<(String, Vec<Vec<u8>>, Vec<String>)>>>()
                },
                || slice_row.map(|row| plots::slice_svg(records, h, &run.decisions, row)),
            )
        });
        for (_, _, files) in pngs? {
            outputs.extend(files);
        }
        previews("rejected", tone(&run.removed), &mut outputs)?;
        assets.viewer = viewer::data(&shown(&report, run, reference), exposure);
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
        html::write(&report, &assets, &dir.join("report.html"))?;
    } else {
        outputs.push("report.json".into());
        report.outputs = outputs;
    }
    report.timing.write_seconds = t_write.elapsed().as_secs_f64();
    report.timing.total_seconds = t_start.elapsed().as_secs_f64();
    let json = serde_json::to_vec_pretty(&report).expect("the report serialises");
    atomic::write_bytes(&dir.join("report.json"), &json)?;
    Ok(report)
}
