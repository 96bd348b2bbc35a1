//! Regression fixtures: a directory per fixture holding a dump, its
//! reference, a `manifest.json` (the configuration to run and the expected
//! counts and metrics) and the expected images under `expected/`.
//! [`check`] re-runs the configuration and reports every drift beyond the
//! stated tolerances; [`bless`] rewrites the expectations.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};

use crate::commands::filter::{FilterOptions, filter};
use crate::density::FilterCounts;
use crate::imagespace::bilateral::BilateralParams;
use crate::io::{atomic, exr};
use crate::joint::JointSpace;
use crate::methods::Method;
use crate::metrics::Metrics;
use crate::recon::ReconFilter;

/// The configuration a fixture runs (the `filter` options that matter).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Config {
    pub k: usize,
    pub sigma_image: f64,
    pub sigma_color: f64,
    pub sigma_time: f64,
    pub white: f64,
    /// `box` or `gaussian` (s = 0.5, r = 1.5).
    pub recon: String,
    pub alpha: f64,
    pub bilateral_sigma_s: f64,
    pub bilateral_sigma_r: f64,
}

impl Default for Config {
    fn default() -> Self {
        let s = JointSpace::default();
        let b = BilateralParams::default();
        Config {
            k: 10,
            sigma_image: s.sigma_image,
            sigma_color: s.sigma_color,
            sigma_time: s.sigma_time,
            white: s.white,
            recon: "box".into(),
            alpha: 0.1,
            bilateral_sigma_s: b.sigma_s,
            bilateral_sigma_r: b.sigma_r,
        }
    }
}

/// How far a re-run may drift before it is an error. Pixels compare as
/// |a − b| ≤ abs + rel · |b|; metrics as |a − b| ≤ rel · |b|. The slack
/// covers libm differences (cube roots, exponentials) between platforms.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Tolerance {
    pub pixel_abs: f64,
    pub pixel_rel: f64,
    pub metric_rel: f64,
}

impl Default for Tolerance {
    fn default() -> Self {
        Tolerance {
            pixel_abs: 1e-6,
            pixel_rel: 1e-5,
            metric_rel: 1e-5,
        }
    }
}

/// Counts that must match exactly.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq, Default)]
pub struct ExpectedCounts {
    pub valid: u64,
    pub invalid: u64,
    pub accepted_streaming: u64,
    pub accepted_final: u64,
    pub rejected: u64,
    pub stored: u64,
    pub fallback_pixels: u64,
}

impl ExpectedCounts {
    fn of(c: &FilterCounts, fallback_pixels: u64) -> ExpectedCounts {
        ExpectedCounts {
            valid: c.valid,
            invalid: c.invalid.total(),
            accepted_streaming: c.accepted_streaming,
            accepted_final: c.accepted_final,
            rejected: c.rejected,
            stored: c.stored,
            fallback_pixels,
        }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ExpectedMetrics {
    pub rms: f64,
    pub rms_display: f64,
    pub rel_mse: f64,
    pub energy_ratio: f64,
}

impl From<&Metrics> for ExpectedMetrics {
    fn from(m: &Metrics) -> Self {
        ExpectedMetrics {
            rms: m.rms,
            rms_display: m.rms_display,
            rel_mse: m.rel_mse,
            energy_ratio: m.energy_ratio,
        }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq, Default)]
pub struct Expected {
    pub counts: ExpectedCounts,
    /// Per image name, pooled metrics against the reference.
    pub metrics: BTreeMap<String, ExpectedMetrics>,
    /// Image files under `expected/`.
    pub images: Vec<String>,
}

/// `manifest.json`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Manifest {
    /// What the fixture shows and how it was made.
    pub description: String,
    pub dump: String,
    pub reference: String,
    #[serde(default)]
    pub config: Config,
    #[serde(default)]
    pub tolerance: Tolerance,
    #[serde(default)]
    pub expected: Expected,
}

/// Every fixture directory (one holding `manifest.json`) under `root`,
/// sorted by name.
pub fn find(root: &Path) -> Result<Vec<PathBuf>> {
    let rd = std::fs::read_dir(root)
        .with_context(|| format!("{}: cannot list fixtures", root.display()))?;
    let mut v: Vec<PathBuf> = rd
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("manifest.json").is_file())
        .collect();
    v.sort();
    if v.is_empty() {
        bail!(
            "{}: no fixture (a directory with manifest.json)",
            root.display()
        );
    }
    Ok(v)
}

fn read_manifest(dir: &Path) -> Result<Manifest> {
    let path = dir.join("manifest.json");
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{}: not a manifest", path.display()))
}

/// Runs a fixture's configuration into `out` (no HTML report).
fn run(dir: &Path, m: &Manifest, out: &Path) -> Result<crate::report::FilterReport> {
    let c = &m.config;
    let mut o = FilterOptions::new(dir.join(&m.dump), out);
    o.params.k = c.k;
    o.params.space = JointSpace {
        sigma_image: c.sigma_image,
        sigma_color: c.sigma_color,
        sigma_time: c.sigma_time,
        white: c.white,
    };
    o.recon = match c.recon.as_str() {
        "box" => ReconFilter::Box,
        "gaussian" => ReconFilter::gaussian(),
        other => bail!("{}: unknown recon {other:?}", dir.display()),
    };
    o.reference = Some(dir.join(&m.reference));
    o.alpha = c.alpha;
    o.bilateral = BilateralParams {
        sigma_s: c.bilateral_sigma_s,
        sigma_r: c.bilateral_sigma_r,
    };
    o.methods = Method::ALL.to_vec();
    o.html = false;
    o.threads = 1;
    filter(&o)
}

fn expected_of(report: &crate::report::FilterReport) -> Expected {
    Expected {
        counts: ExpectedCounts::of(&report.counts, report.fallback_pixels),
        metrics: report
            .metrics
            .iter()
            .map(|(n, m)| (n.clone(), (&m.pooled).into()))
            .collect(),
        images: report
            .outputs
            .iter()
            .filter(|f| f.ends_with(".exr"))
            .cloned()
            .collect(),
    }
}

/// Re-runs the fixture in `dir` and lists every drift from its
/// expectations (empty: the fixture passes).
pub fn check(dir: &Path) -> Result<Vec<String>> {
    let m = read_manifest(dir)?;
    let tmp = tempdir(dir)?;
    let report = run(dir, &m, tmp.path())?;
    let got = expected_of(&report);
    let want = &m.expected;
    let tol = &m.tolerance;
    let mut drift = Vec::new();
    if got.counts != want.counts {
        drift.push(format!(
            "counts: expected {:?}, got {:?}",
            want.counts, got.counts
        ));
    }
    for (name, w) in &want.metrics {
        let Some(g) = got.metrics.get(name) else {
            drift.push(format!("{name}: no longer produced"));
            continue;
        };
        for (what, a, b) in [
            ("RMS", g.rms, w.rms),
            ("RMS_display", g.rms_display, w.rms_display),
            ("relMSE", g.rel_mse, w.rel_mse),
            ("energy ratio", g.energy_ratio, w.energy_ratio),
        ] {
            if (a - b).abs() > tol.metric_rel * b.abs() {
                drift.push(format!("{name}: {what} {b:.6} → {a:.6}"));
            }
        }
    }
    for file in &want.images {
        let expected = dir.join("expected").join(file);
        let (_, _, want_px) = exr::read_rgb(&expected)?;
        let (_, _, got_px) = exr::read_rgb(&tmp.path().join(file))
            .with_context(|| format!("{file}: no longer written"))?;
        let (mut n, mut worst) = (0usize, (0.0f64, 0usize));
        for (i, (a, b)) in got_px.iter().zip(&want_px).enumerate() {
            for c in 0..3 {
                let d = (a[c] - b[c]).abs();
                if d > tol.pixel_abs + tol.pixel_rel * b[c].abs() {
                    n += 1;
                    if d > worst.0 {
                        worst = (d, i);
                    }
                }
            }
        }
        if n > 0 || got_px.len() != want_px.len() {
            drift.push(format!(
                "{file}: {n} channel values differ, largest |Δ| {:.3e} at pixel {}",
                worst.0, worst.1
            ));
        }
    }
    Ok(drift)
}

/// Re-runs the fixture in `dir` and stores its results as the expectations.
pub fn bless(dir: &Path) -> Result<Manifest> {
    let mut m = read_manifest(dir)?;
    let tmp = tempdir(dir)?;
    let report = run(dir, &m, tmp.path())?;
    m.expected = expected_of(&report);
    let expected_dir = dir.join("expected");
    if expected_dir.exists() {
        std::fs::remove_dir_all(&expected_dir)
            .with_context(|| format!("{}: cannot clear", expected_dir.display()))?;
    }
    std::fs::create_dir_all(&expected_dir)
        .with_context(|| format!("{}: cannot create", expected_dir.display()))?;
    for f in &m.expected.images {
        std::fs::copy(tmp.path().join(f), expected_dir.join(f))
            .with_context(|| format!("{}: cannot copy", expected_dir.join(f).display()))?;
    }
    let json = serde_json::to_string_pretty(&m).expect("a manifest serialises") + "\n";
    atomic::write_bytes(&dir.join("manifest.json"), json.as_bytes())?;
    Ok(m)
}

/// A scratch directory beside the system's temporary files, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn tempdir(fixture: &Path) -> Result<TempDir> {
    use std::sync::atomic::{AtomicU64, Ordering};
    static N: AtomicU64 = AtomicU64::new(0);
    let name = fixture
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let p = std::env::temp_dir().join(format!(
        "pathdensity-regress-{}-{}-{name}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&p).with_context(|| format!("{}: cannot create", p.display()))?;
    Ok(TempDir(p))
}
