//! Regression fixtures: a directory per fixture holding a dump, its
//! reference, a `manifest.json` (the configuration to run and the expected
//! counts and metrics) and the expected images under `expected/`.
//! [`check`] re-runs the configuration and reports every drift beyond the
//! stated tolerances; [`bless`] rewrites the expectations.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};

use crate::config::FilterConfig;
use crate::dump::DumpReader;
use crate::io::atomic::{self, Staging};
use crate::io::exr;
use crate::io::guard::{self, Inputs};
use crate::method::ImageId;
use crate::metrics::Metrics;
use crate::pipeline::{self, Run, RunOptions};
use crate::progress::Silent;
use crate::recon::{Image, stored};

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
    fn of(run: &Run) -> ExpectedCounts {
        let c = &run.counts;
        ExpectedCounts {
            valid: c.valid,
            invalid: c.invalid.total(),
            accepted_streaming: c.accepted_streaming,
            accepted_final: c.accepted_final,
            rejected: c.rejected,
            stored: c.stored,
            fallback_pixels: run.fallback_pixels,
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
    pub metrics: BTreeMap<ImageId, ExpectedMetrics>,
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
    /// The configuration to run (every field optional, as in
    /// [`FilterConfig`]); run on one thread, without the σ map.
    #[serde(default)]
    pub config: FilterConfig,
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

/// The largest `manifest.json` read: a fixture's is a few kilobytes.
const MANIFEST_LIMIT: u64 = 1 << 24;

fn read_manifest(dir: &Path) -> Result<Manifest> {
    let path = dir.join("manifest.json");
    let text = guard::read_input_text(&path, MANIFEST_LIMIT)?;
    serde_json::from_str(&text).with_context(|| format!("{}: not a manifest", path.display()))
}

/// A fixture's run: the pipeline on one thread, measured against the
/// fixture's reference, and every image as `filter` would write it (file
/// name, pixels as stored in the EXR).
struct Outcome {
    expected: Expected,
    files: Vec<(String, Image)>,
}

fn run(dir: &Path, m: &Manifest) -> Result<Outcome> {
    let path = dir.join(&m.dump);
    let dump = DumpReader::open(&path)?;
    let h = dump.header();
    let reference = exr::read_reference(
        &dir.join(&m.reference),
        h.width as usize,
        h.height as usize,
        h.frames as usize,
    )?;
    let run = pipeline::run(
        dump.records(),
        h,
        &m.config,
        &RunOptions {
            threads: 1,
            exact_sigma: crate::density::ExactSigma::None,
            reference: Some(&reference),
            progress: &Silent,
            aux: None,
        },
    );
    dump.intact()?;
    let run = run.with_context(|| format!("{}", dir.join("manifest.json").display()))?;
    let mut images: Vec<(String, &Image)> = Vec::new();
    for e in run.images.iter() {
        images.push((e.id().to_string(), &e.image));
    }
    images.push(("rejected".into(), &run.removed));
    let mut files = Vec::new();
    for (name, img) in images {
        for f in 0..img.frames {
            let mut frame = Image::new(img.width, img.height, 1);
            for (out, p) in frame.data.iter_mut().zip(img.frame(f)) {
                *out = p.map(|v| stored(v) as f64);
            }
            files.push((exr::frame_file_name(&name, f, img.frames, "exr"), frame));
        }
    }
    let expected = Expected {
        counts: ExpectedCounts::of(&run),
        metrics: run
            .metrics
            .iter()
            .map(|(&n, m)| (n, (&m.pooled).into()))
            .collect(),
        images: files.iter().map(|f| f.0.clone()).collect(),
    };
    Ok(Outcome { expected, files })
}

/// One line per count that changed, in words: `counts: stored 508 → 512`.
fn count_drifts(want: &ExpectedCounts, got: &ExpectedCounts) -> Vec<String> {
    let pairs = |c: &ExpectedCounts| {
        [
            ("valid", c.valid),
            ("invalid", c.invalid),
            ("accepted while streaming", c.accepted_streaming),
            ("accepted in the final pass", c.accepted_final),
            ("rejected", c.rejected),
            ("stored", c.stored),
            ("fallback pixels", c.fallback_pixels),
        ]
    };
    pairs(want)
        .into_iter()
        .zip(pairs(got))
        .filter(|(w, g)| w.1 != g.1)
        .map(|((name, w), (_, g))| format!("counts: {name} {w} → {g}"))
        .collect()
}

/// Re-runs the fixture in `dir` and lists every drift from its
/// expectations (empty: the fixture passes).
pub fn check(dir: &Path) -> Result<Vec<String>> {
    let m = read_manifest(dir)?;
    let outcome = run(dir, &m)?;
    let got = &outcome.expected;
    let want = &m.expected;
    let tol = &m.tolerance;
    let mut drift = Vec::new();
    drift.extend(count_drifts(&want.counts, &got.counts));
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
    for name in got.metrics.keys().filter(|n| !want.metrics.contains_key(n)) {
        drift.push(format!(
            "{name}: produced but not expected (--bless adds it)"
        ));
    }
    for (file, _) in outcome.files.iter().filter(|f| !want.images.contains(&f.0)) {
        drift.push(format!(
            "{file}: written but not expected (--bless adds it)"
        ));
    }
    for file in &want.images {
        let expected = dir.join("expected").join(file);
        let Some((_, got_img)) = outcome.files.iter().find(|f| &f.0 == file) else {
            drift.push(format!("{file}: no longer written"));
            continue;
        };
        let (_, _, want_px) = exr::read_rgb(&expected, got_img.width * got_img.height)?;
        let got_px = &got_img.data;
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
    let outcome = run(dir, &m)?;
    let old_images = std::mem::replace(&mut m.expected, outcome.expected).images;
    let expected_dir = dir.join("expected");
    adopt(&expected_dir, &old_images)?;
    // The images are staged and swapped in whole, then the manifest is
    // replaced: an interruption leaves the old expectations, or the new
    // images beside the old manifest (a drift the next bless repairs).
    let inputs = Inputs::of([dir.join(&m.dump), dir.join(&m.reference)]);
    let staging = Staging::create(&expected_dir, &inputs)?;
    for (file, img) in &outcome.files {
        exr::write_frame(&staging.path().join(file), img, 0)?;
    }
    staging.commit()?;
    let json = serde_json::to_string_pretty(&m).expect("a manifest serialises") + "\n";
    atomic::write_bytes(&dir.join("manifest.json"), json.as_bytes())?;
    Ok(m)
}

/// Marks `expected` as ours when it holds nothing but the images its
/// manifest lists (fixtures written before folders carried the marker),
/// so that [`Staging::create`] replaces it; anything else in it keeps it
/// refused.
fn adopt(expected: &Path, images: &[String]) -> Result<()> {
    if !expected.is_dir() || expected.join(guard::MARKER).exists() {
        return Ok(());
    }
    let listing = std::fs::read_dir(expected).with_context(|| format!("{}", expected.display()))?;
    for e in listing {
        let e = e.with_context(|| format!("{}", expected.display()))?;
        let name = e.file_name().to_string_lossy().into_owned();
        if !images.contains(&name) || !e.file_type().is_ok_and(|t| t.is_file()) {
            return Ok(());
        }
    }
    Ok(guard::write_marker(expected, images)?)
}
