//! `report.html`: one self-contained page (no network): the HDR viewer
//! ([`super::viewer`]) with the recommended image beside the reference,
//! every other image a key away, the metric table, the σ map (with a
//! magnifier) and the slice plot. The page sets `data-status` on `<body>`
//! to `ok` once the viewer has drawn and every image has decoded, or to
//! `error: …` — the browser test reads it.

use std::path::Path;

use crate::io::atomic;

use base64::Engine;

use super::FilterReport;
use super::plots::SigmaScale;
use super::viewer::{SCRIPT as VIEWER_SCRIPT, STYLE as VIEWER_STYLE};

/// What a report shows besides its numbers.
pub struct Assets {
    /// The viewer's JSON ([`super::viewer::data`]).
    pub viewer: String,
    /// The σ map's PNG per frame.
    pub sigma: Option<(Vec<Vec<u8>>, SigmaScale)>,
    pub slice_svg: Option<String>,
}

/// What the viewer says under `name`'s image.
pub fn caption(report: &FilterReport, name: &str) -> String {
    let metrics = name.parse().ok().and_then(|id| report.metrics.get(&id));
    match metrics {
        Some(m) => format!(
            "RMS {:.4}, RMS display {:.4}, FLIP {:.4}, HDR-FLIP {:.4}, energy {:.3}",
            m.pooled.rms,
            m.pooled.rms_display,
            m.pooled.flip,
            m.pooled.hdr_flip,
            m.pooled.energy_ratio
        ),
        None if name == "rejected" => format!(
            "mean − filtered: what the filter took out, {:.2}% of the mean's energy",
            100.0 * report.energy_removed.fraction_of_mean
        ),
        None => String::new(),
    }
}

fn data_uri(png: &[u8]) -> String {
    format!(
        "data:image/png;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(png)
    )
}

pub(crate) fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A JS array literal of the frames' data URIs.
fn frames_array(frames: &[Vec<u8>]) -> String {
    let uris: Vec<String> = frames
        .iter()
        .map(|f| format!("\"{}\"", data_uri(f)))
        .collect();
    format!("[{}]", uris.join(","))
}

pub(crate) const STYLE: &str = r#"
p.note { color: #a40; }
body { font: 14px/1.4 system-ui, sans-serif; margin: 1.5em; color: #222; }
h1 { font-size: 1.3em; } h2 { font-size: 1.1em; margin-top: 1.5em; }
table { border-collapse: collapse; } td, th { padding: 2px 10px; text-align: right; }
th:first-child, td:first-child { text-align: left; }
tr.best td { font-weight: bold; } thead th { border-bottom: 1px solid #888; }
.grid { display: flex; flex-wrap: wrap; gap: 12px; }
figure { margin: 0; } figcaption { text-align: center; font-size: 12px; }
.view { position: relative; cursor: crosshair; }
.view img { display: block; width: var(--w); image-rendering: pixelated; }
.loupe { position: absolute; width: 120px; height: 120px; border: 2px solid #fff;
  box-shadow: 0 0 0 1px #000; border-radius: 4px; pointer-events: none; display: none;
  background-repeat: no-repeat; image-rendering: pixelated; }
.bar { display: flex; justify-content: space-between; width: var(--w); font-size: 12px; }
"#;

/// Reports an error or a console error on `<body data-status>`, where the
/// browser tests read it.
pub(crate) const STATUS: &str = r#"
const status = (s) => { if (!document.body.dataset.status || s.startsWith('error')) document.body.dataset.status = s; };
window.addEventListener('error', (e) => status('error: ' + e.message));
const consoleError = console.error;
console.error = (...args) => { status('error: console: ' + args.join(' ')); consoleError(...args); };
"#;

/// The previews' frames and pointer magnifier.
const SCRIPT: &str = r#"
const ZOOM = 8;
function setFrame(f) {
  document.querySelectorAll('img[data-name]').forEach((img) => {
    const frames = FRAMES[img.dataset.name];
    img.src = frames[Math.min(f, frames.length - 1)];
  });
  document.getElementById('frame-label').textContent = f;
}
function move(e) {
  const r = e.currentTarget.getBoundingClientRect();
  const u = (e.clientX - r.left) / r.width, v = (e.clientY - r.top) / r.height;
  document.querySelectorAll('.view').forEach((view) => {
    const img = view.querySelector('img'), loupe = view.querySelector('.loupe');
    const w = img.clientWidth, h = img.clientHeight;
    loupe.style.display = 'block';
    loupe.style.left = (u * w - 60) + 'px';
    loupe.style.top = (v * h - 60) + 'px';
    loupe.style.backgroundImage = 'url(' + img.src + ')';
    loupe.style.backgroundSize = (w * ZOOM) + 'px ' + (h * ZOOM) + 'px';
    loupe.style.backgroundPosition = (60 - u * w * ZOOM) + 'px ' + (60 - v * h * ZOOM) + 'px';
  });
}
function leave() { document.querySelectorAll('.loupe').forEach((l) => l.style.display = 'none'); }
document.querySelectorAll('.view').forEach((v) => { v.addEventListener('mousemove', move); v.addEventListener('mouseleave', leave); });
const slider = document.getElementById('frame');
if (slider) slider.addEventListener('input', () => setFrame(+slider.value));
setFrame(0);
Promise.all([...document.images].map((img) => img.decode()))
  .then(() => status([...document.images].every((i) => i.naturalWidth > 0) ? 'ok' : 'error: empty image'))
  .catch((e) => status('error: image failed to decode: ' + e));
"#;

/// Writes report.html to `dest`: the page around the viewer's data,
/// which is written as it is rather than copied into the page.
pub fn write(
    report: &FilterReport,
    assets: &Assets,
    dest: &Path,
) -> Result<(), pathdensity_format::Error> {
    let page = render(report, assets);
    let (head, tail) = page
        .split_once(VIEWER_DATA)
        .expect("the page has the viewer's place");
    atomic::write_parts(
        dest,
        &[head.as_bytes(), assets.viewer.as_bytes(), tail.as_bytes()],
    )
}

/// Where the page holds the viewer's data.
const VIEWER_DATA: &str = "\u{0}viewer-data\u{0}";

/// The page, with [`VIEWER_DATA`] where the viewer's data goes.
fn render(report: &FilterReport, assets: &Assets) -> String {
    let h = &report.header;
    // Small films are shown enlarged, large ones at most 512 px wide.
    let scale = (512.0 / h.width as f64).clamp(0.25, 4.0).floor().max(1.0);
    let css_w = format!("{}px", (h.width as f64 * scale).min(512.0).round());
    let mut frames_js = Vec::new();
    let mut figures = String::new();
    let mut add = |name: &str, caption: &str, frames: &[Vec<u8>], extra: &str| {
        frames_js.push(format!("\"{}\": {}", name, frames_array(frames)));
        figures += &format!(
            "<figure><div class=\"view\"><img data-name=\"{n}\" alt=\"{n}\"><div class=\"loupe\"></div></div>{extra}<figcaption>{c}</figcaption></figure>\n",
            n = escape(name),
            c = escape(caption)
        );
    };
    if let Some((frames, s)) = &assets.sigma {
        let bar = format!(
            "<div class=\"bar\"><span>σ {:.3} (red)</span><span>log scale</span><span>σ {:.3} (blue)</span></div>",
            s.low, s.high
        );
        let share = match (report.sigma_map_one_in, report.sigma_map_each_pixel) {
            (Some(n), true) => format!(
                " Estimated from one sample in {n} of each pixel's \
                 (--sigma-map computes every sample's σ and writes sigma.exr)."
            ),
            (Some(n), false) => format!(
                " Estimated from about one sample in {n}, picked alike in every pixel \
                 (--sigma-map computes every sample's σ and writes sigma.exr)."
            ),
            (None, _) => String::new(),
        };
        let caption = format!(
            "σ map: mean σ of each pixel's samples, each the σ that decided it. \
             Samples whose neighbourhood in T was still sparse when the replay \
             met them (where it starts, e.g. the first rows of a pixel-major \
             dump, and along the film's edges, which have neighbours on one \
             side only) are stored and decided in the final pass against all \
             of T, which tends to give a lower σ: a band there comes from the \
             replay, not from the image.{share}"
        );
        add("sigma", &caption, frames, &bar);
    }
    let slider = if h.frames > 1 {
        format!(
            "<p>σ map frame <input id=\"frame\" type=\"range\" min=\"0\" max=\"{}\" value=\"0\"> <span id=\"frame-label\">0</span></p>",
            h.frames - 1
        )
    } else {
        "<span id=\"frame-label\" hidden>0</span>".to_string()
    };
    let slice = assets
        .slice_svg
        .as_ref()
        .map(|s| format!("<h2>Joint-density slice (the paper's Figure 5)</h2>\n{s}"))
        .unwrap_or_default();
    format!(
        r#"<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>pathdensity report: {title}</title>
<style>:root {{ --w: {css_w}; }} {STYLE} {VIEWER_STYLE}</style></head>
<body>
<h1>pathdensity report: {title}</h1>
<p>{w} × {hh} × {frames} frame(s), {count} samples ({scene}); k = {k}, σ_image = {si}, σ_color = {sc}, white = {white}; exposure {exposure}, sRGB.</p>
<p>{counts}</p>
{notes}
<div id="viewer"></div>
<script type="application/json" id="viewer-data">{viewer}</script>
<script>{VIEWER_SCRIPT}</script>
{table}
{slider}
<div class="grid">
{figures}</div>
{slice}
<script>{STATUS}const FRAMES = {{{frames_js}}};
{SCRIPT}</script>
</body></html>
"#,
        title = escape(&report.dump),
        w = h.width,
        hh = h.height,
        frames = h.frames,
        count = report.counts.records,
        scene = escape(&h.scene),
        k = report.config.k,
        si = report.config.sigma_image,
        sc = report.config.sigma_color,
        white = report.white,
        exposure = report.config.exposure,
        table = metric_table(report),
        counts = escape(&report.counts_line()),
        notes = report
            .notes()
            .iter()
            .map(|n| format!("<p class=\"note\">{}</p>\n", escape(n)))
            .collect::<String>(),
        frames_js = frames_js.join(",\n"),
        viewer = VIEWER_DATA,
    )
}

fn metric_table(report: &FilterReport) -> String {
    let rows = report.method_rows();
    if rows.is_empty() {
        return String::new();
    }
    let best = report.best_rms();
    let mut t = String::from(
        "<table><thead><tr><th>method</th><th>RMS</th><th>RMS display</th><th>relMSE</th><th>energy</th><th>energy R / G / B</th><th>FLIP</th><th>HDR-FLIP</th><th>seconds</th></tr></thead><tbody>\n",
    );
    for (name, seconds, m) in rows {
        let cells = match m {
            Some(m) => {
                let p = &m.pooled;
                format!(
                    "<td>{:.5}</td><td>{:.5}</td><td>{:.5}</td><td>{:.4}</td><td>{:.3} / {:.3} / {:.3}</td><td>{:.4}</td><td>{:.4}</td>",
                    p.rms,
                    p.rms_display,
                    p.rel_mse,
                    p.energy_ratio,
                    p.energy_ratio_rgb[0],
                    p.energy_ratio_rgb[1],
                    p.energy_ratio_rgb[2],
                    p.flip,
                    p.hdr_flip
                )
            }
            None => "<td colspan=\"7\">no reference</td>".into(),
        };
        let class = if best == Some(name) {
            " class=\"best\""
        } else {
            ""
        };
        t += &format!(
            "<tr{class}><td>{}</td>{cells}<td>{seconds:.3}</td></tr>\n",
            escape(&name.to_string())
        );
    }
    t + "</tbody></table>"
}
