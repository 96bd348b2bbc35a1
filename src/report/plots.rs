//! The report's pictures that are not images of the scene: the σ map in
//! false colour (the paper's Figure 6) and the joint-density slice (Figure 5).

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::density::Decision;

/// The font every plot's text is set in: DejaVu Sans, embedded (its licence
/// is in assets/fonts/LICENSE) so that PNG plots need no system font and SVG
/// text is measured the same on every machine.
static DEJAVU_SANS: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Registers the embedded font as plotters' "sans-serif"; call before any
/// chart (cheap after the first call).
pub fn register_fonts() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        for style in [FontStyle::Normal, FontStyle::Bold] {
            // The font is embedded and known to parse.
            let _ = plotters::style::register_font("sans-serif", style, DEJAVU_SANS);
        }
    });
}
use crate::dump::{Header, Record, Validity};
use crate::joint::lab::luminance;
use crate::recon::Image;

/// The colour scale of a σ map: log σ from `low` (red) to `high` (blue).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct SigmaScale {
    pub low: f64,
    pub high: f64,
}

/// The 1st and 99th percentiles of the positive σ values of `img` (its
/// first channel), or None if there are none.
pub fn sigma_scale(img: &Image) -> Option<SigmaScale> {
    let mut v: Vec<f64> = img
        .data
        .iter()
        .map(|p| p[0])
        .filter(|&s| s > 0.0 && s.is_finite())
        .collect();
    if v.is_empty() {
        return None;
    }
    v.sort_unstable_by(f64::total_cmp);
    let q = |p: f64| v[((p * (v.len() - 1) as f64).round()) as usize];
    let (low, high) = (q(0.01), q(0.99));
    Some(SigmaScale {
        low,
        high: if high > low { high } else { low * 1.01 + 1e-12 },
    })
}

/// Red (t = 0) through yellow, green and cyan to blue (t = 1).
fn ramp(t: f64) -> [u8; 3] {
    let hue = 240.0 * t.clamp(0.0, 1.0);
    let x = 1.0 - ((hue / 60.0) % 2.0 - 1.0).abs();
    let (r, g, b) = match (hue / 60.0) as u32 {
        0 => (1.0, x, 0.0),
        1 => (x, 1.0, 0.0),
        2 => (0.0, 1.0, x),
        _ => (0.0, x, 1.0),
    };
    [r, g, b].map(|c: f64| (c * 255.0).round() as u8)
}

/// Height of the colour bar under the σ map, in pixels.
const BAR: u32 = 8;

/// Frame `frame` of the σ map in false colour, highest σ blue and lowest
/// red as in the paper's Figure 6, with the colour bar (low at the left)
/// under it. Pixels with no finite σ are black.
pub fn sigma_png(img: &Image, frame: usize, scale: SigmaScale) -> image::RgbImage {
    let (w, h) = (img.width as u32, img.height as u32);
    let (lo, hi) = (scale.low.ln(), scale.high.ln());
    let px = img.frame(frame);
    image::RgbImage::from_fn(w, h + BAR, |x, y| {
        if y >= h {
            if y == h {
                return image::Rgb([0, 0, 0]);
            }
            return image::Rgb(ramp(x as f64 / (w.max(2) - 1) as f64));
        }
        let s = px[(y * w + x) as usize][0];
        if s > 0.0 && s.is_finite() {
            image::Rgb(ramp((s.ln() - lo) / (hi - lo)))
        } else {
            image::Rgb([0, 0, 0])
        }
    })
}

/// At most this many samples are drawn in a slice plot (every n-th).
const SLICE_POINTS: usize = 20_000;

/// The joint-density slice along film row `row` of frame 0: x against the
/// luminance of every valid sample in that row (log scale), accepted and
/// rejected marked differently. Returns the SVG text.
pub fn slice_svg(
    records: &[Record],
    h: &Header,
    decisions: &[u8],
    row: u32,
) -> Result<String, String> {
    let mut acc = Vec::new();
    let mut rej = Vec::new();
    for (r, &d) in records.iter().zip(decisions) {
        // The row first: it is cheap and rules out almost every record.
        if r.y as u32 == row && r.t < 1.0 && r.validity(h) == Validity::Valid {
            let y = luminance([r.r as f64, r.g as f64, r.b as f64]).max(1e-4);
            if Decision::accepted(d) {
                acc.push((r.x as f64, y));
            } else {
                rej.push((r.x as f64, y));
            }
        }
    }
    let step = (acc.len() + rej.len()).div_ceil(SLICE_POINTS).max(1);
    // Two decades of headroom on the log axis for the legend (upper right).
    let y_max = acc.iter().chain(&rej).map(|p| p.1).fold(1.0f64, f64::max) * 100.0;
    to_svg((900, 420), |root| {
        let e = |e: DrawingAreaErrorKind<_>| e.to_string();
        root.fill(&WHITE).map_err(e)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("joint-density slice: row {row}, luminance of every sample"),
                ("sans-serif", 18),
            )
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0f64..h.width as f64, (1e-4f64..y_max).log_scale())
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("x (pixels)")
            .y_desc("luminance Y")
            .draw()
            .map_err(e)?;
        let green = RGBColor(30, 140, 60);
        chart
            .draw_series(
                acc.iter()
                    .step_by(step)
                    .map(|&p| Circle::new(p, 2, green.filled())),
            )
            .map_err(e)?
            .label(format!("accepted ({})", acc.len()))
            .legend(move |p| Circle::new(p, 3, green.filled()));
        chart
            .draw_series(
                rej.iter()
                    .step_by(step)
                    .map(|&p| Cross::new(p, 4, RED.stroke_width(2))),
            )
            .map_err(e)?
            .label(format!("rejected ({})", rej.len()))
            .legend(|p| Cross::new(p, 4, RED.stroke_width(2)));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(e)?;
        root.present().map_err(e)
    })
}

/// Draws a chart as SVG text, in the embedded font.
pub fn to_svg(
    size: (u32, u32),
    draw: impl FnOnce(DrawingArea<SVGBackend, Shift>) -> Result<(), String>,
) -> Result<String, String> {
    register_fonts();
    let mut svg = String::new();
    draw(SVGBackend::with_string(&mut svg, size).into_drawing_area())?;
    Ok(svg)
}

/// Draws a chart as PNG bytes (RGB, the embedded font).
pub fn to_png(
    size: (u32, u32),
    draw: impl FnOnce(DrawingArea<BitMapBackend, Shift>) -> Result<(), String>,
) -> Result<Vec<u8>, String> {
    register_fonts();
    let mut buf = vec![0u8; size.0 as usize * size.1 as usize * 3];
    draw(BitMapBackend::with_buffer(&mut buf, size).into_drawing_area())?;
    let img = image::RgbImage::from_raw(size.0, size.1, buf).expect("the buffer fits the size");
    crate::io::png::encode(&img).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramp_runs_from_red_to_blue() {
        assert_eq!(ramp(0.0), [255, 0, 0]);
        assert_eq!(ramp(1.0), [0, 0, 255]);
        assert_eq!(ramp(0.5), [0, 255, 0]);
    }
}
