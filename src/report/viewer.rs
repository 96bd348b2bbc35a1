//! The data of the HDR viewer of report.html and sweep.html (`viewer.js`, inlined with
//! `viewer.css`): every image as half floats, frame by frame, and its
//! LDR-ꟻLIP map against the reference, in one JSON object the page embeds
//! in `<script type="application/json" id="viewer-data">`. The viewer
//! applies the exposure and the display transform to these linear values,
//! so a user can look at +4 stops without leaving the page.

use base64::Engine;
use half::f16;

use crate::image::Image;
use crate::metrics;

/// The viewer's script and styles.
pub const SCRIPT: &str = include_str!("viewer.js");
pub const STYLE: &str = include_str!("viewer.css");

/// How the viewer labels an image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Recommended,
    Reference,
    Method,
    /// A method's image denoised after it (`METHOD+oidn`).
    Denoised,
    /// Not an estimate of the image (`rejected`).
    Diagnostic,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Recommended => "recommended",
            Kind::Reference => "reference",
            Kind::Method => "method",
            Kind::Denoised => "denoised",
            Kind::Diagnostic => "diagnostic",
        }
    }
}

/// One image the viewer shows.
pub struct Shown<'a> {
    pub name: String,
    pub caption: String,
    pub kind: Kind,
    pub image: &'a Image,
}

/// The most bytes of half floats a page embeds (base64 adds a third):
/// beyond it the images last in the display order are left out, and the
/// page says which. A 1080p frame is 12 MB.
pub const BUDGET: usize = 96 << 20;

/// The viewer's JSON for `images` (in display order: the recommended image
/// first, then the reference) at the previews' `exposure`. A non-reference
/// image gets its FLIP map when there is a reference.
pub fn data(images: &[Shown], exposure: f64) -> String {
    let bytes = |s: &Shown| s.image.data.len() * 6;
    let mut total = 0;
    let mut kept: Vec<&Shown> = Vec::new();
    let mut left_out: Vec<&str> = Vec::new();
    for s in images {
        let always = matches!(s.kind, Kind::Recommended | Kind::Reference);
        if always || total + bytes(s) <= BUDGET {
            total += bytes(s);
            kept.push(s);
        } else {
            left_out.push(&s.name);
        }
    }
    let reference = kept.iter().position(|s| s.kind == Kind::Reference);
    let flips = reference.map(|r| flip_maps(&kept, r, exposure));
    let frames = kept.first().map_or(1, |s| s.image.frames);
    let (width, height) = kept
        .first()
        .map_or((0, 0), |s| (s.image.width, s.image.height));
    let note = if left_out.is_empty() {
        String::new()
    } else {
        format!(
            "Left out of the viewer for the page's size: {}.",
            left_out.join(", ")
        )
    };
    // Written piece by piece, the pixels encoded straight into the page's
    // text: a 1080p page holds about 130 MB of base64, made once.
    let mut out = format!(
        "{{\"width\":{width},\"height\":{height},\"frames\":{frames},\"exposure\":{},\"reference\":{},\"recommended\":{},\"note\":{},\"images\":[",
        serde_json::json!(exposure),
        serde_json::json!(reference),
        serde_json::json!(kept.iter().position(|s| s.kind == Kind::Recommended)),
        text(&note),
    );
    for (i, s) in kept.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        out += &format!(
            "{{\"name\":{n},\"label\":{n},\"caption\":{},\"kind\":\"{}\",\"data\":[",
            text(&s.caption),
            s.kind.name(),
            n = text(&s.name),
        );
        for f in 0..s.image.frames {
            if f > 0 {
                out.push(',');
            }
            out.push('"');
            halves(s.image.frame(f), &mut out);
            out.push('"');
        }
        out += "],\"flip\":";
        match flips.as_ref().and_then(|f| f[i].as_ref()) {
            Some(maps) => out += &serde_json::json!(maps).to_string(),
            None => out += "null",
        }
        out.push('}');
    }
    out += "]}";
    out
}

/// `s` as a JSON string that is safe inside `<script>`: "</" would end
/// it, and JSON allows "<" escaped.
fn text(s: &str) -> String {
    serde_json::json!(s).to_string().replace('<', "\\u003c")
}

/// Appends to `out` the base64 of the pixels as little-endian half floats,
/// RGB interleaved.
fn halves(pixels: &[[f64; 3]], out: &mut String) {
    let mut bytes = Vec::with_capacity(pixels.len() * 6);
    for p in pixels {
        for v in p {
            bytes.extend_from_slice(&f16::from_f64(*v).to_le_bytes());
        }
    }
    base64::engine::general_purpose::STANDARD.encode_string(bytes, out);
}

/// Per image (None for the reference) and frame, base64 of its FLIP map
/// as bytes, round(255 · FLIP).
fn flip_maps(shown: &[&Shown], reference: usize, exposure: f64) -> Vec<Option<Vec<String>>> {
    let r = shown[reference].image;
    let others: Vec<&Image> = shown
        .iter()
        .enumerate()
        .filter(|&(i, _)| i != reference)
        .map(|(_, s)| s.image)
        .collect();
    // maps[frame][other image]
    let maps: Vec<Vec<String>> = (0..r.frames)
        .map(|f| {
            metrics::ldr_flip_maps(&others, r, f, exposure)
                .iter()
                .map(|m| {
                    let bytes: Vec<u8> = m
                        .iter()
                        .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
                        .collect();
                    base64::engine::general_purpose::STANDARD.encode(bytes)
                })
                .collect()
        })
        .collect();
    let mut next = 0;
    (0..shown.len())
        .map(|i| {
            (i != reference).then(|| {
                let k = next;
                next += 1;
                maps.iter().map(|frame| frame[k].clone()).collect()
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halves_are_little_endian_rgb() {
        let mut s = String::new();
        halves(&[[1.0, -2.0, 65504.0]], &mut s);
        let b = base64::engine::general_purpose::STANDARD.decode(s).unwrap();
        assert_eq!(b, [0x00, 0x3c, 0x00, 0xc0, 0xff, 0x7b]);
    }

    #[test]
    fn the_reference_has_no_flip_map_and_others_do() {
        let mut a = Image::new(8, 8, 2);
        let r = Image::new(8, 8, 2);
        a.data[3] = [0.5, 0.5, 0.5];
        let shown = [
            Shown {
                name: "filtered".into(),
                caption: "a </script> caption".into(),
                kind: Kind::Recommended,
                image: &a,
            },
            Shown {
                name: "reference".into(),
                caption: String::new(),
                kind: Kind::Reference,
                image: &r,
            },
        ];
        let json = data(&shown, 1.0);
        assert!(!json.contains("</"), "{json:.200}");
        let v: serde_json::Value = serde_json::from_str(&json).unwrap();
        assert_eq!(v["reference"], 1);
        assert_eq!(v["recommended"], 0);
        assert!(v["images"][1]["flip"].is_null());
        assert_eq!(v["images"][0]["flip"].as_array().unwrap().len(), 2);
        assert_eq!(v["images"][0]["data"].as_array().unwrap().len(), 2);
    }
}
