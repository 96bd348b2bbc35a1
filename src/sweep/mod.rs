//! Parameter sweeps: the path-density filter over every combination of k,
//! σ_color, σ_image and white of one dump, measured against a reference,
//! with the baselines run once as reference points. The dump is mapped
//! once; each configuration replays it through the pipeline's pieces.

pub mod equal_time;

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Result, bail};

use crate::config::{ColorSpace, FilterConfig, FinalPass, Method, White};
use crate::density::ExactSigma;
use crate::dump::{DumpReader, Header, Record};
use crate::io::exr;
use crate::method::{Param, Role};
use crate::metrics::{self, Metrics};
use crate::pipeline::estimate::{Estimators, Shared};
use crate::pipeline::{self, PipelineError, thread_pool};
use crate::progress::Progress;
use crate::recon::{Image, energy};

pub use equal_time::{EqualTimeRow, equal_time, equal_time_csv};

#[derive(Clone, Debug)]
pub struct SweepOptions {
    pub dump: PathBuf,
    pub reference: PathBuf,
    pub out_dir: PathBuf,
    /// Every field the lists below do not vary (σ_time, recon, exposure,
    /// the baselines' parameters).
    pub config: FilterConfig,
    pub ks: Vec<usize>,
    pub sigma_colors: Vec<f64>,
    pub sigma_images: Vec<f64>,
    pub whites: Vec<White>,
    pub color_spaces: Vec<ColorSpace>,
    pub final_passes: Vec<FinalPass>,
    /// Worker threads; 0 means one per core.
    pub threads: usize,
    /// Group counts of the median-of-means baselines (mon, gmon).
    pub mon_groups: Vec<usize>,
    /// κ values of the rwmc baseline.
    pub rwmc_kappas: Vec<f64>,
    /// C values of the clamp baseline.
    pub clamps: Vec<f64>,
}

/// The peer methods' configurations, one per swept value.
struct Peers {
    mon: Vec<FilterConfig>,
    rwmc: Vec<FilterConfig>,
    clamp: Vec<FilterConfig>,
}

impl Peers {
    /// The configurations that vary `param`.
    fn of(&self, param: Param) -> &[FilterConfig] {
        match param {
            Param::MonGroups => &self.mon,
            Param::RwmcKappa => &self.rwmc,
            Param::Clamp => &self.clamp,
        }
    }
}

/// A peer method's label in a sweep: its name and its parameter's value
/// in `c` (`mon groups=11`).
pub(crate) fn peer_label(method: Method, param: Param, c: &FilterConfig) -> String {
    let value = match param {
        Param::MonGroups => c.mon_groups.to_string(),
        Param::RwmcKappa => c.rwmc_kappa.to_string(),
        Param::Clamp => c.clamp.to_string(),
    };
    format!("{method} {}={value}", param.key())
}

impl SweepOptions {
    /// The default grid: k 5…200, σ_color 25…400, σ_image 1.5…6, white 1.
    pub fn new(
        dump: impl Into<PathBuf>,
        reference: impl Into<PathBuf>,
        out: impl Into<PathBuf>,
    ) -> Self {
        let d = FilterConfig::DEFAULT;
        SweepOptions {
            dump: dump.into(),
            reference: reference.into(),
            out_dir: out.into(),
            config: d,
            ks: vec![5, 10, 20, 50, 200],
            sigma_colors: vec![25.0, 50.0, 100.0, 200.0, 400.0],
            sigma_images: vec![1.5, 3.0, 6.0],
            whites: vec![d.white],
            color_spaces: vec![d.color_space],
            final_passes: vec![d.final_pass],
            threads: 0,
            mon_groups: vec![d.mon_groups],
            rwmc_kappas: vec![d.rwmc_kappa],
            clamps: vec![d.clamp],
        }
    }

    /// The base configuration with each peer value swept, checked:
    /// one per mon/gmon group count, one per rwmc κ, one per clamp C.
    fn peer_configs(&self) -> Result<Peers> {
        if self.mon_groups.is_empty() || self.rwmc_kappas.is_empty() || self.clamps.is_empty() {
            bail!("mon_groups, rwmc_kappa and clamp need one or more values");
        }
        let vary = |set: &dyn Fn(&mut FilterConfig)| {
            let mut c = self.config;
            set(&mut c);
            c.validate().map(|_| c)
        };
        Ok(Peers {
            mon: self
                .mon_groups
                .iter()
                .map(|&g| vary(&|c| c.mon_groups = g))
                .collect::<Result<_, _>>()?,
            rwmc: self
                .rwmc_kappas
                .iter()
                .map(|&k| vary(&|c| c.rwmc_kappa = k))
                .collect::<Result<_, _>>()?,
            clamp: self
                .clamps
                .iter()
                .map(|&v| vary(&|c| c.clamp = v))
                .collect::<Result<_, _>>()?,
        })
    }
}

/// One configuration's outcome.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Row {
    pub final_pass: FinalPass,
    pub color_space: ColorSpace,
    pub k: usize,
    pub sigma_color: f64,
    pub sigma_image: f64,
    /// As given (`1`, `auto`).
    pub white: String,
    /// The Y_w used.
    pub white_value: f64,
    /// Why the configuration did not run, if it did not.
    pub failure: Option<String>,
    /// Filter plus reconstruction wall time.
    pub seconds: f64,
    pub stored: u64,
    pub accepted_fraction: f64,
    pub fallback_pixels: u64,
    /// The filtered image's.
    pub metrics: Option<Metrics>,
    /// The energy-preserving variant's (`filtered_energy`).
    pub energy_metrics: Option<Metrics>,
}

/// A baseline measured once.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Baseline {
    /// The method whose image this is.
    #[serde(skip)]
    pub method: Method,
    /// Its name, and for a peer method the value of its swept parameter.
    #[serde(rename = "method")]
    pub label: String,
    pub seconds: f64,
    pub metrics: Metrics,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Sweep {
    pub dump: String,
    pub reference: String,
    pub header: Header,
    pub threads: usize,
    /// The exposure of the display transform (RMS_display, FLIP).
    pub exposure: f64,
    pub rows: Vec<Row>,
    pub baselines: Vec<Baseline>,
    /// What sweep.html's viewer shows.
    #[serde(skip)]
    pub images: SweepImages,
}

/// The images sweep.html shows: the filtered images of the rows with the
/// lowest FLIP and (when another row) the lowest RMS, the mean and the
/// reference.
#[derive(Clone)]
pub struct SweepImages {
    pub reference: Image,
    pub mean: Image,
    pub lowest_flip: Option<(usize, Image)>,
    pub lowest_rms: Option<(usize, Image)>,
}

impl std::fmt::Debug for SweepImages {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let row = |b: &Option<(usize, Image)>| b.as_ref().map(|(i, _)| *i);
        f.debug_struct("SweepImages")
            .field("lowest_flip", &row(&self.lowest_flip))
            .field("lowest_rms", &row(&self.lowest_rms))
            .finish_non_exhaustive()
    }
}

/// The row whose filtered image has the lowest `of` (the first on a tie).
fn lowest(rows: &[Row], of: fn(&Metrics) -> f64) -> Option<usize> {
    rows.iter()
        .enumerate()
        .filter_map(|(i, r)| r.metrics.as_ref().map(|m| (i, of(m))))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

/// Every configuration of the grid, in nested order (white outermost, k
/// innermost).
fn grid(o: &SweepOptions) -> Vec<FilterConfig> {
    let mut v = Vec::new();
    for (&final_pass, &color_space) in o
        .final_passes
        .iter()
        .flat_map(|f| o.color_spaces.iter().map(move |c| (f, c)))
    {
        for &white in &o.whites {
            for &sigma_image in &o.sigma_images {
                for &sigma_color in &o.sigma_colors {
                    for &k in &o.ks {
                        v.push(FilterConfig {
                            k,
                            sigma_color,
                            sigma_image,
                            white,
                            color_space,
                            final_pass,
                            ..o.config
                        });
                    }
                }
            }
        }
    }
    v
}

pub fn run(o: &SweepOptions, progress: &dyn Progress) -> Result<Sweep> {
    if o.ks.is_empty()
        || o.sigma_colors.is_empty()
        || o.sigma_images.is_empty()
        || o.whites.is_empty()
        || o.color_spaces.is_empty()
        || o.final_passes.is_empty()
    {
        bail!("every swept list needs at least one value");
    }
    o.config.validate()?;
    let peers = o.peer_configs()?;
    let dump = DumpReader::open(&o.dump)?;
    let h = dump.header().clone();
    let records = dump.records();
    let reference = exr::read_reference(
        &o.reference,
        h.width as usize,
        h.height as usize,
        h.frames as usize,
    )?;
    let pool = thread_pool(o.threads)?;

    // The baselines, once, at the base configuration; the peer methods
    // once per value of their swept parameter, labelled with it.
    let compare = |img: &Image| metrics::compare(img, &reference, o.config.exposure).pooled;
    let shared = Shared::new(records, &h);
    let base_white = pipeline::resolve_white(&o.config, records, &h)?;
    let (baselines, valid, mean) = pool.install(|| {
        let base = &o.config;
        let white = base_white;
        let core = pipeline::reconstruct(records, &h, base, |_| true, 0.0);
        let valid: u64 = core
            .reconstruction
            .occupancy
            .iter()
            .map(|&n| n as u64)
            .sum();
        let mut baselines = Vec::new();
        let mut add = |c: &FilterConfig, method: Method, label: String| -> Result<()> {
            let (img, seconds) = Estimators::new(&shared, c, white, &core)
                .image(method)
                .map_err(|e| anyhow::anyhow!("{label}: {e}"))?;
            baselines.push(Baseline {
                method,
                label,
                seconds,
                metrics: compare(&img),
            });
            Ok(())
        };
        for m in Method::with_role(|r| matches!(r, Role::Baseline | Role::EqualTime)) {
            add(base, m, m.name().to_string())?;
        }
        // Each value of a parameter, then every method that shares it.
        for param in Param::ALL {
            for c in peers.of(param) {
                for m in Method::with_role(|r| r == Role::Peer(param)) {
                    add(c, m, peer_label(m, param, c))?;
                }
            }
        }
        Ok::<_, anyhow::Error>((
            baselines,
            valid,
            Arc::unwrap_or_clone(core.reconstruction.mean),
        ))
    })?;

    let configs = grid(o);
    progress.set_length(configs.len() as u64);
    let mut whites: Vec<(White, Result<f64, String>)> = Vec::new();
    let mut rows = Vec::new();
    for config in &configs {
        let white_value = match whites.iter().find(|e| e.0 == config.white) {
            Some(e) => e.1.clone(),
            None => {
                let v = pipeline::resolve_white(config, records, &h).map_err(|e| e.to_string());
                whites.push((config.white, v.clone()));
                v
            }
        };
        let row = match white_value {
            Ok(white) => {
                pool.install(|| configuration(records, &h, config, white, &reference, valid).0)
            }
            Err(failure) => Row {
                failure: Some(failure),
                ..Row::unrun(config, f64::NAN)
            },
        };
        rows.push(row);
        progress.inc(1);
    }
    // The page's images: the one or two winning rows run again (the same
    // bytes), rather than every row's image held while the grid runs.
    let image_of = |i: usize| {
        let white = rows[i].white_value;
        pool.install(|| configuration(records, &h, &configs[i], white, &reference, valid).1)
            .map(|img| (i, img))
    };
    let flip_row = lowest(&rows, |m| m.flip);
    let rms_row = lowest(&rows, |m| m.rms).filter(|&i| Some(i) != flip_row);
    let lowest_flip = flip_row.and_then(image_of);
    let lowest_rms = rms_row.and_then(image_of);
    let images = SweepImages {
        reference,
        mean,
        lowest_flip,
        lowest_rms,
    };
    progress.finish();
    dump.intact()?;
    Ok(Sweep {
        dump: o.dump.display().to_string(),
        reference: o.reference.display().to_string(),
        header: h,
        threads: pool.current_num_threads(),
        exposure: o.config.exposure,
        rows,
        baselines,
        images,
    })
}

/// Runs one configuration: its row and its filtered image; a
/// configuration that cannot run is a row with its reason and no image.
fn configuration(
    records: &[Record],
    h: &Header,
    config: &FilterConfig,
    white_value: f64,
    reference: &Image,
    valid: u64,
) -> (Row, Option<Image>) {
    let mut row = Row::unrun(config, white_value);
    // The dump's valid samples were counted once for the whole sweep.
    // k first: a k the dump cannot serve is what a sweep's reader needs
    // to know about a row before any other refusal.
    let k_first = if config.k > 0 {
        pipeline::k_fits(config.k, valid)
    } else {
        Ok(())
    };
    let refused = k_first
        .and_then(|()| config.validate().map_err(PipelineError::from))
        .and_then(|()| pipeline::check_counted(config, h, valid));
    if let Err(e) = refused {
        row.failure = Some(e.to_string());
        return (row, None);
    }
    let t = Instant::now();
    let result = pipeline::replay(
        records,
        h,
        config,
        white_value,
        ExactSigma::None,
        &crate::progress::Silent,
    );
    let core = pipeline::reconstruct(
        records,
        h,
        config,
        |i| crate::density::Decision::accepted(result.decisions[i]),
        0.0,
    );
    row.seconds = t.elapsed().as_secs_f64();
    let c = &result.counts;
    row.stored = c.stored;
    row.accepted_fraction =
        (c.accepted_streaming + c.accepted_final) as f64 / c.valid.max(1) as f64;
    row.fallback_pixels = core.reconstruction.fallback_pixels;
    let rec = &core.reconstruction;
    row.metrics = Some(metrics::compare(&rec.filtered, reference, config.exposure).pooled);
    let energy_aware = energy::energy_aware(
        &rec.filtered,
        &core.removed,
        &rec.occupancy,
        config.energy_sigma,
    );
    row.energy_metrics = Some(metrics::compare(&energy_aware, reference, config.exposure).pooled);
    (
        row,
        Some(Arc::unwrap_or_clone(core.reconstruction.filtered)),
    )
}

impl Row {
    /// The row of a configuration before it runs.
    fn unrun(config: &FilterConfig, white_value: f64) -> Row {
        Row {
            final_pass: config.final_pass,
            color_space: config.color_space,
            k: config.k,
            sigma_color: config.sigma_color,
            sigma_image: config.sigma_image,
            white: config.white.to_string(),
            white_value,
            failure: None,
            seconds: 0.0,
            stored: 0,
            accepted_fraction: 0.0,
            fallback_pixels: 0,
            metrics: None,
            energy_metrics: None,
        }
    }
}

impl Sweep {
    pub fn ok_rows(&self) -> impl Iterator<Item = (&Row, &Metrics)> {
        self.rows
            .iter()
            .filter_map(|r| r.metrics.as_ref().map(|m| (r, m)))
    }

    /// Indices of the configurations on the time–RMS Pareto front: no
    /// other configuration is both faster (or as fast) and more accurate.
    pub fn pareto(&self) -> Vec<usize> {
        let ok: Vec<(usize, f64, f64)> = self
            .rows
            .iter()
            .enumerate()
            .filter_map(|(i, r)| r.metrics.map(|m| (i, r.seconds, m.rms)))
            .collect();
        let mut front: Vec<usize> = ok
            .iter()
            .filter(|&&(i, t, e)| {
                !ok.iter()
                    .any(|&(j, t2, e2)| j != i && t2 <= t && e2 <= e && (t2 < t || e2 < e))
            })
            .map(|e| e.0)
            .collect();
        front.sort_by(|&a, &b| self.rows[a].seconds.total_cmp(&self.rows[b].seconds));
        front
    }
}
