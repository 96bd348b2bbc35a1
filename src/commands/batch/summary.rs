//! The batch's summary, built from its entries and each dump's
//! `report.json` (so that a merged summary of shards and a summary of one
//! process are built alike): `summary.csv` (one row per dump, and one per
//! frame of an animation), `summary.json` (the same, per dump) and
//! `summary.html` (a table linking each dump's report, and plots).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::Result;
use plotters::prelude::*;

use super::{Entry, Status};
use crate::config::Method;
use crate::density::FilterCounts;
use crate::io::{atomic, guard};
use crate::method::ImageId;
use crate::metrics::{ImageMetrics, Metrics};
use crate::report::Timing;
use crate::report::html::escape;
use crate::report::plots::to_svg;

/// The part of a dump's `report.json` a batch reads back (any other field
/// is ignored).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct ReportDigest {
    pub header: HeaderDigest,
    pub counts: FilterCounts,
    pub fallback_pixels: u64,
    pub empty_pixels: u64,
    pub timing: Timing,
    #[serde(default)]
    pub metrics: BTreeMap<ImageId, ImageMetrics>,
    pub recommended: Option<ImageId>,
    #[serde(skip_serializing)]
    pub outputs: Vec<String>,
    #[serde(skip_serializing)]
    pub provenance: ProvenanceDigest,
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct HeaderDigest {
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    pub spp: u32,
}

#[derive(Clone, Debug, Default, serde::Deserialize)]
pub struct ProvenanceDigest {
    pub dump_xxh3: String,
    #[serde(default)]
    pub config_xxh3: String,
    pub reference_xxh3: Option<String>,
}

/// The largest `report.json` read back (a few kilobytes a frame).
const REPORT_LIMIT: u64 = 1 << 28;

impl ReportDigest {
    /// `dir/report.json`, if it is there and reads.
    pub fn read(dir: &Path) -> Option<ReportDigest> {
        let bytes = guard::read_input(&dir.join("report.json"), REPORT_LIMIT).ok()?;
        serde_json::from_slice(&bytes).ok()
    }
}

/// One dump in `summary.json`.
#[derive(serde::Serialize)]
struct DumpSummary<'a> {
    #[serde(flatten)]
    entry: &'a Entry,
    /// The dump's report, relative to OUTDIR.
    #[serde(skip_serializing_if = "Option::is_none")]
    report_json: Option<String>,
    #[serde(flatten)]
    report: Option<ReportDigest>,
}

#[derive(serde::Serialize)]
struct SummaryJson<'a> {
    dumps: usize,
    filtered: usize,
    skipped: usize,
    failed: usize,
    results: Vec<DumpSummary<'a>>,
}

/// Writes `summary.csv`, `summary.json` and `summary.html` into `out_dir`
/// for `entries` (in name order, whatever order they ran in); returns the
/// HTML's path.
pub fn write(out_dir: &Path, entries: &[Entry]) -> Result<PathBuf> {
    let mut entries: Vec<&Entry> = entries.iter().collect();
    entries.sort_by(|a, b| a.name.cmp(&b.name));
    let dumps: Vec<(&Entry, Option<ReportDigest>)> = entries
        .into_iter()
        .map(|e| {
            let report = (e.status != Status::Failed)
                .then(|| ReportDigest::read(&out_dir.join(&e.name)))
                .flatten();
            (e, report)
        })
        .collect();
    let images = image_names(&dumps);
    atomic::write_bytes(&out_dir.join("summary.csv"), &csv(&dumps, &images)?)?;
    let n = |s| dumps.iter().filter(|(e, _)| e.status == s).count();
    let json = SummaryJson {
        dumps: dumps.len(),
        filtered: n(Status::Filtered),
        skipped: n(Status::Skipped),
        failed: n(Status::Failed),
        results: dumps
            .iter()
            .map(|(e, r)| DumpSummary {
                entry: e,
                report_json: r.as_ref().map(|_| format!("{}/report.json", e.name)),
                report: r.clone(),
            })
            .collect(),
    };
    let json = serde_json::to_vec_pretty(&json).expect("the summary serialises");
    atomic::write_bytes(&out_dir.join("summary.json"), &json)?;
    let html_path = out_dir.join("summary.html");
    atomic::write_bytes(&html_path, html(out_dir, &dumps, &images).as_bytes())?;
    Ok(html_path)
}

/// Every image with metrics in some dump, in the canonical order.
fn image_names(dumps: &[(&Entry, Option<ReportDigest>)]) -> Vec<ImageId> {
    ImageId::all()
        .filter(|n| {
            dumps
                .iter()
                .any(|(_, r)| r.as_ref().is_some_and(|r| r.metrics.contains_key(n)))
        })
        .collect()
}

const FIXED: [&str; 24] = [
    "name",
    "status",
    "problem",
    "frame",
    "width",
    "height",
    "frames",
    "spp",
    "records",
    "valid",
    "invalid",
    "accepted_streaming",
    "accepted_final",
    "rejected",
    "stored",
    "fallback_pixels",
    "empty_pixels",
    "recommended",
    "open_seconds",
    "streaming_seconds",
    "final_pass_seconds",
    "reconstruct_seconds",
    "write_seconds",
    "total_seconds",
];

/// `summary.csv`: the fixed columns, then per image `IMAGE.rms`,
/// `IMAGE.rms_display`, `IMAGE.energy`, `IMAGE.flip`, `IMAGE.hdr_flip` (and for animations
/// `IMAGE.temporal_rms`, `IMAGE.temporal_rms_display`). A frame's row
/// (`frame` 0, 1, …) has that frame's metrics and leaves the dump's
/// counts and times to the dump's row (`frame` empty).
fn csv(dumps: &[(&Entry, Option<ReportDigest>)], images: &[ImageId]) -> Result<Vec<u8>> {
    let animated = dumps
        .iter()
        .any(|(_, r)| r.as_ref().is_some_and(|r| r.header.frames > 1));
    let mut header: Vec<String> = FIXED.iter().map(|s| s.to_string()).collect();
    for i in images {
        header.extend(
            ["rms", "rms_display", "energy", "flip", "hdr_flip"].map(|m| format!("{i}.{m}")),
        );
        if animated {
            header.extend(["temporal_rms", "temporal_rms_display"].map(|m| format!("{i}.{m}")));
        }
    }
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(&header)?;
    let metric_cells = |m: Option<&Metrics>| -> [String; 5] {
        match m {
            Some(m) => {
                [m.rms, m.rms_display, m.energy_ratio, m.flip, m.hdr_flip].map(|v| v.to_string())
            }
            None => Default::default(),
        }
    };
    for (e, r) in dumps {
        let status = e.status.name();
        let mut row = vec![
            e.name.clone(),
            status.to_string(),
            e.problem.clone().unwrap_or_default(),
            String::new(),
        ];
        let Some(r) = r else {
            row.resize(header.len(), String::new());
            w.write_record(&row)?;
            continue;
        };
        let (h, c, t) = (&r.header, &r.counts, &r.timing);
        row.extend(
            [h.width, h.height, h.frames, h.spp]
                .map(|v| v.to_string())
                .into_iter()
                .chain(
                    [
                        c.records,
                        c.valid,
                        c.invalid.total(),
                        c.accepted_streaming,
                        c.accepted_final,
                        c.rejected,
                        c.stored,
                        r.fallback_pixels,
                        r.empty_pixels,
                    ]
                    .map(|v| v.to_string()),
                ),
        );
        row.push(r.recommended.map(|r| r.to_string()).unwrap_or_default());
        row.extend(
            [
                t.open_seconds,
                t.streaming_seconds,
                t.final_pass_seconds,
                t.reconstruct_seconds,
                t.write_seconds,
                t.total_seconds,
            ]
            .map(|v| format!("{v:.4}")),
        );
        for i in images {
            let m = r.metrics.get(i);
            row.extend(metric_cells(m.map(|m| &m.pooled)));
            if animated {
                let t = m.and_then(|m| m.temporal);
                row.extend(match t {
                    Some(t) => [t.rms.to_string(), t.rms_display.to_string()],
                    None => Default::default(),
                });
            }
        }
        w.write_record(&row)?;
        for f in 0..r.header.frames as usize {
            if r.header.frames < 2 {
                break;
            }
            let mut row = vec![
                e.name.clone(),
                status.to_string(),
                String::new(),
                f.to_string(),
            ];
            row.resize(FIXED.len(), String::new());
            for i in images {
                let m = r.metrics.get(i).and_then(|m| m.per_frame.get(f));
                row.extend(metric_cells(m));
                if animated {
                    row.extend([String::new(), String::new()]);
                }
            }
            w.write_record(&row)?;
        }
    }
    w.into_inner().map_err(|e| anyhow::anyhow!("{e}"))
}

const STYLE: &str = r#"
body { font: 14px/1.4 system-ui, sans-serif; margin: 1.5em; color: #222; }
h1 { font-size: 1.3em; } h2 { font-size: 1.1em; margin-top: 1.5em; }
table { border-collapse: collapse; } td, th { padding: 2px 10px; text-align: right; }
th:first-child, td:first-child, td.text { text-align: left; }
thead th { border-bottom: 1px solid #888; } tr.failed td { color: #a00; }
"#;

/// `summary.html`: counts, one table row per dump (linked to its report),
/// and the plots.
fn html(out_dir: &Path, dumps: &[(&Entry, Option<ReportDigest>)], images: &[ImageId]) -> String {
    let n = |s| dumps.iter().filter(|(e, _)| e.status == s).count();
    let mut s = format!(
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>pathdensity batch</title><style>{STYLE}</style></head><body>\n<h1>pathdensity batch: {} dumps</h1>\n<p>{} filtered, {} skipped (up to date), {} failed. Each dump's outputs are in <code>OUTDIR/NAME/</code>; the numbers are in <code>summary.csv</code> and <code>summary.json</code>.</p>\n",
        dumps.len(),
        n(Status::Filtered),
        n(Status::Skipped),
        n(Status::Failed)
    );
    s += "<table><thead><tr><th>dump</th><th>status</th><th>samples</th><th>rejected</th><th>seconds</th><th>recommended</th><th>its RMS display</th><th>mean's</th><th></th></tr></thead><tbody>\n";
    for (e, r) in dumps {
        let status = e.status.name();
        let has_html = out_dir.join(&e.name).join("report.html").is_file();
        let name = if has_html {
            format!("<a href=\"{0}/report.html\">{0}</a>", escape(&e.name))
        } else {
            escape(&e.name)
        };
        let class = if e.status == Status::Failed {
            " class=\"failed\""
        } else {
            ""
        };
        let problem = escape(e.problem.as_deref().unwrap_or(""));
        match r {
            Some(r) => {
                let c = &r.counts;
                let display = |i: Option<ImageId>| {
                    i.and_then(|i| r.metrics.get(&i))
                        .map_or(String::new(), |m| format!("{:.5}", m.pooled.rms_display))
                };
                let rec = r.recommended.map(|r| r.to_string()).unwrap_or_default();
                s += &format!(
                    "<tr{class}><td>{name}</td><td class=\"text\">{status}</td><td>{}</td><td>{:.3}%</td><td>{:.2}</td><td class=\"text\">{}</td><td>{}</td><td>{}</td><td class=\"text\">{problem}</td></tr>\n",
                    c.valid,
                    100.0 * c.rejected as f64 / c.valid.max(1) as f64,
                    r.timing.total_seconds,
                    escape(&rec),
                    display(r.recommended),
                    display(Some(Method::Mean.into())),
                );
            }
            None => {
                s += &format!(
                    "<tr{class}><td>{name}</td><td class=\"text\">{status}</td><td colspan=\"6\"></td><td class=\"text\">{problem}</td></tr>\n"
                )
            }
        }
    }
    s += "</tbody></table>\n";
    let measured: Vec<(&str, &ReportDigest)> = dumps
        .iter()
        .filter_map(|(e, r)| {
            r.as_ref()
                .filter(|r| r.metrics.contains_key(&Method::Mean.into()))
                .map(|r| (e.name.as_str(), r))
        })
        .collect();
    if !measured.is_empty() {
        s += "<h2>RMS display of each image, relative to the mean's, per dump</h2>\n<p>Below 1: closer to the reference than the unfiltered mean on screen.</p>\n";
        s += &plot(&measured, images, "RMS display / mean's", |m| {
            Some(m.pooled.rms_display)
        });
        s += "<h2>FLIP of each image, relative to the mean's, per dump</h2>\n<p>NVIDIA's perceptual error of the display transform (docs/filter.md §4). Below 1: looks closer to the reference than the mean.</p>\n";
        s += &plot(&measured, images, "FLIP / mean's", |m| Some(m.pooled.flip));
        let animated: Vec<(&str, &ReportDigest)> = measured
            .iter()
            .copied()
            .filter(|(_, r)| r.header.frames > 1)
            .collect();
        if !animated.is_empty() {
            s += "<h2>Temporal stability: flicker relative to the mean's, per animation</h2>\n<p>RMS of each image's frame-to-frame differences against the reference's, on display values (docs/filter.md §4, F9t), divided by the mean's. Below 1: less flicker than the unfiltered mean.</p>\n";
            s += &plot(&animated, images, "temporal RMS display / mean's", |m| {
                m.temporal.map(|t| t.rms_display)
            });
        }
    }
    s += "</body></html>\n";
    s
}

/// An SVG of `value(image) / value(mean)` per dump, one series per image;
/// a plotting error becomes a line of text.
fn plot(
    dumps: &[(&str, &ReportDigest)],
    images: &[ImageId],
    what: &str,
    value: impl Fn(&ImageMetrics) -> Option<f64>,
) -> String {
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for i in images.iter().filter(|&&i| i != Method::Mean.into()) {
        let pts: Vec<(f64, f64)> = dumps
            .iter()
            .enumerate()
            .filter_map(|(x, (_, r))| {
                let v = value(r.metrics.get(i)?)?;
                let mean = value(r.metrics.get(&Method::Mean.into())?)?;
                (mean > 0.0).then_some((x as f64, v / mean))
            })
            .collect();
        if !pts.is_empty() {
            series.push((i.to_string(), pts));
        }
    }
    let y_max = series
        .iter()
        .flat_map(|s| s.1.iter().map(|p| p.1))
        .fold(1.0f64, f64::max)
        .min(4.0)
        * 1.1;
    let names: Vec<&str> = dumps.iter().map(|d| d.0).collect();
    let n = names.len();
    let svg = to_svg((900, 480), |root| {
        let e = |e: DrawingAreaErrorKind<_>| e.to_string();
        root.fill(&WHITE).map_err(e)?;
        let mut chart = ChartBuilder::on(&root)
            .margin(12)
            .x_label_area_size(60)
            .y_label_area_size(60)
            .build_cartesian_2d(-0.5f64..(n as f64 - 0.5), 0f64..y_max)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_labels(n.min(30))
            .x_label_formatter(&|x| {
                let i = x.round();
                if (x - i).abs() < 1e-6 && i >= 0.0 {
                    names
                        .get(i as usize)
                        .map_or(String::new(), |s| s.to_string())
                } else {
                    String::new()
                }
            })
            .y_desc(what)
            .draw()
            .map_err(e)?;
        chart
            .draw_series(LineSeries::new(
                [(-0.5, 1.0), (n as f64 - 0.5, 1.0)],
                BLACK.stroke_width(1),
            ))
            .map_err(e)?
            .label("mean")
            .legend(|(x, y)| PathElement::new(vec![(x - 8, y), (x + 8, y)], BLACK));
        for (k, (name, pts)) in series.iter().enumerate() {
            let color = Palette99::pick(k).to_rgba();
            let clipped: Vec<(f64, f64)> = pts.iter().map(|&(x, y)| (x, y.min(y_max))).collect();
            chart
                .draw_series(clipped.iter().map(|&p| Circle::new(p, 4, color.filled())))
                .map_err(e)?
                .label(name.as_str())
                .legend(move |(x, y)| Circle::new((x, y), 4, color.filled()));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", 11))
            .draw()
            .map_err(e)?;
        root.present().map_err(e)
    });
    match svg {
        Ok(svg) => format!("<figure>{svg}</figure>\n"),
        Err(e) => format!("<p>(the plot could not be drawn: {})</p>\n", escape(&e)),
    }
}
