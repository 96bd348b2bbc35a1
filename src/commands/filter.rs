//! `pathdensity filter`: read a dump, run the path-density filter and the
//! baselines, write the images, the decisions and the report.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};

use crate::density::{self, Decision, FilterParams};
use crate::dump::{DumpReader, Header};
use crate::imagespace::{self, bilateral::BilateralParams};
use crate::io::{atomic, exr, png};
use crate::joint::white::White;
use crate::methods::Method;
use crate::metrics;
use crate::recon::rwmc::{self, RwmcParams};
use crate::recon::{self, Image, ReconFilter, energy, groups::PixelGroups, mon, robust};
use crate::report::html::{self, Assets};
use crate::report::plots;
use crate::report::{EnergyRemoved, FilterReport, Timing};

#[derive(Clone, Debug)]
pub struct FilterOptions {
    pub dump: PathBuf,
    pub out_dir: PathBuf,
    pub params: FilterParams,
    pub recon: ReconFilter,
    pub reference: Option<PathBuf>,
    /// Exposure of the PNG previews and the display metrics.
    pub exposure: f64,
    /// Worker threads; 0 means rayon's default (one per core).
    pub threads: usize,
    pub decisions: Option<PathBuf>,
    pub sigma_map: bool,
    /// Extra images besides mean and filtered (SPEC §4 baselines).
    pub methods: Vec<Method>,
    /// α of the trimmed mean, in [0, 0.5).
    pub alpha: f64,
    pub bilateral: BilateralParams,
    /// Write the PNG previews, σ map, slice plot and `report.html` (turns
    /// the σ map on).
    pub html: bool,
    /// Film row of the slice plot (default: the middle row).
    pub slice_row: Option<u32>,
    /// Replace `params.space.white` by the dump's auto white
    /// ([`crate::joint::white`]).
    pub white_auto: bool,
    /// Groups of the median of means (mon, gmon).
    pub mon_groups: usize,
    pub rwmc: RwmcParams,
    /// σ_e of the energy-aware filter's spread, in pixels.
    pub energy_sigma: f64,
}

impl FilterOptions {
    /// Every method, the HTML report, the paper's parameters.
    pub fn new(dump: impl Into<PathBuf>, out_dir: impl Into<PathBuf>) -> FilterOptions {
        FilterOptions {
            dump: dump.into(),
            out_dir: out_dir.into(),
            params: FilterParams::default(),
            recon: ReconFilter::Box,
            reference: None,
            exposure: 1.0,
            threads: 0,
            decisions: None,
            sigma_map: false,
            methods: Method::ALL.to_vec(),
            alpha: 0.1,
            bilateral: BilateralParams::default(),
            html: true,
            slice_row: None,
            white_auto: false,
            mon_groups: mon::DEFAULT_GROUPS,
            rwmc: RwmcParams::default(),
            energy_sigma: energy::DEFAULT_SPREAD_SIGMA,
        }
    }

    fn check(&self) -> Result<()> {
        if self.params.k == 0 {
            bail!("--k must be at least 1");
        }
        self.params.space.validate().map_err(anyhow::Error::msg)?;
        if let ReconFilter::Gaussian { s, radius } = self.recon
            && !(s > 0.0 && s.is_finite() && radius >= 0.0 && radius.is_finite())
        {
            bail!("the gaussian filter needs s > 0 and a finite radius ≥ 0");
        }
        if !(0.0..0.5).contains(&self.alpha) {
            bail!("--alpha must lie in [0, 0.5), got {}", self.alpha);
        }
        if !(self.exposure > 0.0 && self.exposure.is_finite()) {
            bail!("--exposure must be finite and positive");
        }
        if self.mon_groups == 0 {
            bail!("--mon-groups must be at least 1");
        }
        if !(self.energy_sigma > 0.0 && self.energy_sigma <= 1e4) {
            bail!("--energy-sigma must lie in (0, 10000] pixels");
        }
        self.rwmc.validate().map_err(anyhow::Error::msg)?;
        self.bilateral.validate().map_err(anyhow::Error::msg)
    }
}

/// Fails early, before any work, when `dir` cannot take our files.
fn prepare_out_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create output directory", dir.display()))?;
    let probe = atomic::AtomicFile::new(dir.join("probe"));
    probe
        .create()
        .with_context(|| format!("{}: output directory is not writable", dir.display()))?;
    Ok(())
}

/// The images of one run, by method, with the seconds each took.
type Images = Vec<(Method, Image, f64)>;

pub fn filter(opts: &FilterOptions) -> Result<FilterReport> {
    let t_start = Instant::now();
    opts.check()?;
    let mut params = opts.params.clone();
    params.exact_sigma |= opts.sigma_map || opts.html;
    let methods = Method::with_core(&opts.methods);
    let dump = DumpReader::open(&opts.dump)?;
    let h = dump.header().clone();
    if opts.white_auto {
        params.space.white = White::Auto.resolve(dump.records(), &h);
    }
    // From here on the options carry the resolved white (the bilateral
    // filter's ΔE uses it too).
    let resolved = FilterOptions {
        params: params.clone(),
        ..opts.clone()
    };
    let opts = &resolved;
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
    prepare_out_dir(&opts.out_dir)?;
    let open_seconds = t_start.elapsed().as_secs_f64();

    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(opts.threads)
        .build()
        .context("cannot start the worker threads")?;
    let records = dump.records();
    let progress = super::progress_bar(records.len() as u64, "filter");
    let result = pool.install(|| density::run(records, &h, &params, &progress));
    progress.finish_and_clear();
    let filter_seconds = result.streaming_seconds + result.final_seconds;

    let t_recon = Instant::now();
    let rec = recon::reconstruct(records, &h, opts.recon, |i| {
        Decision::accepted(result.decisions[i])
    });
    let mean_seconds = t_recon.elapsed().as_secs_f64();
    let recon::Reconstruction {
        mean,
        filtered,
        occupancy,
        fallback_pixels,
        empty_pixels,
    } = rec;
    let removed = energy::removed(&mean, &filtered);
    let images = pool.install(|| {
        let core = (mean, filtered, occupancy, &removed);
        baselines(
            records,
            &h,
            opts,
            &methods,
            core,
            mean_seconds,
            filter_seconds,
        )
    });
    let sigma_img = result
        .sigma
        .as_ref()
        .map(|s| recon::sigma_map(records, &h, s));
    let mut metrics_by_image = BTreeMap::new();
    if let Some(r) = &reference {
        for (m, img, _) in &images {
            metrics_by_image.insert(m.name().into(), metrics::compare(img, r, opts.exposure));
        }
    }
    let reconstruct_seconds = t_recon.elapsed().as_secs_f64();

    let t_write = Instant::now();
    let dir = &opts.out_dir;
    let mut outputs = Vec::new();
    for (m, img, _) in &images {
        outputs.extend(exr::write_image(dir, m.name(), img)?);
    }
    outputs.extend(exr::write_image(dir, "rejected", &removed)?);
    if let Some(img) = &sigma_img {
        outputs.extend(exr::write_image(dir, "sigma", img)?);
    }
    if let Some(p) = &opts.decisions {
        atomic::write_bytes(p, &result.decisions)?;
    }
    let slice_row = opts.html.then(|| opts.slice_row.unwrap_or(h.height / 2));
    let sigma_scale = sigma_img.as_ref().and_then(plots::sigma_scale);
    let mut report = FilterReport {
        dump: opts.dump.display().to_string(),
        header: h.clone(),
        parameters: params,
        recon: opts.recon,
        threads: pool.current_num_threads(),
        counts: result.counts,
        fallback_pixels,
        empty_pixels,
        timing: Timing {
            open_seconds,
            streaming_seconds: result.streaming_seconds,
            final_pass_seconds: result.final_seconds,
            reconstruct_seconds,
            write_seconds: 0.0,
            total_seconds: 0.0,
        },
        metrics: metrics_by_image,
        reference: opts.reference.as_ref().map(|p| p.display().to_string()),
        method_seconds: images
            .iter()
            .map(|(m, _, s)| (m.name().to_string(), *s))
            .collect(),
        white_auto: opts.white_auto,
        energy_removed: EnergyRemoved::new(&removed, &images),
        mon_groups: opts.mon_groups,
        rwmc: opts.rwmc,
        energy_sigma: opts.energy_sigma,
        alpha: opts.alpha,
        bilateral: opts.bilateral,
        exposure: opts.exposure,
        sigma_scale,
        slice_row,
        outputs: Vec::new(),
    };
    if opts.html {
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
                .map(|f| png::tone_map(img, f, opts.exposure))
                .collect()
        };
        if let Some(r) = &reference {
            assets.reference = Some(previews("reference", tone(r), &mut outputs)?);
        }
        for (m, img, _) in &images {
            let frames = previews(m.name(), tone(img), &mut outputs)?;
            assets.images.push((m.name().to_string(), frames));
        }
        let frames = previews("rejected", tone(&removed), &mut outputs)?;
        assets.images.push(("rejected".to_string(), frames));
        if let (Some(img), Some(scale)) = (&sigma_img, sigma_scale) {
            let frames = (0..img.frames)
                .map(|f| plots::sigma_png(img, f, scale))
                .collect();
            assets.sigma = Some((previews("sigma", frames, &mut outputs)?, scale));
        }
        if let Some(row) = slice_row {
            let svg = plots::slice_svg(records, &h, &result.decisions, row)
                .map_err(|e| anyhow::anyhow!("cannot draw the slice plot: {e}"))?;
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
    Ok(report)
}

/// Every requested image, with the wall time to make it from the dump
/// (the passes it shares with other images included).
fn baselines(
    records: &[crate::dump::Record],
    h: &Header,
    opts: &FilterOptions,
    methods: &[Method],
    (mean, filtered, occupancy, removed): (Image, Image, Vec<u32>, &Image),
    mean_seconds: f64,
    filter_seconds: f64,
) -> Images {
    let mut list = Vec::new();
    let white = opts.params.space.white;
    let wants = |m| methods.contains(&m);
    let grouped = [Method::Median, Method::Trimmed, Method::Mon, Method::Gmon];
    if grouped.into_iter().any(wants) {
        let t = Instant::now();
        let groups = PixelGroups::new(records, h);
        let group_seconds = t.elapsed().as_secs_f64();
        let mut pair = |a: Method, b: Method, make: &dyn Fn() -> (Image, Image)| {
            if wants(a) || wants(b) {
                let t = Instant::now();
                let (ia, ib) = make();
                let secs = group_seconds + t.elapsed().as_secs_f64();
                for (m, img) in [(a, ia), (b, ib)] {
                    if wants(m) {
                        list.push((m, img, secs));
                    }
                }
            }
        };
        pair(Method::Median, Method::Trimmed, &|| {
            let r = robust::robust_images(&groups, h, opts.alpha);
            (r.median, r.trimmed)
        });
        pair(Method::Mon, Method::Gmon, &|| {
            let r = mon::mon_images(&groups, h, opts.mon_groups);
            (r.mon, r.gmon)
        });
    }
    let timed = |f: &dyn Fn() -> Image| {
        let t = Instant::now();
        let img = f();
        (img, t.elapsed().as_secs_f64())
    };
    if wants(Method::Bilateral) {
        let (img, s) = timed(&|| imagespace::bilateral(&mean, &occupancy, opts.bilateral, white));
        list.push((Method::Bilateral, img, mean_seconds + s));
    }
    if wants(Method::Median3) {
        let (img, s) = timed(&|| imagespace::median3(&mean, &occupancy));
        list.push((Method::Median3, img, mean_seconds + s));
    }
    if wants(Method::FilteredBilateral) {
        let (img, s) =
            timed(&|| imagespace::bilateral(&filtered, &occupancy, opts.bilateral, white));
        list.push((
            Method::FilteredBilateral,
            img,
            filter_seconds + mean_seconds + s,
        ));
    }
    if wants(Method::Rwmc) {
        let (img, s) = timed(&|| rwmc::rwmc(records, h, &opts.rwmc));
        list.push((Method::Rwmc, img, s));
    }
    if wants(Method::FilteredEnergy) {
        let (img, s) =
            timed(&|| energy::energy_aware(&filtered, removed, &occupancy, opts.energy_sigma));
        list.push((
            Method::FilteredEnergy,
            img,
            filter_seconds + mean_seconds + s,
        ));
    }
    list.push((Method::Mean, mean, mean_seconds));
    list.push((Method::Filtered, filtered, filter_seconds + mean_seconds));
    list.sort_by_key(|e| e.0);
    list
}
