//! The memory a run needs, predicted from the header before anything is
//! allocated: a dump of a few kilobytes may claim a film of any size, and
//! the images follow the film, not the file. A run that cannot fit is
//! refused in one line with the figure instead of aborting mid-way.

use super::PipelineError;
use crate::config::FilterConfig;
use crate::dump::Header;

/// Bytes a pixel of every frame costs whatever the methods (the mean, the
/// occupancy, the reconstruction's sums, the shared per-pixel passes).
const PER_PIXEL: u64 = 100;
/// Bytes a pixel costs for each image made (the image, its preview and
/// its metrics' buffers).
const PER_PIXEL_IMAGE: u64 = 18;
/// Bytes a record costs beside its mapped bytes (its decision, σ, and
/// the stored samples' index).
const PER_RECORD: u64 = 16;

/// The bytes a run of `config` on a dump of `header` holds at its peak,
/// about (docs/BENCHMARKS.md, "Memory a film needs", says how the
/// constants were measured).
pub fn needed(config: &FilterConfig, header: &Header) -> u64 {
    let pixels = header.width as u64 * header.height as u64 * header.frames.max(1) as u64;
    // Every method's image, the removed energy, the σ map and the reference.
    let images = super::images_of(config).len() as u64 + 3;
    let per_pixel = PER_PIXEL + PER_PIXEL_IMAGE * images;
    pixels
        .saturating_mul(per_pixel)
        .saturating_add(header.sample_count.saturating_mul(PER_RECORD))
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
pub fn check(config: &FilterConfig, header: &Header) -> Result<(), PipelineError> {
    let needed = needed(config, header);
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
