//! The memory a run needs, predicted from the header before anything is
//! allocated: a dump of a few kilobytes may claim a film of any size, and
//! the images follow the film, not the file. A run that cannot fit is
//! refused in one line with the figure instead of aborting mid-way.
//!
//! Per pixel of every frame, the run's peak is the larger of two phases:
//! while the images are made, each made image keeps its result and the
//! one whose making costs most adds its working buffers
//! ([`crate::method::Row::bytes_per_pixel`]); while they are measured
//! against a reference, each has its metrics' planes beside it. Beside
//! the pixels: a few bytes a record, F6a's grid over every sample up to
//! [`GRID_SAMPLES`] records (it counts valid samples: a dump with more
//! records and fewer valid ones than that is under-predicted), the
//! exact σ kept, the reference and the renderer's images, and the
//! process's own. The mapped dump is the page cache's,
//! not the process's, and is not counted. docs/BENCHMARKS.md ("Memory a
//! film needs") has the measurements and how close the prediction comes.

use super::{PipelineError, RunOptions};
use crate::config::FilterConfig;
use crate::density::FinalPass;
use crate::density::evidence::GRID_SAMPLES;
use crate::dump::Header;
use crate::imagespace::aux::AuxPrefilter;
use crate::method::Method;

/// Bytes a run holds whatever its film: the binary, thread stacks.
const FIXED: u64 = 24_000_000;
/// Bytes OIDN's library holds once loaded (its weights and threads).
const FIXED_OIDN: u64 = 150_000_000;
/// Bytes more OIDN holds when told its auxiliary images are clean (the
/// larger network it then runs at high quality), beside [`AUX`] more a
/// pixel: a bound over what the quarter and the whole 1080p frame
/// measured (docs/BENCHMARKS.md, "OIDN's auxiliary images at 1080p").
const FIXED_OIDN_CLEAN: u64 = 130_000_000;
/// Bytes a pixel costs in the bare run, its pages written: the mean and
/// filtered images, the occupancy, the reconstruction's sums, the
/// replay's stored samples.
const PER_PIXEL: u64 = 90;
/// Bytes an image keeps a pixel once made (three f64).
const IMAGE: u64 = 24;
/// Bytes a pixel costs while the images are measured, beside the bare
/// run's: ꟻLIP's planes, and each image's with its own planes.
const MEASURING: u64 = 61;
const PER_IMAGE_MEASURED: u64 = 61;
/// Bytes a pixel of the reference, and of the renderer's albedo and
/// normal, held the whole run (the latter twice where OIDN prefilters
/// them: the run keeps OIDN's copy too).
const REFERENCE: u64 = 24;
const AUX: u64 = 24;
/// Bytes a pixel of the σ map: its image and its sums.
const SIGMA_MAP: u64 = IMAGE + 16;
/// Bytes a record costs beside its mapped bytes: its decision, the
/// replay's share.
const PER_RECORD: u64 = 3;
/// Bytes a valid sample costs in F6a's grid over every sample.
const PER_GRID_SAMPLE: u64 = 24;

/// The bytes a run of `config` with `options` on a dump of `header` holds
/// at its peak, about.
pub fn needed(config: &FilterConfig, header: &Header, options: &RunOptions) -> u64 {
    let pixels = film_pixels(header);
    let records = header.sample_count;
    let images = super::images_of(config);
    let oidn_bytes = Method::Oidn.row().bytes_per_pixel as u64;
    // (working bytes, bytes kept once made) of each image, a pixel: an
    // image OIDN denoises after its method keeps OIDN's buffers with it.
    let costs = images.iter().map(|&(m, denoised)| match denoised {
        true => (oidn_bytes, oidn_bytes),
        false => {
            let b = m.row().bytes_per_pixel as u64;
            (b, b.min(IMAGE))
        }
    });
    let kept: u64 = costs.clone().map(|(_, k)| k).sum();
    let making = costs.map(|(b, k)| b - k).max().unwrap_or(0);
    let made = PER_PIXEL + kept + making;
    let measuring = PER_PIXEL + MEASURING + PER_IMAGE_MEASURED * images.len() as u64;
    let mut per_pixel = match options.reference {
        Some(_) => made.max(measuring) + REFERENCE,
        None => made,
    };
    let oidn = images.iter().any(|&(m, d)| d || m.needs_oidn());
    let mut fixed = FIXED + if oidn { FIXED_OIDN } else { 0 };
    if let Some(aux) = options.aux {
        let prefiltered = oidn && aux.prefilter() == AuxPrefilter::Accurate;
        per_pixel += if prefiltered { 2 * AUX } else { AUX };
        if oidn && aux.prefilter().clean() {
            per_pixel += AUX;
            fixed += FIXED_OIDN_CLEAN;
        }
    }
    if options.exact_sigma.any() {
        per_pixel += SIGMA_MAP;
    }
    // Beyond GRID_SAMPLES the pass reads the dump past the stored samples.
    let grid = match config.final_pass {
        FinalPass::All if records <= GRID_SAMPLES => PER_GRID_SAMPLE * records,
        _ => 0,
    };
    pixels
        .saturating_mul(per_pixel)
        .saturating_add(records.saturating_mul(PER_RECORD))
        .saturating_add(grid)
        .saturating_add(options.exact_sigma.bytes(records))
        .saturating_add(fixed)
}

/// The pixels of every frame.
fn film_pixels(header: &Header) -> u64 {
    header.pixels() as u64 * header.frames as u64
}

/// What of [`needed`] the caller holds already: the reference and the
/// renderer's images, read before the run.
fn held(header: &Header, options: &RunOptions) -> u64 {
    let pixels = film_pixels(header);
    let reference = options.reference.map_or(0, |_| REFERENCE);
    let aux = options.aux.map_or(0, |_| AUX);
    pixels * (reference + aux)
}

/// The memory this machine can give a process now: Linux's estimate of
/// what is available without swapping, plus free swap. `None` where it
/// cannot be read (no limit is applied then).
pub fn available() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let field = |name: &str| -> Option<u64> {
        let line = text.lines().find(|l| l.starts_with(name))?;
        let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kb * 1024)
    };
    Some(field("MemAvailable:")? + field("SwapFree:").unwrap_or(0))
}

/// Refuses a run that would need more memory than the machine has: more
/// than it has free beside what the caller holds already.
pub fn check(
    config: &FilterConfig,
    header: &Header,
    options: &RunOptions,
) -> Result<(), PipelineError> {
    let needed = needed(config, header, options).saturating_sub(held(header, options));
    match available() {
        Some(free) if needed > free => Err(PipelineError::Memory {
            needed,
            free,
            film: format!(
                "{} × {} × {} frames",
                header.width, header.height, header.frames
            ),
        }),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::method::MethodSet;
    use crate::progress::Silent;
    use crate::recon::Image;

    fn config(methods: &str) -> FilterConfig {
        FilterConfig {
            methods: MethodSet::from_names(methods.split(',')).unwrap(),
            ..FilterConfig::default()
        }
    }

    fn options(reference: Option<&Image>) -> RunOptions<'_> {
        RunOptions {
            threads: 1,
            exact_sigma: crate::density::ExactSigma::None,
            reference,
            progress: &Silent,
            aux: None,
        }
    }

    fn frame(samples: u64) -> Header {
        Header {
            sample_count: samples,
            ..crate::recon::test_header(1920, 1080)
        }
    }

    const PIXELS: u64 = 1920 * 1080;

    /// Each record costs a few bytes, and up to 2²⁴ F6a's grid a few more.
    /// The bare run of the 1080p × 64-spp frame is predicted under 0.7 GB
    /// (docs/BENCHMARKS.md has what it measured).
    #[test]
    fn records_cost_a_few_bytes_and_the_grid_more_up_to_its_limit() {
        let bare = config("mean,filtered");
        let at = |n| needed(&bare, &frame(n), &options(None));
        assert!(at(1920 * 1080 * 64) < 700_000_000);
        assert_eq!(
            at(2_000) - at(1_000),
            1_000 * (PER_RECORD + PER_GRID_SAMPLE)
        );
        let beyond = GRID_SAMPLES + 1_000;
        assert_eq!(at(beyond + 1_000) - at(beyond), 1_000 * PER_RECORD);
        assert_eq!(
            at(GRID_SAMPLES) - at(GRID_SAMPLES + 1),
            GRID_SAMPLES * PER_GRID_SAMPLE - PER_RECORD
        );
        let stored = FilterConfig {
            final_pass: FinalPass::Stored,
            ..bare
        };
        let paper = needed(&stored, &frame(2_000), &options(None));
        assert_eq!(at(2_000) - paper, 2_000 * PER_GRID_SAMPLE);
    }

    /// Only the costliest image adds its working buffers; each other image
    /// adds what it keeps.
    #[test]
    fn the_costliest_image_is_made_once_the_others_are_kept() {
        let h = frame(1_000);
        let at = |m| needed(&config(m), &h, &options(None));
        let guided = at("mean,filtered,guided");
        assert_eq!(at("mean,filtered,guided,median3") - guided, PIXELS * IMAGE);
        assert!(at("mean,filtered,statmc") < guided);
        assert_eq!(at("mean,filtered,statmc,guided") - guided, PIXELS * IMAGE);
        // Made alone, an image costs its row's bytes.
        let bare = at("mean,filtered");
        let row = Method::Guided.row().bytes_per_pixel as u64;
        assert_eq!(guided - bare, PIXELS * row);
    }

    /// A reference costs its image the whole run and, measuring many
    /// images, more than making them; it is not counted twice against
    /// the memory the caller already holds it in.
    #[test]
    fn a_reference_costs_its_image_and_the_measuring() {
        let h = frame(1_000);
        let reference = Image::new(1, 1, 1);
        let c = config("mean,filtered,guided");
        let with = needed(&c, &h, &options(Some(&reference)));
        assert_eq!(with - needed(&c, &h, &options(None)), PIXELS * REFERENCE);
        assert_eq!(
            with - held(&h, &options(Some(&reference))),
            needed(&c, &h, &options(None))
        );
        let many = config("mean,filtered,median,trimmed,bilateral,mon,gmon,rwmc,clamp,median3");
        let more =
            needed(&many, &h, &options(Some(&reference))) - needed(&many, &h, &options(None));
        assert!(more > PIXELS * REFERENCE);
    }

    /// OIDN's library is counted once, whichever images use it.
    #[test]
    fn oidn_is_loaded_once() {
        let h = frame(1_000);
        let at = |m| needed(&config(m), &h, &options(None));
        let row = |m: Method| m.row().bytes_per_pixel as u64;
        let one = at("mean,filtered,oidn");
        let bare = at("mean,filtered");
        assert_eq!(one, bare + PIXELS * row(Method::Oidn) + FIXED_OIDN);
        let two = at("mean,filtered,oidn,oidn_ci");
        assert_eq!(
            two,
            bare + PIXELS * (IMAGE + row(Method::OidnCi)) + FIXED_OIDN
        );
    }

    /// The renderer's images are held the whole run and, like the
    /// reference, not counted twice against what the caller holds; the
    /// σ map costs its image, its sums and its kept σ.
    #[test]
    fn the_albedo_and_the_sigma_map_are_counted() {
        let h = frame(1_000);
        let c = config("mean,filtered,guided");
        let plain = needed(&c, &h, &options(None));
        let aux = crate::imagespace::oidn::Aux::new(&Image::new(1, 1, 1), None);
        let with_aux = RunOptions {
            aux: Some(&aux),
            ..options(None)
        };
        assert_eq!(needed(&c, &h, &with_aux) - plain, PIXELS * AUX);
        assert_eq!(needed(&c, &h, &with_aux) - held(&h, &with_aux), plain);
        let sigma = RunOptions {
            exact_sigma: crate::density::ExactSigma::All,
            ..options(None)
        };
        assert_eq!(
            needed(&c, &h, &sigma) - plain,
            PIXELS * SIGMA_MAP + 8 * 1_000
        );
    }

    /// OIDN told its auxiliary images are clean (`accurate`, `none`) runs
    /// a larger network; `accurate` also keeps the prefiltered copy.
    #[test]
    fn oidns_clean_mode_is_counted() {
        let h = frame(1_000);
        let c = config("mean,filtered,oidn");
        let with = |prefilter| {
            let aux = crate::imagespace::oidn::Aux::new(&Image::new(1, 1, 1), None)
                .with_prefilter(prefilter);
            let o = RunOptions {
                aux: Some(&aux),
                ..options(None)
            };
            needed(&c, &h, &o)
        };
        let fast = with(AuxPrefilter::Fast);
        let clean = PIXELS * AUX + FIXED_OIDN_CLEAN;
        assert_eq!(with(AuxPrefilter::None) - fast, clean);
        assert_eq!(with(AuxPrefilter::Accurate) - fast, clean + PIXELS * AUX);
        // Without OIDN the images are statmc's guide alone.
        let statmc = config("mean,filtered,guided");
        let aux = crate::imagespace::oidn::Aux::new(&Image::new(1, 1, 1), None);
        let o = RunOptions {
            aux: Some(&aux),
            ..options(None)
        };
        assert_eq!(
            needed(&statmc, &h, &o) - needed(&statmc, &h, &options(None)),
            PIXELS * AUX
        );
    }

    /// An image the bare run does not make costs at least what it keeps:
    /// a row below that would be counted as keeping less than its image.
    #[test]
    fn every_row_costs_at_least_its_image() {
        for m in Method::ALL {
            let bytes = m.row().bytes_per_pixel as u64;
            match m {
                Method::Mean | Method::Filtered => assert_eq!(bytes, 0),
                _ => assert!(bytes >= IMAGE, "{}", m.row().name),
            }
        }
    }

    /// Every frame is a film of its own.
    #[test]
    fn frames_multiply_the_pixels() {
        let c = config("mean,filtered,guided");
        let one = needed(&c, &frame(0), &options(None));
        let two = needed(
            &c,
            &Header {
                frames: 2,
                ..frame(0)
            },
            &options(None),
        );
        assert_eq!(two - one, one - FIXED);
    }
}
