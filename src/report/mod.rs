//! What a filter run tells its user: `report.json` and the summary table.

use std::collections::BTreeMap;

use crate::config::{FilterConfig, Method};
use crate::density::FilterCounts;
use crate::dump::Header;
use crate::joint::lab::luminance;
use crate::method::ImageId;
use crate::metrics::ImageMetrics;
use crate::recon::{Image, energy};

pub mod html;
pub mod plots;
pub mod sweep;
pub mod viewer;

use plots::SigmaScale;

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Timing {
    pub open_seconds: f64,
    pub streaming_seconds: f64,
    pub final_pass_seconds: f64,
    pub reconstruct_seconds: f64,
    pub write_seconds: f64,
    pub total_seconds: f64,
}

/// The radiance the path-density filter removed, `mean − filtered`
/// summed over the film ([`crate::recon::energy`]).
#[derive(Clone, Debug, serde::Serialize)]
pub struct EnergyRemoved {
    /// Σ over pixels, per channel.
    pub sum_rgb: [f64; 3],
    /// Σ Y(removed) / Σ Y(mean): the share of the mean's energy removed.
    pub fraction_of_mean: f64,
}

impl EnergyRemoved {
    pub fn new(removed: &Image, mean: &Image) -> EnergyRemoved {
        let sum_rgb = energy::channel_sums(removed);
        let mean = luminance(energy::channel_sums(mean));
        let removed_y = luminance(sum_rgb);
        EnergyRemoved {
            sum_rgb,
            fraction_of_mean: if mean != 0.0 { removed_y / mean } else { 0.0 },
        }
    }
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct FilterReport {
    pub dump: String,
    pub header: Header,
    /// The configuration as given (`white` may be `auto`).
    pub config: FilterConfig,
    /// The white luminance Y_w used (`config.white`, resolved).
    pub white: f64,
    pub threads: usize,
    pub counts: FilterCounts,
    pub fallback_pixels: u64,
    pub empty_pixels: u64,
    pub timing: Timing,
    /// Per image name (`mean`, `filtered`), metrics against the reference.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub metrics: BTreeMap<ImageId, ImageMetrics>,
    /// The image a user should use (`Method::by_preference`); the first row
    /// of the printed table.
    pub recommended: Option<ImageId>,
    pub reference: Option<String>,
    /// The denoiser the denoised images were made with: `OIDN 2.5.1
    /// (PATH)`, or `statmc` and why no OIDN was used ([`denoiser`]);
    /// absent when no image of the run is denoised.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub denoiser: Option<String>,
    /// The renderer's albedo and normal (OIDN's and statmc's), when given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub albedo: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normal: Option<String>,
    /// How OIDN takes them (`--aux-prefilter`), when an albedo was given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aux_prefilter: Option<String>,
    /// Wall time to produce each image from the dump, passes it shares
    /// with other images included (see README).
    pub method_seconds: BTreeMap<ImageId, f64>,
    /// What the path-density filter took out (`rejected.exr`).
    pub energy_removed: EnergyRemoved,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_scale: Option<SigmaScale>,
    /// The report's σ map is the mean over one sample in n (its exact σ),
    /// an estimate (docs/filter.md §3); absent when every sample's σ was
    /// computed or there is no map.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_map_one_in: Option<u32>,
    /// Those samples are one in n of each pixel's (`ExactSigma::Strata`),
    /// not about one in n picked by a hash.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub sigma_map_each_pixel: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slice_row: Option<u32>,
    pub outputs: Vec<String>,
    /// What the user should hear (most samples rejected, most pixels
    /// falling back).
    pub warnings: Vec<String>,
    pub provenance: Provenance,
}

/// What a report was made from and by, so a run can be reproduced and a
/// batch can tell a finished output from a stale one.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Provenance {
    /// `pathdensity`, its version and the git commit it was built from.
    pub program: String,
    /// The command line, one argument each.
    pub command: Vec<String>,
    /// XXH3-64 of the dump's header and records, in hex.
    pub dump_xxh3: String,
    /// XXH3-64 of what else decides the outputs: the configuration and the
    /// output choices (HTML report, σ map, slice row), in hex
    /// ([`crate::commands::filter::FilterOptions::config_hash`]).
    pub config_xxh3: String,
    /// XXH3-64 of the reference as read (its size and every pixel's
    /// bits, frame after frame), in hex.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_xxh3: Option<String>,
    /// When the run started, seconds since 1970-01-01 UTC.
    pub started_unix_seconds: u64,
}

pub use crate::pipeline::denoiser;

impl FilterReport {
    /// The short table the `filter` command prints.
    pub fn summary(&self) -> String {
        let c = &self.counts;
        let pct = |n: u64| 100.0 * n as f64 / c.valid.max(1) as f64;
        let mut s = String::new();
        s += &format!("{}\n", self.dump);
        s += &format!(
            "  records {:>12}   valid {:>12}   invalid {:>10}\n",
            c.records,
            c.valid,
            c.invalid.total()
        );
        s += &format!(
            "  accepted streaming {:>12} ({:6.2}%)\n  accepted final     {:>12} ({:6.2}%)\n  rejected           {:>12} ({:6.2}%)\n",
            c.accepted_streaming,
            pct(c.accepted_streaming),
            c.accepted_final,
            pct(c.accepted_final),
            c.rejected,
            pct(c.rejected)
        );
        s += &format!(
            "  stored (|T|) {:>10}   fallback pixels {:>8}   empty pixels {:>8}\n",
            c.stored, self.fallback_pixels, self.empty_pixels
        );
        let t = &self.timing;
        let rate = c.records as f64 / (t.streaming_seconds + t.final_pass_seconds).max(1e-9) / 1e6;
        s += &format!(
            "  time {:.3} s (filter {:.3} s = {:.2} M samples/s on {} thread(s))\n",
            t.total_seconds,
            t.streaming_seconds + t.final_pass_seconds,
            rate,
            self.threads
        );
        let best = self.best_rms();
        let rows: Vec<_> = self
            .method_rows()
            .into_iter()
            .map(|(id, seconds, m)| {
                let name = if self.recommended == Some(id) {
                    format!("{id} (use)")
                } else {
                    id.to_string()
                };
                (id, name, seconds, m)
            })
            .collect();
        // The name column as wide as its longest entry.
        let w = rows
            .iter()
            .map(|r| r.1.chars().count() + 1)
            .fold(20, usize::max);
        s += &format!(
            "  {:<w$}{:>12}{:>14}{:>12}{:>10}{:>9}{:>10}{:>10}\n",
            "image", "RMS", "RMS display", "relMSE", "energy", "FLIP", "HDR-FLIP", "seconds"
        );
        for (id, name, seconds, m) in rows {
            let mark = if best == Some(id) { "*" } else { " " };
            match m {
                Some(m) => {
                    let m = &m.pooled;
                    s += &format!(
                        "{mark} {:<w$}{:>12.6}{:>14.6}{:>12.6}{:>10.4}{:>9.4}{:>10.4}{:>10.3}\n",
                        name,
                        m.rms,
                        m.rms_display,
                        m.rel_mse,
                        m.energy_ratio,
                        m.flip,
                        m.hdr_flip,
                        seconds
                    );
                }
                None => s += &format!("  {:<w$}{:>77.3}\n", name, seconds),
            }
        }
        if best.is_some() {
            s += "  (* lowest RMS)\n";
        }
        if let Some(r) = &self.recommended {
            s += &format!("  (use) {r}: the recommended image (README, \"Which image to use\")\n");
        }
        if let Some(d) = &self.denoiser {
            s += &format!("  denoiser: {d}\n");
        }
        for n in self.notes() {
            s += &format!("  {n}\n");
        }
        s
    }

    /// What the reader should be told beside the numbers: the run's
    /// warnings, and rwmc's κ when the dump has too few samples for it.
    pub fn notes(&self) -> Vec<String> {
        let mut notes: Vec<String> = self
            .warnings
            .iter()
            .map(|w| format!("warning: {w}"))
            .collect();
        // rwmc's counting reliability is at most spp / κ: below κ samples
        // per pixel no cascade is fully trusted and the image darkens.
        let spp = self.header.spp as f64;
        if self.method_seconds.contains_key(&Method::Rwmc.into())
            && spp > 0.0
            && self.config.rwmc_kappa > spp / 2.0
        {
            notes.push(format!(
                "note: rwmc's κ = {} needs well over κ samples per pixel; with {} spp try --rwmc-kappa {}",
                self.config.rwmc_kappa,
                self.header.spp,
                (spp / 16.0).max(1.0)
            ));
        }
        notes
    }

    /// The counts, as one sentence.
    pub fn counts_line(&self) -> String {
        let c = &self.counts;
        let pct = |n: u64| 100.0 * n as f64 / c.valid.max(1) as f64;
        format!(
            "{} valid samples ({} invalid): {} accepted while streaming ({:.2}%), {} in the final pass ({:.2}%), {} rejected ({:.2}%); {} stored in T; {} pixels fell back to their median, {} are empty.",
            c.valid,
            c.invalid.total(),
            c.accepted_streaming,
            pct(c.accepted_streaming),
            c.accepted_final,
            pct(c.accepted_final),
            c.rejected,
            pct(c.rejected),
            c.stored,
            self.fallback_pixels,
            self.empty_pixels
        )
    }
}

impl FilterReport {
    /// (image name, seconds, metrics) for every image written, in the
    /// canonical method order.
    pub fn method_rows(&self) -> Vec<(ImageId, f64, Option<&ImageMetrics>)> {
        let first = self.recommended;
        let names = first
            .into_iter()
            .chain(ImageId::all().filter(|&n| Some(n) != first));
        names
            .filter_map(|n| {
                let secs = *self.method_seconds.get(&n)?;
                let metrics = self.metrics.get(&n);
                Some((n, secs, metrics))
            })
            .collect()
    }

    /// The image with the lowest linear RMS, if there is a reference.
    pub fn best_rms(&self) -> Option<ImageId> {
        self.metrics
            .iter()
            .min_by(|a, b| a.1.pooled.rms.total_cmp(&b.1.pooled.rms))
            .map(|(&n, _)| n)
    }
}
