//! The sweep's files: `sweep.csv` and the two plots (SVG and PNG).

use plotters::coord::Shift;
use plotters::prelude::*;

use super::html::{STATUS, STYLE, escape};
use super::plots::{to_png, to_svg};
use super::viewer::{self, Kind, SCRIPT as VIEWER_SCRIPT, STYLE as VIEWER_STYLE, Shown};
use crate::config::Method;
use crate::metrics::Metrics;
use crate::sweep::{Row, Sweep};

/// A configuration's two images and their metrics.
fn images(r: &Row) -> [(&'static str, Option<&Metrics>); 2] {
    [
        ("filtered", r.metrics.as_ref()),
        ("filtered_energy", r.energy_metrics.as_ref()),
    ]
}

/// One line of `sweep.csv`: a configuration (method `filtered`) or a
/// baseline, whose filter fields are empty.
#[derive(serde::Serialize)]
struct CsvRow<'a> {
    method: &'a str,
    final_pass: Option<&'a str>,
    color_space: Option<&'a str>,
    k: Option<usize>,
    sigma_color: Option<f64>,
    sigma_image: Option<f64>,
    white: Option<&'a str>,
    white_value: Option<f64>,
    status: String,
    seconds: f64,
    stored: Option<u64>,
    accepted_fraction: Option<f64>,
    fallback_pixels: Option<u64>,
    rms: Option<f64>,
    rms_display: Option<f64>,
    rel_mse: Option<f64>,
    energy_ratio: Option<f64>,
    flip: Option<f64>,
    hdr_flip: Option<f64>,
}

impl CsvRow<'_> {
    fn metrics(mut self, m: Option<&Metrics>) -> Self {
        self.rms = m.map(|m| m.rms);
        self.rms_display = m.map(|m| m.rms_display);
        self.rel_mse = m.map(|m| m.rel_mse);
        self.energy_ratio = m.map(|m| m.energy_ratio);
        self.flip = m.map(|m| m.flip);
        self.hdr_flip = m.map(|m| m.hdr_flip);
        self
    }
}

/// `sweep.csv`: two lines per configuration (its `filtered` and
/// `filtered_energy` images), then one per baseline.
pub fn csv(s: &Sweep) -> String {
    let mut w = csv::Writer::from_writer(Vec::new());
    let rows = s
        .rows
        .iter()
        .flat_map(|r| images(r).map(|(method, m)| (r, method, m)))
        .map(|(r, method, m)| {
            CsvRow {
                method,
                final_pass: Some(r.final_pass.name()),
                color_space: Some(r.color_space.name()),
                k: Some(r.k),
                sigma_color: Some(r.sigma_color),
                sigma_image: Some(r.sigma_image),
                white: Some(&r.white),
                white_value: Some(r.white_value),
                status: match &r.failure {
                    None => "ok".into(),
                    Some(f) => format!("failed: {f}"),
                },
                seconds: r.seconds,
                stored: Some(r.stored),
                accepted_fraction: Some(r.accepted_fraction),
                fallback_pixels: Some(r.fallback_pixels),
                rms: None,
                rms_display: None,
                rel_mse: None,
                energy_ratio: None,
                flip: None,
                hdr_flip: None,
            }
            .metrics(m)
        });
    let baselines = s.baselines.iter().map(|b| {
        CsvRow {
            method: &b.label,
            final_pass: None,
            color_space: None,
            k: None,
            sigma_color: None,
            sigma_image: None,
            white: None,
            white_value: None,
            status: "ok".into(),
            seconds: b.seconds,
            stored: None,
            accepted_fraction: None,
            fallback_pixels: None,
            rms: None,
            rms_display: None,
            rel_mse: None,
            energy_ratio: None,
            flip: None,
            hdr_flip: None,
        }
        .metrics(Some(&b.metrics))
    });
    for row in rows.chain(baselines) {
        w.serialize(row).expect("CSV into memory");
    }
    String::from_utf8(w.into_inner().expect("CSV into memory")).expect("UTF-8 fields")
}

/// RMS against wall time: every configuration, the Pareto front joined,
/// the baselines as labelled points. SVG text.
pub fn plot_time(s: &Sweep) -> Result<String, String> {
    to_svg(PLOT_SIZE, |root| chart_time(s, root))
}

/// [`Sweep::plot_time`] as PNG bytes.
pub fn plot_time_png(s: &Sweep) -> Result<Vec<u8>, String> {
    to_png(PLOT_SIZE, |root| chart_time(s, root))
}

fn chart_time<DB: DrawingBackend>(s: &Sweep, root: DrawingArea<DB, Shift>) -> Result<(), String> {
    let pts: Vec<(f64, f64)> = s.ok_rows().map(|(r, m)| (r.seconds, m.rms)).collect();
    let all_t: Vec<f64> = pts
        .iter()
        .map(|p| p.0)
        .chain(s.baselines.iter().map(|b| b.seconds))
        .map(|t| t.max(1e-4))
        .collect();
    let t_min = all_t.iter().copied().fold(f64::INFINITY, f64::min) / 1.5;
    let t_max = all_t.iter().copied().fold(1e-3, f64::max) * 1.5;
    // The configurations set the scale; a baseline far above them (rwmc
    // at low spp, say) is drawn on the top edge with its value, rather
    // than squashing every configuration into one line.
    let configs_max = pts.iter().map(|p| p.1).fold(1e-6, f64::max);
    let baselines_max = s
        .baselines
        .iter()
        .map(|b| b.metrics.rms)
        .fold(0.0, f64::max);
    // Headroom above the data for the legend (drawn upper right).
    let e_max = baselines_max.min(3.0 * configs_max).max(configs_max) * 1.4;
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
        .x_labels(6)
        .x_label_formatter(&|v| format!("{v:.3}"))
        .draw()
        .map_err(e)?;
    let blue = RGBColor(40, 90, 200);
    chart
        .draw_series(pts.iter().map(|&p| Circle::new(p, 3, blue.filled())))
        .map_err(e)?
        .label("configurations")
        .legend(move |p| Circle::new(p, 3, blue.filled()));
    let front: Vec<(f64, f64)> = s
        .pareto()
        .iter()
        .map(|&i| (s.rows[i].seconds, s.rows[i].metrics.unwrap().rms))
        .collect();
    chart
        .draw_series(LineSeries::new(front, RED.stroke_width(2)))
        .map_err(e)?
        .label("Pareto front")
        .legend(|(x, y)| PathElement::new(vec![(x - 8, y), (x + 8, y)], RED));
    for b in &s.baselines {
        let rms = b.metrics.rms;
        let (p, label) = if rms > e_max {
            let top = (b.seconds.max(1e-4), e_max * 0.97);
            (top, format!("{} (RMS {rms:.3}, off scale)", b.label))
        } else {
            ((b.seconds.max(1e-4), rms), b.label.clone())
        };
        chart
            .draw_series([TriangleMarker::new(p, 6, BLACK.filled())])
            .map_err(e)?;
        chart
            .draw_series([Text::new(label, p, ("sans-serif", 13))])
            .map_err(e)?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(e)?;
    root.present().map_err(e)?;
    Ok(())
}

/// The metric a plot against k shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Measure {
    Rms,
    Flip,
}

impl Measure {
    fn of(self, m: &Metrics) -> f64 {
        match self {
            Measure::Rms => m.rms,
            Measure::Flip => m.flip,
        }
    }

    fn label(self) -> &'static str {
        match self {
            Measure::Rms => "RMS",
            Measure::Flip => "FLIP",
        }
    }
}

/// `measure` against k, one line per σ_color, at σ_image = 3 (or the
/// first σ_image swept) and the first white swept. SVG text.
pub fn plot_k(s: &Sweep, measure: Measure) -> Result<String, String> {
    to_svg(PLOT_SIZE, |root| chart_k(s, measure, root))
}

/// [`plot_k`] as PNG bytes.
pub fn plot_k_png(s: &Sweep, measure: Measure) -> Result<Vec<u8>, String> {
    to_png(PLOT_SIZE, |root| chart_k(s, measure, root))
}

fn chart_k<DB: DrawingBackend>(
    s: &Sweep,
    measure: Measure,
    root: DrawingArea<DB, Shift>,
) -> Result<(), String> {
    let value = |m: &Metrics| measure.of(m);
    let si = if s.rows.iter().any(|r| r.sigma_image == 3.0) {
        3.0
    } else {
        s.rows.first().map_or(3.0, |r| r.sigma_image)
    };
    let white = s.rows.first().map(|r| r.white.clone()).unwrap_or_default();
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for (r, m) in s.ok_rows() {
        if r.sigma_image != si || r.white != white {
            continue;
        }
        let name = format!("σ_color {}", r.sigma_color);
        match series.iter_mut().find(|s| s.0 == name) {
            Some(s) => s.1.push((r.k as f64, value(m))),
            None => series.push((name, vec![(r.k as f64, value(m))])),
        }
    }
    let k_max = s.rows.iter().map(|r| r.k).max().unwrap_or(1).max(2) as f64 * 1.5;
    // Headroom above the data for the legend (drawn upper right), and for
    // the mean's line.
    let mean_rms = s
        .baselines
        .iter()
        .find(|b| b.method == Method::Mean)
        .map_or(0.0, |b| value(&b.metrics));
    let e_max = s
        .ok_rows()
        .map(|(_, m)| value(m))
        .fold(mean_rms.max(1e-6), f64::max)
        * 1.4;
    let e = |e: DrawingAreaErrorKind<_>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!(
                "{} against k (σ_image {si}, white {white})",
                measure.label()
            ),
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
        .y_desc(measure.label())
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
    if let Some(mean) = s.baselines.iter().find(|b| b.method == Method::Mean) {
        let y = value(&mean.metrics);
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
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 11))
        .draw()
        .map_err(e)?;
    root.present().map_err(e)?;
    Ok(())
}

const PLOT_SIZE: (u32, u32) = (800, 500);

/// sweep.html: the HDR viewer (the lowest-FLIP configuration's filtered
/// image beside the reference, the lowest-RMS one's and the mean), the
/// printed `table` and the `plots` (SVG), in one self-contained page.
pub fn page(s: &Sweep, table: &str, plots: &[String]) -> String {
    let label = |i: usize| {
        let r = &s.rows[i];
        format!(
            "filtered, {} k = {} σ_color = {} σ_image = {} white = {} final pass {}",
            r.color_space.name(),
            r.k,
            r.sigma_color,
            r.sigma_image,
            r.white,
            r.final_pass.name()
        )
    };
    let im = &s.images;
    let mut shown = Vec::new();
    if let Some((i, img)) = &im.lowest_flip {
        shown.push(Shown {
            name: format!("lowest FLIP: {}", label(*i)),
            caption: "the configuration with the lowest FLIP".into(),
            kind: Kind::Recommended,
            image: img,
        });
    }
    shown.push(Shown {
        name: "reference".into(),
        caption: s.reference.clone(),
        kind: Kind::Reference,
        image: &im.reference,
    });
    if let Some((i, img)) = &im.lowest_rms {
        shown.push(Shown {
            name: format!("lowest RMS: {}", label(*i)),
            caption: "the configuration with the lowest RMS".into(),
            kind: Kind::Method,
            image: img,
        });
    }
    shown.push(Shown {
        name: "mean".into(),
        caption: "every valid sample".into(),
        kind: Kind::Method,
        image: &im.mean,
    });
    let h = &s.header;
    format!(
        r#"<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>pathdensity sweep: {title}</title>
<style>{STYLE} {VIEWER_STYLE} svg {{ max-width: 100%; height: auto; }}</style></head>
<body>
<script>{STATUS}</script>
<h1>pathdensity sweep: {title}</h1>
<p>{w} × {hh} × {frames} frame(s) against {reference}; exposure {exposure}, sRGB. {n} configurations.</p>
<div id="viewer"></div>
<script type="application/json" id="viewer-data">{viewer}</script>
<script>{VIEWER_SCRIPT}</script>
<h2>Every configuration</h2>
<pre>{table}</pre>
<h2>Plots</h2>
{plots}
</body></html>
"#,
        title = escape(&s.dump),
        w = h.width,
        hh = h.height,
        frames = h.frames,
        reference = escape(&s.reference),
        exposure = s.exposure,
        n = s.rows.len(),
        viewer = viewer::data(&shown, s.exposure),
        table = escape(table),
        plots = plots.join("\n"),
    )
}
