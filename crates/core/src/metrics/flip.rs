//! ꟻLIP, the perceptual difference of two images that rendering papers
//! report (Andersson et al., "FLIP: A Difference Evaluator for Alternating
//! Images", HPG 2020), and HDR-ꟻLIP (Andersson et al., "Visualizing and
//! Communicating Errors in Rendered Images", Ray Tracing Gems II, 2021),
//! as NVIDIA's reference implementation computes them (`tests/flip.rs`
//! holds this one to it). Lower is better; 0 for equal images.
//!
//! Per pixel: a colour error from the images filtered by the human
//! contrast sensitivity functions in YCxCz, compared as Hunt-adjusted
//! HyAB distances in CIELAB; a feature error from edges and points of the
//! unfiltered luminance; combined as ΔE_c^(1 − ΔE_f). HDR-ꟻLIP is the
//! per-pixel maximum of ꟻLIP over exposures of the ACES-tone-mapped
//! images, spanning the reference's luminance range.
//!
//! ```
//! use pathdensity_core::metrics::flip;
//! let a = vec![[0.2f32, 0.4, 0.6]; 16 * 16];
//! let mut b = a.clone();
//! b[5 * 16 + 5] = [1.0, 1.0, 1.0];
//! let map = flip::ldr(&a, &b, 16, 16, flip::PPD);
//! assert_eq!(flip::ldr(&a, &a, 16, 16, flip::PPD).iter().sum::<f32>(), 0.0);
//! // The changed pixel is where the difference is seen most.
//! let worst = map.iter().copied().fold(0.0, f32::max);
//! assert!(worst > 0.0 && map[5 * 16 + 5] == worst);
//! ```

// The constants as the reference implementation publishes them.
#![allow(clippy::excessive_precision)]

use std::f32::consts::PI;

use crate::par::prelude::*;

/// Pixels per degree of visual angle: a 0.7 m wide 3840-pixel display
/// seen from 0.7 m, the reference implementation's default.
pub const PPD: f32 = 0.7 * (3840.0 / 0.7) * (PI / 180.0);

// The paper's constants: the colour error's power and its remap, the
// feature detector's width (degrees) and power.
const QC: f32 = 0.7;
const PC: f32 = 0.4;
const PT: f32 = 0.95;
const W: f32 = 0.082;
const QF: f32 = 0.5;

/// The reference white (the XYZ of linear RGB 1, 1, 1) and its inverse.
const WHITE: [f32; 3] = [0.950428545, 1.0, 1.088900371];
const INV_WHITE: [f32; 3] = [1.052156925, 1.0, 0.918357670];

type Rgb = [f32; 3];

fn rgb_to_xyz(c: Rgb) -> Rgb {
    let m = [
        [
            10135552.0 / 24577794.0,
            8788810.0 / 24577794.0,
            4435075.0 / 24577794.0,
        ],
        [
            2613072.0 / 12288897.0,
            8788810.0 / 12288897.0,
            887015.0 / 12288897.0,
        ],
        [
            1425312.0 / 73733382.0,
            8788810.0 / 73733382.0,
            70074185.0 / 73733382.0,
        ],
    ];
    m.map(|r| r[0] * c[0] + r[1] * c[1] + r[2] * c[2])
}

fn xyz_to_rgb(c: Rgb) -> Rgb {
    let m = [
        [3.241003275, -1.537398934, -0.498615861],
        [-0.969224334, 1.875930071, 0.041554224],
        [0.055639423, -0.204011202, 1.057148933],
    ];
    m.map(|r| r[0] * c[0] + r[1] * c[1] + r[2] * c[2])
}

/// YCxCz: CIELAB without its cube root, linear in XYZ.
fn xyz_to_ycxcz(c: Rgb) -> Rgb {
    let [x, y, z] = [0, 1, 2].map(|i| c[i] * INV_WHITE[i]);
    [116.0 * y - 16.0, 500.0 * (x - y), 200.0 * (y - z)]
}

fn ycxcz_to_xyz(c: Rgb) -> Rgb {
    let y = (c[0] + 16.0) / 116.0;
    let (x, z) = (y + c[1] / 500.0, y - c[2] / 200.0);
    [x * WHITE[0], y * WHITE[1], z * WHITE[2]]
}

/// CIELAB with the Hunt effect: chroma scaled by 0.01 L.
fn hunt_lab(xyz: Rgb) -> Rgb {
    let delta = 6.0f32 / 29.0;
    let f = |t: f32| {
        if t > delta * delta * delta {
            t.cbrt()
        } else {
            t / (3.0 * delta * delta) + 4.0 / 29.0
        }
    };
    let [fx, fy, fz] = [0, 1, 2].map(|i| f(xyz[i] * INV_WHITE[i]));
    let l = 116.0 * fy - 16.0;
    [
        l,
        0.01 * l * 500.0 * (fx - fy),
        0.01 * l * 200.0 * (fy - fz),
    ]
}

/// HyAB: the lightness difference plus the chroma plane's distance.
fn hyab(a: Rgb, b: Rgb) -> f32 {
    (a[0] - b[0]).abs() + ((a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Samples `f` at the integer offsets −r..=r.
fn taps(r: usize, f: impl Fn(f32) -> f32) -> Vec<f32> {
    (0..=2 * r).map(|i| f(i as f32 - r as f32)).collect()
}

fn normalised(mut k: Vec<f32>) -> Vec<f32> {
    let s: f32 = k.iter().sum();
    k.iter_mut().for_each(|v| *v /= s);
    k
}

/// A derivative kernel with its positive and negative taps each
/// normalised to ±1.
fn normalised_by_sign(mut k: Vec<f32>) -> Vec<f32> {
    let pos: f32 = k.iter().filter(|v| **v > 0.0).sum();
    let neg: f32 = -k.iter().filter(|v| **v < 0.0).sum::<f32>();
    for v in &mut k {
        if *v > 0.0 {
            *v /= pos;
        } else if *v < 0.0 {
            *v /= neg;
        }
    }
    k
}

/// A plane of `w × h` values filtered by `kx` along rows, then `ky` along
/// columns, the edges clamped.
fn separable(plane: &[f32], w: usize, h: usize, kx: &[f32], ky: &[f32]) -> Vec<f32> {
    vertical(&horizontal(plane, w, kx), w, h, ky)
}

fn horizontal(plane: &[f32], w: usize, k: &[f32]) -> Vec<f32> {
    let r = k.len() / 2;
    let mut out = vec![0.0f32; plane.len()];
    out.par_chunks_mut(w)
        .zip(plane.par_chunks(w))
        .for_each(|(out, src)| {
            // The row with its edge values repeated r times each side, so
            // that every output is one contiguous dot product.
            let mut padded = Vec::with_capacity(w + 2 * r);
            padded.extend(std::iter::repeat_n(src[0], r));
            padded.extend_from_slice(src);
            padded.extend(std::iter::repeat_n(src[w - 1], r));
            for (x, o) in out.iter_mut().enumerate() {
                *o = padded[x..x + k.len()]
                    .iter()
                    .zip(k)
                    .map(|(v, k)| v * k)
                    .sum();
            }
        });
    out
}

fn vertical(plane: &[f32], w: usize, h: usize, k: &[f32]) -> Vec<f32> {
    let r = k.len() / 2;
    let mut out = vec![0.0f32; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, o)| {
        for (i, k) in k.iter().enumerate() {
            let row = &plane[(y + i).saturating_sub(r).min(h - 1) * w..][..w];
            for (o, v) in o.iter_mut().zip(row) {
                *o += k * v;
            }
        }
    });
    out
}

/// The filters of one pixels-per-degree.
struct Kernels {
    /// The contrast sensitivity of Y′ and Cx (one Gaussian each), and Cz's
    /// two Gaussians, each scaled so that their sum is the 2-D kernel.
    y: Vec<f32>,
    cx: Vec<f32>,
    cz: [Vec<f32>; 2],
    /// The feature detector's Gaussian and its first and second
    /// derivatives.
    g: Vec<f32>,
    dg: Vec<f32>,
    ddg: Vec<f32>,
}

impl Kernels {
    fn new(ppd: f32) -> Kernels {
        // The CSFs as sums of Gaussians a·sqrt(π/b)·exp(−π² x² / b), x in
        // degrees (the paper's Table 1), one radius for all: 3 σ of the
        // widest.
        let r = (3.0 * (0.04 / (2.0 * PI * PI)).sqrt() * ppd).ceil() as usize;
        let gauss = |a: f32, b: f32| taps(r, move |i| a * (-PI * PI * (i / ppd).powi(2) / b).exp());
        let cz = [(34.1f32, 0.04f32), (13.5, 0.025)]
            .map(|(a, b)| gauss((a * (PI / b).sqrt()).sqrt(), b));
        let norm = cz
            .iter()
            .map(|k| k.iter().sum::<f32>().powi(2))
            .sum::<f32>()
            .sqrt();
        let cz = cz.map(|k| k.into_iter().map(|v| v / norm).collect());
        let sigma = 0.5 * W * ppd;
        let rf = (3.0 * sigma).ceil() as usize;
        let g = |x: f32| (-x * x / (2.0 * sigma * sigma)).exp();
        Kernels {
            y: normalised(gauss(1.0, 0.0047)),
            cx: normalised(gauss(1.0, 0.0053)),
            cz,
            g: normalised(taps(rf, g)),
            dg: normalised_by_sign(taps(rf, |x| -x * g(x))),
            ddg: normalised_by_sign(taps(rf, |x| (x * x / (sigma * sigma) - 1.0) * g(x))),
        }
    }
}

/// What ꟻLIP compares of one image: its Hunt-adjusted CIELAB after the
/// contrast sensitivity filters, and its edge and point magnitudes.
struct Seen {
    lab: Vec<Rgb>,
    edges: Vec<f32>,
    points: Vec<f32>,
}

fn seen(img: &[Rgb], w: usize, h: usize, k: &Kernels) -> Seen {
    let ycc: Vec<Rgb> = img
        .par_iter()
        .map(|c| xyz_to_ycxcz(rgb_to_xyz(c.map(|v| v.clamp(0.0, 1.0)))))
        .collect();
    let plane = |i: usize| ycc.iter().map(|c| c[i]).collect::<Vec<f32>>();
    let (y, cx, cz) = (plane(0), plane(1), plane(2));
    let fy = separable(&y, w, h, &k.y, &k.y);
    let fcx = separable(&cx, w, h, &k.cx, &k.cx);
    let fcz0 = separable(&cz, w, h, &k.cz[0], &k.cz[0]);
    let fcz1 = separable(&cz, w, h, &k.cz[1], &k.cz[1]);
    let lab = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let rgb = xyz_to_rgb(ycxcz_to_xyz([fy[i], fcx[i], fcz0[i] + fcz1[i]]));
            hunt_lab(rgb_to_xyz(rgb.map(|v| v.clamp(0.0, 1.0))))
        })
        .collect();
    // Features of the unfiltered luminance, normalised to [0, 1].
    let lum: Vec<f32> = y.iter().map(|v| (v + 16.0) / 116.0).collect();
    // The Gaussian along rows is shared by both derivatives along columns.
    let smooth = horizontal(&lum, w, &k.g);
    let magnitude = |d: &[f32]| {
        let a = vertical(&horizontal(&lum, w, d), w, h, &k.g);
        let b = vertical(&smooth, w, h, d);
        a.iter()
            .zip(&b)
            .map(|(a, b)| (a * a + b * b).sqrt())
            .collect()
    };
    Seen {
        lab,
        edges: magnitude(&k.dg),
        points: magnitude(&k.ddg),
    }
}

/// The largest colour error: HyAB between green and blue, raised to qc.
fn cmax() -> f32 {
    let lab = |c: Rgb| hunt_lab(rgb_to_xyz(c));
    hyab(lab([0.0, 1.0, 0.0]), lab([0.0, 0.0, 1.0])).powf(QC)
}

/// The ꟻLIP error map of `test` against `reference`, both `w × h` linear
/// RGB (clamped to [0, 1]: a display's values), seen at `ppd` pixels per
/// degree.
pub fn ldr(reference: &[Rgb], test: &[Rgb], w: usize, h: usize, ppd: f32) -> Vec<f32> {
    ldr_many(reference, &[test], w, h, ppd).remove(0)
}

/// [`ldr`] of each of `tests` against one reference, which is seen once.
pub fn ldr_many(
    reference: &[Rgb],
    tests: &[&[Rgb]],
    w: usize,
    h: usize,
    ppd: f32,
) -> Vec<Vec<f32>> {
    assert_eq!(reference.len(), w * h);
    assert!(tests.iter().all(|t| t.len() == w * h));
    if w == 0 || h == 0 {
        return vec![Vec::new(); tests.len()];
    }
    let k = Kernels::new(ppd);
    let r = seen(reference, w, h, &k);
    tests
        .iter()
        .map(|t| error(&r, &seen(t, w, h, &k)))
        .collect()
}

/// Per pixel ΔE_c^(1 − ΔE_f) of two seen images.
fn error(r: &Seen, t: &Seen) -> Vec<f32> {
    let cmax = cmax();
    (0..r.lab.len())
        .into_par_iter()
        .map(|i| {
            let d = hyab(r.lab[i], t.lab[i]).powf(QC);
            let colour = if d < PC * cmax {
                d * PT / (PC * cmax)
            } else {
                PT + (d - PC * cmax) / (cmax - PC * cmax) * (1.0 - PT)
            };
            let feature = ((r.edges[i] - t.edges[i]).abs()).max((r.points[i] - t.points[i]).abs())
                / std::f32::consts::SQRT_2;
            colour.powf(1.0 - feature.powf(QF))
        })
        .collect()
}

/// ACES (Narkowicz's fit of 0.6 x) as a ratio of quadratics.
const ACES: [f32; 6] = [
    0.6 * 0.6 * 2.51,
    0.6 * 0.03,
    0.0,
    0.6 * 0.6 * 2.43,
    0.6 * 0.59,
    0.14,
];

fn aces(x: f32) -> f32 {
    let k = ACES;
    (k[0] * x * x + k[1] * x + k[2]) / (k[3] * x * x + k[4] * x + k[5])
}

/// The exposures HDR-ꟻLIP evaluates, in stops: from the one that maps the
/// reference's brightest luminance to 0.85 after tone mapping to the one
/// that maps its median there, one a stop or closer, at least two.
/// A reference with no positive luminance has the single range [0, 0].
pub fn exposures(reference: &[Rgb]) -> Vec<f32> {
    // x with aces(x) = 0.85: the larger root of a quadratic.
    let t = 0.85f32;
    let k = ACES;
    let (a, b, c) = (k[0] - t * k[3], k[1] - t * k[4], k[2] - t * k[5]);
    let d1 = -b / (2.0 * a);
    let xmax = d1 + (d1 * d1 - c / a).sqrt();
    let mut lum: Vec<f32> = reference
        .iter()
        .map(|c| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2])
        .collect();
    if lum.is_empty() {
        return vec![0.0, 0.0];
    }
    let n = lum.len();
    let max = lum.iter().copied().fold(f32::MIN, f32::max);
    let (_, median, _) = lum.select_nth_unstable_by(n / 2, f32::total_cmp);
    let median = median.max(f32::EPSILON);
    let (start, stop) = ((xmax / max).log2(), (xmax / median).log2());
    if !(start.is_finite() && stop.is_finite() && start <= stop) {
        return vec![0.0, 0.0];
    }
    let count = ((stop - start).ceil() as usize).max(2);
    let step = (stop - start) / (count - 1) as f32;
    (0..count).map(|i| start + i as f32 * step).collect()
}

/// The HDR-ꟻLIP error map of linear `test` against `reference`: per pixel
/// the largest ꟻLIP over [`exposures`], each image scaled by 2^c and tone
/// mapped by ACES.
pub fn hdr(reference: &[Rgb], test: &[Rgb], w: usize, h: usize, ppd: f32) -> Vec<f32> {
    hdr_many(reference, &[test], w, h, ppd).remove(0)
}

/// [`hdr`] of each of `tests` against one reference, which is seen once
/// an exposure.
pub fn hdr_many(
    reference: &[Rgb],
    tests: &[&[Rgb]],
    w: usize,
    h: usize,
    ppd: f32,
) -> Vec<Vec<f32>> {
    let tone = |img: &[Rgb], c: f32| -> Vec<Rgb> {
        let s = c.exp2();
        img.iter()
            .map(|p| p.map(|v| aces(v * s).clamp(0.0, 1.0)))
            .collect()
    };
    let mut out = vec![vec![0.0f32; w * h]; tests.len()];
    for c in exposures(reference) {
        let toned: Vec<Vec<Rgb>> = tests.iter().map(|t| tone(t, c)).collect();
        let toned: Vec<&[Rgb]> = toned.iter().map(Vec::as_slice).collect();
        let errors = ldr_many(&tone(reference, c), &toned, w, h, ppd);
        for (o, e) in out.iter_mut().zip(errors) {
            for (o, e) in o.iter_mut().zip(e) {
                *o = o.max(e);
            }
        }
    }
    out
}

/// The mean of an error map (what papers report as an image's ꟻLIP).
pub fn mean(map: &[f32]) -> f64 {
    map.iter().map(|&v| v as f64).sum::<f64>() / map.len().max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The kernels' taps as the reference implementation's (its check
    /// values at the default pixels per degree).
    #[test]
    fn kernels_match_the_reference_taps() {
        let k = Kernels::new(PPD);
        let close = |got: &[f32], want: &[f32]| {
            let r = got.len() / 2;
            for (i, w) in want.iter().enumerate() {
                assert!((got[r + i] - w).abs() < 2e-6, "{i}: {} {w}", got[r + i]);
            }
        };
        assert_eq!(k.y.len(), 21);
        close(&k.y, &[0.38576019, 0.24170370, 0.059453988, 0.0057413031]);
        close(&k.cx, &[0.36326905, 0.23998234, 0.069188188, 0.0087053534]);
        close(&k.cz[0], &[0.115442, 0.1092717, 0.0926698, 0.0704134]);
        close(
            &k.cz[1],
            &[0.081692788, 0.074819242, 0.057478056, 0.037038212],
        );
        assert_eq!(k.g.len(), 19);
        close(&k.g, &[0.1452575, 0.1359502, 0.1114560, 0.0800406]);
        close(&k.dg, &[0.0, -0.125649, -0.2060217, -0.2219273]);
        close(&k.ddg, &[-0.2989015, -0.2426999, -0.1078493, 0.0320540]);
        assert!((cmax() - 41.276099).abs() < 1e-4);
    }

    /// The reference implementation's means on images defined by formula
    /// (flip-evaluator 1.7): LDR of sRGB values, and HDR with ACES.
    #[test]
    fn means_match_the_reference_on_formula_images() {
        let (w, h) = (64usize, 48usize);
        let decode = |s: f64| {
            if s <= 0.04045 {
                s / 12.92
            } else {
                ((s + 0.055) / 1.055).powf(2.4)
            }
        };
        let mut reference = Vec::new();
        let mut test = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let r = [
                    x as f64 / 63.0,
                    y as f64 / 47.0,
                    ((x + y) % 16) as f64 / 15.0,
                ];
                let mut t = r;
                if (16..32).contains(&x) && (12..24).contains(&y) {
                    t[0] = 1.0 - t[0];
                }
                t[2] = (t[2] + 0.1 * (((7 * x + 13 * y) % 5) as f64 - 2.0) / 2.0).clamp(0.0, 1.0);
                // The reference decodes its sRGB inputs in f32.
                let f = |c: [f64; 3]| c.map(|v| decode(v as f32 as f64) as f32);
                reference.push(f(r));
                test.push(f(t));
            }
        }
        let m = mean(&ldr(&reference, &test, w, h, PPD));
        assert!((m / 0.06081308424472809 - 1.0).abs() < 1e-4, "{m}");
        let m = mean(&ldr(&reference, &test, w, h, 30.0));
        assert!((m / 0.092113196849823 - 1.0).abs() < 1e-4, "{m}");

        let mut href = Vec::new();
        let mut htest = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let s = 2f64.powf((x as f64 - 32.0) / 8.0);
                let r = [s, s * (y as f64 + 1.0) / 48.0, s * 0.5];
                let g = 1.0 + 0.25 * (((7 * x + 13 * y) % 5) as f64 - 2.0) / 2.0;
                href.push(r.map(|v| v as f32));
                htest.push(r.map(|v| (v * g) as f32));
            }
        }
        let e = exposures(&href);
        assert_eq!(e.len(), 5);
        assert!((e[0] + 2.7386582).abs() < 1e-4 && (e[4] - 1.9343008).abs() < 1e-4);
        let m = mean(&hdr(&href, &htest, w, h, PPD));
        assert!((m / 0.049424439668655396 - 1.0).abs() < 1e-4, "{m}");
    }
}
