//! Parameter sweeps: the path-density filter over every combination of k,
//! σ_color, σ_image and white of one dump, measured against a reference,
//! with the baselines run once as reference points. The dump is mapped
//! once; each configuration replays it.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use indicatif::ProgressBar;
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::commands::filter::{FilterOptions, filter};
use crate::density::{self, Decision, FilterParams};
use crate::dump::{DumpReader, Header, Record};
use crate::io::exr;
use crate::joint::JointSpace;
use crate::joint::white::White;
use crate::methods::Method;
use crate::metrics::{self, Metrics};
use crate::recon::groups::PixelGroups;
use crate::recon::rwmc::{self, RwmcParams};
use crate::recon::{self, Image, ReconFilter, energy, mon, robust};
use crate::report::plots::{to_png, to_svg};

#[derive(Clone, Debug)]
pub struct SweepOptions {
    pub dump: PathBuf,
    pub reference: PathBuf,
    pub out_dir: PathBuf,
    pub ks: Vec<usize>,
    pub sigma_colors: Vec<f64>,
    pub sigma_images: Vec<f64>,
    pub whites: Vec<White>,
    pub sigma_time: f64,
    pub recon: ReconFilter,
    pub exposure: f64,
    /// Worker threads; 0 means one per core.
    pub threads: usize,
    /// Group counts of the median-of-means baselines (mon, gmon).
    pub mon_groups: Vec<usize>,
    /// κ values of the rwmc baseline (its other parameters at defaults).
    pub rwmc_kappas: Vec<f64>,
}

impl SweepOptions {
    /// The peer methods' swept values, checked: mon/gmon group counts and
    /// rwmc parameters (κ from the list, the rest the authors' defaults).
    fn peer_params(&self) -> Result<(Vec<usize>, Vec<RwmcParams>)> {
        if self.mon_groups.is_empty() || self.mon_groups.contains(&0) {
            bail!("--mon-groups needs one or more values of at least 1");
        }
        if self.rwmc_kappas.is_empty() {
            bail!("--rwmc-kappa needs one or more values");
        }
        let rwmc = self
            .rwmc_kappas
            .iter()
            .map(|&kappa| {
                let p = RwmcParams {
                    kappa,
                    ..RwmcParams::default()
                };
                p.validate().map(|_| p).map_err(anyhow::Error::msg)
            })
            .collect::<Result<Vec<_>>>()?;
        Ok((self.mon_groups.clone(), rwmc))
    }

    /// The default grid: k 5…200, σ_color 25…400, σ_image 1.5…6.
    pub fn new(
        dump: impl Into<PathBuf>,
        reference: impl Into<PathBuf>,
        out: impl Into<PathBuf>,
    ) -> Self {
        SweepOptions {
            dump: dump.into(),
            reference: reference.into(),
            out_dir: out.into(),
            ks: vec![5, 10, 20, 50, 200],
            sigma_colors: vec![25.0, 50.0, 100.0, 200.0, 400.0],
            sigma_images: vec![1.5, 3.0, 6.0],
            whites: vec![White::Fixed(1.0)],
            sigma_time: 2.0,
            recon: ReconFilter::Box,
            exposure: 1.0,
            threads: 0,
            mon_groups: vec![crate::recon::mon::DEFAULT_GROUPS],
            rwmc_kappas: vec![RwmcParams::default().kappa],
        }
    }
}

/// One configuration's outcome.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Row {
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
    pub metrics: Option<Metrics>,
}

/// A baseline measured once.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Baseline {
    pub method: String,
    pub seconds: f64,
    pub metrics: Metrics,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Sweep {
    pub dump: String,
    pub reference: String,
    pub header: Header,
    pub threads: usize,
    pub rows: Vec<Row>,
    pub baselines: Vec<Baseline>,
}

/// Every (k, σ_color, σ_image, white) in the options, in nested order.
fn grid(o: &SweepOptions) -> Vec<(usize, f64, f64, White)> {
    let mut v = Vec::new();
    for &w in &o.whites {
        for &si in &o.sigma_images {
            for &sc in &o.sigma_colors {
                for &k in &o.ks {
                    v.push((k, sc, si, w));
                }
            }
        }
    }
    v
}

pub fn run(o: &SweepOptions, progress: &ProgressBar) -> Result<Sweep> {
    if o.ks.is_empty()
        || o.sigma_colors.is_empty()
        || o.sigma_images.is_empty()
        || o.whites.is_empty()
    {
        bail!("every swept list needs at least one value");
    }
    let dump = DumpReader::open(&o.dump)?;
    let h = dump.header().clone();
    let records = dump.records();
    let reference = exr::read_reference(
        &o.reference,
        h.width as usize,
        h.height as usize,
        h.frames as usize,
    )?;
    std::fs::create_dir_all(&o.out_dir)
        .with_context(|| format!("{}: cannot create output directory", o.out_dir.display()))?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(o.threads)
        .build()
        .context("cannot start the worker threads")?;

    // The baselines, once: the filter command at the paper's defaults.
    let mut fo = FilterOptions::new(&o.dump, o.out_dir.join("baselines"));
    fo.reference = Some(o.reference.clone());
    fo.methods = vec![Method::Bilateral];
    fo.html = false;
    fo.recon = o.recon;
    fo.exposure = o.exposure;
    fo.threads = o.threads;
    let (mon_groups, rwmc_params) = o.peer_params()?;
    let base = filter(&fo)?;
    let from_filter = |m: &str| Baseline {
        method: m.to_string(),
        seconds: base.method_seconds[m],
        metrics: base.metrics[m].pooled,
    };
    let mut baselines = vec![from_filter("mean")];
    // The per-pixel estimators share one grouping of the samples; the peer
    // methods run once per value of their swept parameter, labelled with it.
    let compare = |img: &Image| metrics::compare(img, &reference, o.exposure).pooled;
    pool.install(|| {
        let t = Instant::now();
        let groups = PixelGroups::new(records, &h);
        let group_seconds = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let r = robust::robust_images(&groups, &h, fo.alpha);
        let seconds = group_seconds + t.elapsed().as_secs_f64();
        for (name, img) in [("median", &r.median), ("trimmed", &r.trimmed)] {
            baselines.push(Baseline {
                method: name.into(),
                seconds,
                metrics: compare(img),
            });
        }
        baselines.push(from_filter("bilateral"));
        for &g in &mon_groups {
            let t = Instant::now();
            let m = mon::mon_images(&groups, &h, g);
            let seconds = group_seconds + t.elapsed().as_secs_f64();
            for (name, img) in [("mon", &m.mon), ("gmon", &m.gmon)] {
                baselines.push(Baseline {
                    method: format!("{name} groups={g}"),
                    seconds,
                    metrics: compare(img),
                });
            }
        }
        for p in &rwmc_params {
            let t = Instant::now();
            let img = rwmc::rwmc(records, &h, p);
            baselines.push(Baseline {
                method: format!("rwmc kappa={}", p.kappa),
                seconds: t.elapsed().as_secs_f64(),
                metrics: compare(&img),
            });
        }
    });

    let valid = base.counts.valid;
    let configs = grid(o);
    progress.set_length(configs.len() as u64);
    let mut whites: Vec<(White, f64)> = Vec::new();
    let mut rows = Vec::new();
    for (k, sc, si, w) in configs {
        let white_value = match whites.iter().find(|e| e.0 == w) {
            Some(e) => e.1,
            None => {
                let v = w.resolve(records, &h);
                whites.push((w, v));
                v
            }
        };
        let params = FilterParams {
            k,
            space: JointSpace {
                sigma_image: si,
                sigma_color: sc,
                sigma_time: o.sigma_time,
                white: white_value,
            },
            ..FilterParams::default()
        };
        let row = pool.install(|| configuration(records, &h, &params, o, &reference, valid));
        rows.push(Row {
            white: w.to_string(),
            white_value,
            ..row
        });
        progress.inc(1);
    }
    progress.finish_and_clear();
    Ok(Sweep {
        dump: o.dump.display().to_string(),
        reference: o.reference.display().to_string(),
        header: h,
        threads: pool.current_num_threads(),
        rows,
        baselines,
    })
}

/// Runs one configuration; a configuration that cannot run is a row with
/// its reason.
fn configuration(
    records: &[Record],
    h: &Header,
    params: &FilterParams,
    o: &SweepOptions,
    reference: &Image,
    valid: u64,
) -> Row {
    let mut row = Row {
        k: params.k,
        sigma_color: params.space.sigma_color,
        sigma_image: params.space.sigma_image,
        white: String::new(),
        white_value: params.space.white,
        failure: None,
        seconds: 0.0,
        stored: 0,
        accepted_fraction: 0.0,
        fallback_pixels: 0,
        metrics: None,
    };
    if params.k == 0 {
        row.failure = Some("k must be at least 1".into());
        return row;
    }
    if params.k as u64 >= valid {
        row.failure = Some(format!(
            "k = {} needs more than {valid} valid samples: every sample would be rejected",
            params.k
        ));
        return row;
    }
    if let Err(e) = params.space.validate() {
        row.failure = Some(e);
        return row;
    }
    let t = Instant::now();
    let result = density::run(records, h, params, &ProgressBar::hidden());
    let rec = recon::reconstruct(records, h, o.recon, |i| {
        Decision::accepted(result.decisions[i])
    });
    row.seconds = t.elapsed().as_secs_f64();
    let c = &result.counts;
    row.stored = c.stored;
    row.accepted_fraction =
        (c.accepted_streaming + c.accepted_final) as f64 / c.valid.max(1) as f64;
    row.fallback_pixels = rec.fallback_pixels;
    row.metrics = Some(metrics::compare(&rec.filtered, reference, o.exposure).pooled);
    row
}

impl Sweep {
    /// One line per configuration (method `filtered`) and per baseline.
    pub fn csv(&self) -> String {
        let mut s = String::from(
            "method,k,sigma_color,sigma_image,white,white_value,status,seconds,stored,accepted_fraction,fallback_pixels,rms,rms_display,rel_mse,energy_ratio\n",
        );
        let m = |m: &Option<Metrics>| match m {
            Some(m) => format!(
                "{},{},{},{}",
                m.rms, m.rms_display, m.rel_mse, m.energy_ratio
            ),
            None => ",,,".into(),
        };
        for r in &self.rows {
            let status = match &r.failure {
                None => "ok".to_string(),
                Some(f) => format!("\"failed: {}\"", f.replace('"', "'")),
            };
            s += &format!(
                "filtered,{},{},{},{},{},{},{},{},{},{},{}\n",
                r.k,
                r.sigma_color,
                r.sigma_image,
                r.white,
                r.white_value,
                status,
                r.seconds,
                r.stored,
                r.accepted_fraction,
                r.fallback_pixels,
                m(&r.metrics)
            );
        }
        for b in &self.baselines {
            s += &format!(
                "{},,,,,,ok,{},,,,{}\n",
                b.method,
                b.seconds,
                m(&Some(b.metrics))
            );
        }
        s
    }

    fn ok_rows(&self) -> impl Iterator<Item = (&Row, &Metrics)> {
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

    /// RMS against wall time: every configuration, the Pareto front joined,
    /// the baselines as labelled points. SVG text.
    pub fn plot_time(&self) -> Result<String, String> {
        to_svg(PLOT_SIZE, |root| self.chart_time(root))
    }

    /// [`Sweep::plot_time`] as PNG bytes.
    pub fn plot_time_png(&self) -> Result<Vec<u8>, String> {
        to_png(PLOT_SIZE, |root| self.chart_time(root))
    }

    fn chart_time<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> Result<(), String> {
        let pts: Vec<(f64, f64)> = self.ok_rows().map(|(r, m)| (r.seconds, m.rms)).collect();
        let all_t: Vec<f64> = pts
            .iter()
            .map(|p| p.0)
            .chain(self.baselines.iter().map(|b| b.seconds))
            .map(|t| t.max(1e-4))
            .collect();
        let all_e = pts
            .iter()
            .map(|p| p.1)
            .chain(self.baselines.iter().map(|b| b.metrics.rms));
        let t_min = all_t.iter().copied().fold(f64::INFINITY, f64::min) / 1.5;
        let t_max = all_t.iter().copied().fold(1e-3, f64::max) * 1.5;
        let e_max = all_e.fold(1e-6, f64::max) * 1.1;
        let e = |e: DrawingAreaErrorKind<_>| e.to_string();
        root.fill(&WHITE).map_err(e)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "RMS against wall time (filter + reconstruction)",
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d((t_min..t_max).log_scale(), 0f64..e_max)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("seconds (log scale)")
            .y_desc("RMS")
            .draw()
            .map_err(e)?;
        let blue = RGBColor(40, 90, 200);
        chart
            .draw_series(pts.iter().map(|&p| Circle::new(p, 3, blue.filled())))
            .map_err(e)?
            .label("configurations")
            .legend(move |p| Circle::new(p, 3, blue.filled()));
        let front: Vec<(f64, f64)> = self
            .pareto()
            .iter()
            .map(|&i| (self.rows[i].seconds, self.rows[i].metrics.unwrap().rms))
            .collect();
        chart
            .draw_series(LineSeries::new(front, RED.stroke_width(2)))
            .map_err(e)?
            .label("Pareto front")
            .legend(|(x, y)| PathElement::new(vec![(x - 8, y), (x + 8, y)], RED));
        for b in &self.baselines {
            let p = (b.seconds.max(1e-4), b.metrics.rms);
            chart
                .draw_series([TriangleMarker::new(p, 6, BLACK.filled())])
                .map_err(e)?;
            chart
                .draw_series([Text::new(b.method.clone(), p, ("sans-serif", 13))])
                .map_err(e)?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(e)?;
        root.present().map_err(e)?;
        Ok(())
    }

    /// RMS against k, one line per σ_color, at σ_image = 3 (or the first
    /// σ_image swept) and the first white swept. SVG text.
    pub fn plot_k(&self) -> Result<String, String> {
        to_svg(PLOT_SIZE, |root| self.chart_k(root))
    }

    /// [`Sweep::plot_k`] as PNG bytes.
    pub fn plot_k_png(&self) -> Result<Vec<u8>, String> {
        to_png(PLOT_SIZE, |root| self.chart_k(root))
    }

    fn chart_k<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> Result<(), String> {
        let si = if self.rows.iter().any(|r| r.sigma_image == 3.0) {
            3.0
        } else {
            self.rows.first().map_or(3.0, |r| r.sigma_image)
        };
        let white = self
            .rows
            .first()
            .map(|r| r.white.clone())
            .unwrap_or_default();
        let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
        for (r, m) in self.ok_rows() {
            if r.sigma_image != si || r.white != white {
                continue;
            }
            let name = format!("σ_color {}", r.sigma_color);
            match series.iter_mut().find(|s| s.0 == name) {
                Some(s) => s.1.push((r.k as f64, m.rms)),
                None => series.push((name, vec![(r.k as f64, m.rms)])),
            }
        }
        let k_max = self.rows.iter().map(|r| r.k).max().unwrap_or(1).max(2) as f64 * 1.5;
        let e_max = self.ok_rows().map(|(_, m)| m.rms).fold(1e-6, f64::max) * 1.1;
        let e = |e: DrawingAreaErrorKind<_>| e.to_string();
        root.fill(&WHITE).map_err(e)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("RMS against k (σ_image {si}, white {white})"),
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .right_y_label_area_size(0)
            .build_cartesian_2d((1f64..k_max).log_scale(), 0f64..e_max)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("k")
            .y_desc("RMS")
            .draw()
            .map_err(e)?;
        for (i, (name, mut pts)) in series.into_iter().enumerate() {
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            let color = Palette99::pick(i).to_rgba();
            chart
                .draw_series(LineSeries::new(pts, color.stroke_width(2)))
                .map_err(e)?
                .label(name)
                .legend(move |(x, y)| PathElement::new(vec![(x - 8, y), (x + 8, y)], color));
        }
        if let Some(mean) = self.baselines.iter().find(|b| b.method == "mean") {
            let y = mean.metrics.rms;
            chart
                .draw_series(LineSeries::new(
                    [(1.0, y), (k_max, y)],
                    BLACK.stroke_width(1),
                ))
                .map_err(e)?
                .label("mean (no filter)")
                .legend(|(x, y)| PathElement::new(vec![(x - 8, y), (x + 8, y)], BLACK));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", 11))
            .draw()
            .map_err(e)?;
        root.present().map_err(e)?;
        Ok(())
    }
}

const PLOT_SIZE: (u32, u32) = (800, 500);

/// One prefix of the equal-time comparison.
#[derive(Clone, Debug, serde::Serialize)]
pub struct EqualTimeRow {
    /// Passes (samples per pixel) the filter used.
    pub spp: u32,
    /// Render time of those passes plus the filter and reconstruction.
    pub filtered_seconds: f64,
    pub filtered: Metrics,
    /// The pass count whose render time alone is closest to, and not above,
    /// `filtered_seconds` (at most the dump's spp).
    pub mean_spp: u32,
    pub mean_seconds: f64,
    pub mean: Metrics,
    /// The energy-aware filter at `spp` passes (its spread costs a few
    /// milliseconds, counted in `filtered_seconds`).
    pub filtered_energy: Metrics,
    /// mon, gmon and rwmc at `mean_spp` passes: their cost is a small
    /// fraction of the render time, so equal time is (nearly) equal samples.
    pub peers: Vec<(String, Metrics)>,
}

/// The equal-time comparison on a pass-major still, for one configuration
/// (each list's single value, else the paper's default): the first m
/// passes are an m-spp render. For m = 1, 2, 4, … and the full count, the filtered
/// image of m passes is set against the mean of the most passes that cost
/// no more in total, with render time `render_seconds / spp` per pass.
pub fn equal_time(
    o: &SweepOptions,
    render_seconds: f64,
    progress: &ProgressBar,
) -> Result<Vec<EqualTimeRow>> {
    let dump = DumpReader::open(&o.dump)?;
    let h = dump.header().clone();
    if h.order != crate::dump::Order::PassMajor || h.frames != 1 || h.spp == 0 {
        bail!(
            "{}: --equal-time needs a pass-major still with a uniform spp",
            o.dump.display()
        );
    }
    if !(render_seconds > 0.0 && render_seconds.is_finite()) {
        bail!("--render-seconds must be positive");
    }
    let reference = exr::read_reference(&o.reference, h.width as usize, h.height as usize, 1)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(o.threads)
        .build()
        .context("cannot start the worker threads")?;
    let per_pass = render_seconds / h.spp as f64;
    let pixels = h.pixels();
    let prefix = |m: u32| {
        let mut ph = h.clone();
        ph.spp = m;
        ph.sample_count = m as u64 * pixels as u64;
        (ph, &dump.records()[..m as usize * pixels])
    };
    let compare = |img: &Image| metrics::compare(img, &reference, o.exposure).pooled;
    let (mon_groups, rwmc_params) = o.peer_params()?;
    let (groups_m, rwmc_p) = (mon_groups[0], rwmc_params[0]);
    // The mean and the peer estimators of the first m passes.
    let plain = |m: u32| {
        let (ph, recs) = prefix(m);
        let rec = recon::reconstruct(recs, &ph, o.recon, |_| true);
        let g = PixelGroups::new(recs, &ph);
        let mm = mon::mon_images(&g, &ph, groups_m);
        let rw = rwmc::rwmc(recs, &ph, &rwmc_p);
        let peers = vec![
            (format!("mon groups={groups_m}"), compare(&mm.mon)),
            (format!("gmon groups={groups_m}"), compare(&mm.gmon)),
            (format!("rwmc kappa={}", rwmc_p.kappa), compare(&rw)),
        ];
        (compare(&rec.mean), peers)
    };
    // One configuration: a single value given is used, a list (such as
    // the default grid) means the paper's default.
    let one = |v: &[f64], default: f64| if v.len() == 1 { v[0] } else { default };
    let paper = JointSpace::default();
    let params = FilterParams {
        k: if o.ks.len() == 1 { o.ks[0] } else { 10 },
        space: JointSpace {
            sigma_image: one(&o.sigma_images, paper.sigma_image),
            sigma_color: one(&o.sigma_colors, paper.sigma_color),
            sigma_time: o.sigma_time,
            white: match o.whites.as_slice() {
                [w] => w.resolve(dump.records(), &h),
                _ => paper.white,
            },
        },
        ..FilterParams::default()
    };
    params.space.validate().map_err(anyhow::Error::msg)?;
    let mut ms: Vec<u32> = std::iter::successors(Some(1u32), |m| m.checked_mul(2))
        .take_while(|&m| m < h.spp)
        .collect();
    ms.push(h.spp);
    progress.set_length(ms.len() as u64);
    let mut rows = Vec::new();
    for m in ms {
        let (ph, recs) = prefix(m);
        let t = Instant::now();
        let (filtered, filter_secs, energy_aware) = pool.install(|| {
            let result = density::run(recs, &ph, &params, &ProgressBar::hidden());
            let rec = recon::reconstruct(recs, &ph, o.recon, |i| {
                Decision::accepted(result.decisions[i])
            });
            let secs = t.elapsed().as_secs_f64();
            let removed = energy::removed(&rec.mean, &rec.filtered);
            let ea = energy::energy_aware(
                &rec.filtered,
                &removed,
                &rec.occupancy,
                energy::DEFAULT_SPREAD_SIGMA,
            );
            (rec.filtered, secs, ea)
        });
        let filtered_seconds = m as f64 * per_pass + filter_secs;
        let mean_spp = ((filtered_seconds / per_pass).floor() as u32).clamp(1, h.spp);
        let (mean, peers) = pool.install(|| plain(mean_spp));
        rows.push(EqualTimeRow {
            spp: m,
            filtered_seconds,
            filtered: compare(&filtered),
            mean_spp,
            mean_seconds: mean_spp as f64 * per_pass,
            mean,
            filtered_energy: compare(&energy_aware),
            peers,
        });
        progress.inc(1);
    }
    progress.finish_and_clear();
    Ok(rows)
}

/// The equal-time table as text (also written as `equal_time.csv`).
pub fn equal_time_csv(rows: &[EqualTimeRow]) -> String {
    let mut s = String::from("spp,method,seconds,rms,rms_display\n");
    let line = |spp: u32, name: &str, secs: f64, m: &Metrics| {
        format!("{spp},{name},{secs},{},{}\n", m.rms, m.rms_display)
    };
    for r in rows {
        s += &line(r.spp, "filtered", r.filtered_seconds, &r.filtered);
        s += &line(
            r.spp,
            "filtered_energy",
            r.filtered_seconds,
            &r.filtered_energy,
        );
        s += &line(r.mean_spp, "mean", r.mean_seconds, &r.mean);
        for (name, m) in &r.peers {
            s += &line(r.mean_spp, name, r.mean_seconds, m);
        }
    }
    s
}
