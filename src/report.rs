//! What a filter run tells its user: `report.json` and the summary table.

use std::collections::BTreeMap;

use crate::density::{FilterCounts, FilterParams};
use crate::dump::Header;
use crate::metrics::ImageMetrics;
use crate::recon::ReconFilter;

#[derive(Clone, Debug, serde::Serialize)]
pub struct Timing {
    pub open_seconds: f64,
    pub streaming_seconds: f64,
    pub final_pass_seconds: f64,
    pub reconstruct_seconds: f64,
    pub write_seconds: f64,
    pub total_seconds: f64,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct FilterReport {
    pub dump: String,
    pub header: Header,
    pub parameters: FilterParams,
    pub recon: ReconFilter,
    pub threads: usize,
    pub counts: FilterCounts,
    pub fallback_pixels: u64,
    pub empty_pixels: u64,
    pub timing: Timing,
    /// Per image name (`mean`, `filtered`), metrics against the reference.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub metrics: BTreeMap<String, ImageMetrics>,
    pub reference: Option<String>,
    pub outputs: Vec<String>,
}

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
        if !self.metrics.is_empty() {
            s += &format!(
                "  {:<10}{:>12}{:>14}{:>12}{:>10}\n",
                "image", "RMS", "RMS display", "relMSE", "energy"
            );
            for (name, m) in &self.metrics {
                let m = &m.pooled;
                s += &format!(
                    "  {:<10}{:>12.6}{:>14.6}{:>12.6}{:>10.4}\n",
                    name, m.rms, m.rms_display, m.rel_mse, m.energy_ratio
                );
            }
        }
        s
    }
}
