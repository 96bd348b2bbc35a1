//! The pipeline as one library call: a dump's records and a configuration
//! in, the filter's decisions, one image per method and their metrics out,
//! with no file I/O. The `filter` command writes what [`run`] returns;
//! sweeps, the equal-time comparison and the regression fixtures call the
//! same pieces ([`replay`], [`reconstruct`], [`estimate::Estimators`]).

mod check;
pub mod estimate;
pub mod memory;

use crate::imagespace::aux::Aux;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Instant;

use crate::config::{ConfigError, Denoise, FilterConfig, FinalPass};
use crate::density::{self, Decision, ExactSigma, FilterCounts, FilterResult, ReplayOptions};
use crate::dump::{Header, Record};
use crate::imagespace::oidn::OidnError;
use crate::method::{ImageId, Method};
use crate::metrics::{self, ImageMetrics};
use crate::par::prelude::*;
use crate::progress::Progress;
use crate::recon::{self, Image, Reconstruction};
pub use check::{check, check_counted, k_fits, resolve_white};
use estimate::{Core, Estimators, Shared};

/// Why a run could not start.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    // The field's own message, not a source: `{:#}` would print it twice.
    #[error("{0}")]
    Config(ConfigError),
    #[error("cannot start the worker threads: {0}")]
    Threads(#[from] crate::par::ThreadPoolBuildError),
    #[error("no valid sample: every record is non-finite or outside the film (see `info`)")]
    NoValidSample,
    #[error(
        "--white auto needs a valid sample of positive luminance, and the dump has none (give --white a number)"
    )]
    NoWhite,
    #[error(
        "its {film} film needs about {:.1} GB more for the run, and this machine has {:.1} GB free (fewer --methods, or a smaller film)",
        *needed as f64 / 1e9,
        *free as f64 / 1e9
    )]
    Memory {
        needed: u64,
        free: u64,
        film: String,
    },
    #[error("{image}: {problem}")]
    Method { image: ImageId, problem: OidnError },
}

impl From<ConfigError> for PipelineError {
    fn from(e: ConfigError) -> Self {
        PipelineError::Config(e)
    }
}

/// How to run, beyond the configuration: nothing here changes an image.
pub struct RunOptions<'a> {
    /// Worker threads; 0 means one per core.
    pub threads: usize,
    /// Which samples' exact σ to keep (for the σ map; slower).
    pub exact_sigma: ExactSigma,
    /// Measure every image against this reference.
    pub reference: Option<&'a Image>,
    pub progress: &'a dyn Progress,
    /// The renderer's albedo and normal: OIDN's auxiliary images and
    /// statmc's guide.
    pub aux: Option<&'a crate::imagespace::oidn::Aux>,
}

/// One method's image and the seconds it took from the dump, the passes
/// it shares with other images included.
pub struct MethodImage {
    pub method: Method,
    /// Denoised by `config.denoise` after `method` (`METHOD+oidn`).
    pub denoised: bool,
    pub image: Arc<Image>,
    pub seconds: f64,
}

impl MethodImage {
    pub fn id(&self) -> ImageId {
        ImageId {
            method: self.method,
            denoised: self.denoised,
        }
    }
}

/// The recommended image among `images`: the first a run made in the
/// table's order of preference ([`Method::by_preference`]).
pub fn recommended(images: &[MethodImage]) -> Option<ImageId> {
    Method::by_preference()
        .into_iter()
        .find(|&m| images.iter().any(|e| e.id() == m.into()))
        .map(ImageId::from)
}

/// Which denoiser a run with `config` (and the renderer's `aux` images)
/// used, in one phrase for the summary and report.json: OIDN (its
/// version and file, and how it took the renderer's images) when an
/// image needs it, else the statistical denoiser and why OIDN was not
/// used (not asked for, or not found); `None` when no image is denoised.
pub fn denoiser(config: &FilterConfig, aux: Option<&Aux>) -> Option<String> {
    use crate::imagespace::oidn;
    use crate::method::Piece;
    if config.denoise == Denoise::Oidn || config.methods.iter().any(|m| m.needs_oidn()) {
        let images = |a: &Aux| match a.normal() {
            Some(_) => "albedo and normal",
            None => "albedo",
        };
        let given = aux.map_or(String::new(), |a| {
            format!(
                ", with the renderer's {} (--aux-prefilter {})",
                images(a),
                a.prefilter()
            )
        });
        return oidn::library().ok().map(|l| l.describe() + &given);
    }
    if !config
        .methods
        .iter()
        .any(|m| Piece::of(m).contains(&Piece::Statmc))
    {
        return None;
    }
    Some(match oidn::library() {
        Ok(_) => "statmc (OIDN found but not asked for: --methods)".to_string(),
        Err(why) => format!("statmc, the statistical denoiser ({why})"),
    })
}

/// The images a configuration makes, in order: every selected method, and
/// with `denoise` OIDN on each of them too (`oidn` is the mean's, so there
/// is no `mean+oidn`, and `oidn_ci` is denoised already).
pub fn images_of(config: &FilterConfig) -> Vec<(Method, bool)> {
    let denoise = config.denoise == Denoise::Oidn;
    let methods = if denoise {
        config.methods.with(Method::Oidn)
    } else {
        config.methods
    };
    let plain = methods.iter().map(|m| (m, false));
    let denoised = methods
        .iter()
        .filter(move |&m| denoise && m != Method::Mean && !m.needs_oidn())
        .map(|m| (m, true));
    plain.chain(denoised).collect()
}

/// Everything a run produced.
pub struct Run {
    /// The configuration as given (`white` may be `auto`).
    pub config: FilterConfig,
    /// The white luminance Y_w used.
    pub white: f64,
    pub threads: usize,
    /// One [`Decision`] byte per record, in file order.
    pub decisions: Vec<u8>,
    pub counts: FilterCounts,
    pub fallback_pixels: u64,
    pub empty_pixels: u64,
    /// Every image of `config.methods`, in the canonical order.
    pub images: Vec<MethodImage>,
    /// `mean − filtered`: what the filter took out.
    pub removed: Image,
    /// Per pixel the mean exact σ of its samples (with `exact_sigma`).
    pub sigma_image: Option<Image>,
    /// Per method name, against the reference (empty without one).
    pub metrics: BTreeMap<ImageId, ImageMetrics>,
    pub streaming_seconds: f64,
    pub final_pass_seconds: f64,
    /// After the replay: the filtered image, the images that need the
    /// decisions, the σ map and the metrics. The other images are made
    /// beside the replay, in its wall time ([`run`]).
    pub reconstruct_seconds: f64,
    /// What the user should hear (most samples rejected, most pixels
    /// falling back).
    pub warnings: Vec<String>,
}

impl Run {
    pub fn image(&self, m: Method) -> Option<&Image> {
        self.images
            .iter()
            .find(|e| e.method == m && !e.denoised)
            .map(|e| &*e.image)
    }
}

/// A thread pool of `threads` workers (0: one per core); [`crate::par::pool`].
pub fn thread_pool(threads: usize) -> Result<crate::par::ThreadPool, PipelineError> {
    Ok(crate::par::pool(threads)?)
}

/// What a user should hear about a run that succeeded: most samples
/// rejected, most pixels falling back to their median.
fn warnings(counts: &FilterCounts, fallback: u64, occupied: u64) -> Vec<String> {
    let mut w = Vec::new();
    let rejected = counts.rejected as f64 / counts.valid.max(1) as f64;
    if rejected > 0.5 {
        w.push(format!(
            "{:.0}% of the valid samples were rejected: the filter removed most of the image \
             (try a smaller k or a larger sigma_color)",
            100.0 * rejected
        ));
    }
    if occupied > 0 && fallback * 2 > occupied {
        w.push(format!(
            "{fallback} of {occupied} pixels kept no sample and fell back to their median \
             (try a smaller k)"
        ));
    }
    w
}

/// The path-density filter's replay (docs/filter.md) at white `white`, on
/// the current rayon pool.
pub fn replay(
    records: &[Record],
    header: &Header,
    config: &FilterConfig,
    white: f64,
    exact_sigma: ExactSigma,
    progress: &dyn Progress,
) -> FilterResult {
    let options = ReplayOptions {
        exact_sigma,
        ..ReplayOptions::default()
    };
    let space = config.space(white);
    let mut result = density::run(
        records,
        header,
        &space,
        config.k,
        config.index,
        &options,
        progress,
    );
    if config.final_pass == FinalPass::All {
        let k = config.k;
        density::evidence::final_pass_against_all(
            records,
            header,
            &space,
            k,
            exact_sigma,
            &mut result,
        );
    }
    result
}

/// The mean of every valid sample and the filtered image of those
/// `accepted(i)` says are accepted; `replay_seconds` is what deciding
/// them cost.
pub fn reconstruct(
    records: &[Record],
    header: &Header,
    config: &FilterConfig,
    accepted: impl Fn(usize) -> bool + Sync,
    replay_seconds: f64,
) -> Core {
    let t = Instant::now();
    let rec = recon::reconstruct(records, header, config.recon.filter(), accepted);
    Core::new(rec, t.elapsed().as_secs_f64(), replay_seconds)
}

/// Runs the whole pipeline on `records`.
///
/// The images that need neither the decisions
/// ([`Method::needs_decisions`]) nor the white luminance
/// ([`Method::needs_white`]) are made beside the checks, the white and the
/// replay, on the same threads, which take up their work where those leave
/// a core waiting (the checks and the white are serial passes, and so is
/// the replay's in-order pass), as are the confidence intervals the later
/// images need. After the replay, the images that need only the white and
/// the σ map are made beside the filtered image, and the images that need
/// the decisions follow it. A dump the checks refuse is refused once the
/// first images are made.
pub fn run(
    records: &[Record],
    header: &Header,
    config: &FilterConfig,
    options: &RunOptions,
) -> Result<Run, PipelineError> {
    config.validate()?;
    if let Some(aux) = options.aux {
        check::aux_fits(aux, header)?;
    }
    memory::check(config, header, options)?;
    let pool = thread_pool(options.threads)?;
    let shared = Shared::new(records, header);
    let wanted = images_of(config);
    // Each image starts once what it reads exists: the samples (beside the
    // replay), the white luminance (after it), or the decisions (after
    // the filtered image).
    let (decided, undecided): (Vec<_>, Vec<_>) =
        wanted.iter().partition(|(m, _)| m.needs_decisions());
    let (white_only, beside): (Vec<_>, Vec<_>) =
        undecided.iter().partition(|(m, _)| m.needs_white());
    let (main, early) = pool.install(|| {
        crate::par::join(
            || -> Result<_, PipelineError> {
                check(config, records, header)?;
                let white = resolve_white(config, records, header)?;
                let result = replay(
                    records,
                    header,
                    config,
                    white,
                    options.exact_sigma,
                    options.progress,
                );
                Ok((result, white))
            },
            || {
                let t = Instant::now();
                let (mean, occupancy) = recon::mean(records, header, config.recon.filter());
                // Every sample accepted: decision-free images read no filtered image.
                let rec = Reconstruction::all_accepted(Arc::new(mean), occupancy);
                let core = Core::new(rec, t.elapsed().as_secs_f64(), 0.0);
                // Beside the replay, whose bar counts samples: not counted.
                let images = images(
                    &Estimators::before_white(&shared, config, &core).with_aux(options.aux),
                    &beside,
                    &crate::progress::Silent,
                );
                // What the later images share that reads only the samples.
                shared.prepare(&decided);
                (images, core)
            },
        )
    });
    let (mut result, white) = main?;
    // The images made after the replay, then their metrics, as a stage
    // of their own: at a production frame's size they take as long.
    let measured = options.reference.is_some() as usize;
    let after = (white_only.len() + decided.len() + measured) as u64;
    options.progress.stage("images", after);
    release_freed_memory();
    // The exact σ are read once, by the σ map, and dropped as soon as it
    // is made (at 8 a pixel, the most the report takes, they weigh more
    // than five images).
    let sigmas = result.sigma.take();
    let t = Instant::now();
    let replay_seconds = result.streaming_seconds + result.final_seconds;
    let accepted = |i: usize| Decision::accepted(result.decisions[i]);
    let (early, undecided_core) = early;
    let mean_seconds = undecided_core.reconstruct_seconds;
    // The filtered image and the images made from it, beside the σ map and
    // the images that needed only the white.
    let ((core, late), (whitened, sigma_image)) = pool.install(|| {
        crate::par::join(
            || {
                let filter = config.recon.filter();
                let undecided = &undecided_core.reconstruction;
                let (mean, occupancy) = (undecided.mean.clone(), undecided.occupancy.clone());
                let rec = Reconstruction::new(records, header, filter, mean, occupancy, accepted);
                let seconds = mean_seconds + t.elapsed().as_secs_f64();
                let core = Core::new(rec, seconds, replay_seconds);
                let late = images(
                    &Estimators::new(&shared, config, white, &core)
                        .with_aux(options.aux)
                        .with_decisions(&result.decisions),
                    &decided,
                    options.progress,
                );
                (core, late)
            },
            || {
                crate::par::join(
                    || {
                        images(
                            &Estimators::new(&shared, config, white, &undecided_core)
                                .with_aux(options.aux),
                            &white_only,
                            options.progress,
                        )
                    },
                    || sigmas.map(|s| density::sigma_map(records, header, &s)),
                )
            },
        )
    });
    let mut images: Vec<MethodImage> = early?.into_iter().chain(whitened?).chain(late?).collect();
    images.sort_by_key(|e| wanted.iter().position(|&w| w == (e.method, e.denoised)));
    let metrics = match options.reference {
        Some(r) => {
            let all: Vec<&Image> = images.iter().map(|e| &*e.image).collect();
            let m = metrics::compare_all(&all, r, config.exposure);
            options.progress.inc(1);
            images.iter().map(MethodImage::id).zip(m).collect()
        }
        None => BTreeMap::new(),
    };
    let rec = &core.reconstruction;
    let (fallback_pixels, empty_pixels) = (rec.fallback_pixels, rec.empty_pixels);
    let occupied = rec.occupancy.len() as u64 - empty_pixels;
    let mut warnings = warnings(&result.counts, fallback_pixels, occupied);
    let (non_finite, negative) = shared.oidn_zeroed();
    if non_finite + negative > 0 {
        warnings.push(format!(
            "OIDN takes finite, non-negative values: {non_finite} non-finite and {negative} negative channels of its inputs were set to 0"
        ));
    }
    options.progress.finish();
    Ok(Run {
        config: *config,
        white,
        threads: pool.current_num_threads(),
        decisions: result.decisions,
        counts: result.counts,
        fallback_pixels,
        empty_pixels,
        images,
        removed: core.removed,
        sigma_image,
        metrics,
        streaming_seconds: result.streaming_seconds,
        final_pass_seconds: result.final_seconds,
        reconstruct_seconds: t.elapsed().as_secs_f64(),
        warnings,
    })
}

/// Gives the replay's freed buffers back to the system before the images
/// are made: glibc keeps freed blocks below its mmap threshold (up to
/// 32 MB) in its arenas, which would otherwise count again at the run's
/// peak.
fn release_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns unused memory of the allocator.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// `wanted`'s images in parallel, after the work they share (each is
/// deterministic on its own), each a step of `progress` once made.
fn images(
    estimators: &Estimators,
    wanted: &[(Method, bool)],
    progress: &dyn Progress,
) -> Result<Vec<MethodImage>, PipelineError> {
    estimators.prepare(wanted);
    wanted
        .par_iter()
        .map(|&(method, denoised)| {
            let made = if denoised {
                estimators.denoised(method)
            } else {
                estimators.image(method)
            };
            let (image, seconds) = made.map_err(|problem| PipelineError::Method {
                image: ImageId { method, denoised },
                problem,
            })?;
            progress.inc(1);
            Ok(MethodImage {
                method,
                denoised,
                image,
                seconds,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests;
