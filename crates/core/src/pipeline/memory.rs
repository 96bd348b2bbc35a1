//! The memory a run needs, predicted from the header before anything is
//! allocated: a dump of a few kilobytes may claim a film of any size, and
//! the images follow the film, not the file. A run that cannot fit is
//! refused in one line with the figure instead of aborting mid-way.
//!
//! The run's peak is the larger of two phases, per pixel of every frame:
//! while the images are made, each made image keeps its result and the
//! one whose making costs most adds its working buffers
//! ([`crate::method::Row::bytes_per_pixel`]); while they are measured
//! against a reference, each image has its metrics' buffers beside it.
//! Beside the pixels, a few bytes a record (its decision and the replay's
//! index) and the process's own. The mapped dump is the page cache's, not
//! the process's, and is not counted. docs/BENCHMARKS.md ("Memory a film
//! needs") has the measurements and how close the prediction comes.

use super::PipelineError;
use crate::config::FilterConfig;
use crate::dump::Header;
use crate::method::Method;

/// Bytes a run holds whatever its film: the binary, thread stacks.
const FIXED: u64 = 24_000_000;
/// Bytes OIDN's library holds once loaded (its weights and threads).
const FIXED_OIDN: u64 = 150_000_000;
/// Bytes a pixel costs in the bare run (the mean and filtered images, the
/// occupancy, the reconstruction's sums).
const PER_PIXEL: u64 = 28;
/// Bytes an image holds a pixel once made (three f64).
const IMAGE: u64 = 24;
/// Bytes a pixel of the reference image costs, held the whole run.
const REFERENCE: u64 = 24;
/// Bytes a pixel costs while the images are measured: ꟻLIP's planes, and
/// each image's beside them.
const MEASURING: u64 = 61;
const PER_IMAGE_MEASURED: u64 = IMAGE + 37;
/// Bytes a record costs beside its mapped bytes (its decision byte and
/// the replay's share of it).
const PER_RECORD: u64 = 4;

/// The bytes a run of `config` on a dump of `header` holds at its peak,
/// about; `reference` whether its images are measured against one.
pub fn needed(config: &FilterConfig, header: &Header, reference: bool) -> u64 {
    let pixels = header.width as u64 * header.height as u64 * header.frames.max(1) as u64;
    let images = super::images_of(config);
    let oidn_bytes = Method::Oidn.row().bytes_per_pixel as u64;
    // (working bytes, bytes kept once made) of each image a pixel.
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
    let peak = match reference {
        true => {
            REFERENCE + made.max(PER_PIXEL + MEASURING + PER_IMAGE_MEASURED * images.len() as u64)
        }
        false => made,
    };
    let oidn = images.iter().any(|&(m, d)| d || m.needs_oidn());
    let fixed = FIXED + if oidn { FIXED_OIDN } else { 0 };
    pixels
        .saturating_mul(peak)
        .saturating_add(header.sample_count.saturating_mul(PER_RECORD))
        .saturating_add(fixed)
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

/// Refuses a run that would need more memory than the machine has.
pub fn check(config: &FilterConfig, header: &Header, reference: bool) -> Result<(), PipelineError> {
    let needed = needed(config, header, reference);
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

    fn config(methods: &str) -> FilterConfig {
        FilterConfig {
            methods: MethodSet::from_names(methods.split(',')).unwrap(),
            ..FilterConfig::default()
        }
    }

    fn frame(samples: u64) -> Header {
        Header {
            sample_count: samples,
            ..crate::recon::test_header(1920, 1080)
        }
    }

    /// The bare run of a 1080p × 64-spp dump holds about 0.5 GB (measured);
    /// 16 bytes a record, as first fitted, predicted 2.5 GB and refused it
    /// on a machine with 2 GB free.
    #[test]
    fn records_cost_a_few_bytes_each() {
        let bare = needed(&config("mean,filtered"), &frame(132_710_400), false);
        assert!(bare < 700_000_000, "{bare}");
        let fewer = needed(&config("mean,filtered"), &frame(1_000), false);
        assert_eq!(bare - fewer, (132_710_400 - 1_000) * PER_RECORD);
    }

    /// Only the costliest image adds its working buffers; each other image
    /// adds what it keeps.
    #[test]
    fn the_costliest_image_is_made_once_the_others_are_kept() {
        let h = frame(1_000);
        let pixels = 1920 * 1080;
        let guided = needed(&config("mean,filtered,guided"), &h, false);
        let with_median3 = needed(&config("mean,filtered,guided,median3"), &h, false);
        assert_eq!(with_median3 - guided, pixels * IMAGE);
        let statmc = needed(&config("mean,filtered,statmc"), &h, false);
        assert!(statmc < guided);
        let both = needed(&config("mean,filtered,statmc,guided"), &h, false);
        assert_eq!(both - guided, pixels * IMAGE);
    }

    /// A reference is held the whole run, and measuring many images can
    /// cost more than making them.
    #[test]
    fn a_reference_costs_its_image_and_the_measuring() {
        let h = frame(1_000);
        let pixels = 1920 * 1080;
        let c = config("mean,filtered,guided");
        let with = needed(&c, &h, true) - needed(&c, &h, false);
        assert_eq!(with, pixels * REFERENCE);
        let many = config("mean,filtered,median,trimmed,bilateral,mon,gmon,rwmc,clamp,median3");
        assert!(needed(&many, &h, true) - needed(&many, &h, false) > pixels * REFERENCE);
    }

    /// OIDN's library is counted once, whichever images use it.
    #[test]
    fn oidn_is_loaded_once() {
        let h = frame(1_000);
        let one = needed(&config("mean,filtered,oidn"), &h, false);
        let none = needed(&config("mean,filtered,statmc"), &h, false);
        let oidn = Method::Oidn.row().bytes_per_pixel as u64;
        let statmc = Method::Statmc.row().bytes_per_pixel as u64;
        assert_eq!(one - none + 1920 * 1080 * (statmc - oidn), FIXED_OIDN);
        let two = needed(&config("mean,filtered,oidn,oidn_ci"), &h, false);
        assert!(two - one < FIXED_OIDN);
    }
}
