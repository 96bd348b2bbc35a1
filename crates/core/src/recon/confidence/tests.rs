//! The intervals against formulas by hand, at chosen pixels against the
//! film's, and the blocks' hold.

use super::*;

use crate::recon::test_header as header;

fn rec(x: f32, y: f32, v: [f32; 3]) -> Record {
    Record::new(x, y, 0.0, v)
}

/// Against the two-pass formula by hand on a 3 × 1 film: the middle
/// pixel's own variance is below its compatible neighbours' mean, the
/// left one's above it; the right pixel has one sample and a mean no
/// neighbour's interval reaches, so nothing bounds it.
#[test]
fn interval_by_hand() {
    let h = header(3, 1);
    let records = [
        rec(0.5, 0.5, [1.0, 0.0, 0.0]),
        rec(0.5, 0.5, [5.0, 0.0, 0.0]),
        rec(1.5, 0.5, [2.0, 2.0, 2.0]),
        rec(1.5, 0.5, [2.0, 2.0, 2.0]),
        rec(1.5, 0.5, [3.0, 2.0, 2.0]),
        rec(2.5, 0.5, [7.0, 0.0, 0.0]),
        rec(f32::NAN, 0.5, [1e9, 0.0, 0.0]),
    ];
    let ci = interval(&records, &h, 2.0);
    // Pixel 0: mean 3, s² = 8, SE 2; pixel 1: mean 7/3, s² = 1/3, SE 1/3.
    // |3 − 7/3| ≤ 2 (2 + 1/3): compatible, pooled s² = (8 + 1/3) / 2.
    assert_eq!(ci.centre.data[0], [3.0, 0.0, 0.0]);
    assert!((ci.half_width.data[0][0] - 2.0 * (8.0f64 / 2.0).sqrt()).abs() < 1e-12);
    let pooled = (8.0 + 1.0 / 3.0) / 2.0;
    assert!((ci.centre.data[1][0] - 7.0 / 3.0).abs() < 1e-12);
    assert!((ci.half_width.data[1][0] - 2.0 * (pooled / 3.0f64).sqrt()).abs() < 1e-12);
    // Green: pixel 0's 0 lies 2 from pixel 1's 2, beyond 2 (0 + 0); pixel
    // 1 keeps its own s² = 0.
    assert_eq!(ci.half_width.data[1][1], 0.0);
    // Pixel 2: one sample at 7, beyond 2 · (1/3 + 0) of pixel 1's mean.
    assert_eq!(ci.centre.data[2], [7.0, 0.0, 0.0]);
    assert_eq!(ci.half_width.data[2][0], f64::INFINITY);
    assert_eq!(ci.clamp(2, [9.0, 1.0, 2.5]), [9.0, 1.0, 2.5]);
    assert_eq!(
        ci.clamp(1, [9.0, 1.0, 2.5]),
        [7.0 / 3.0 + 2.0 * (pooled / 3.0f64).sqrt(), 2.0, 2.0]
    );
}

/// A light's pixels, whose samples agree, keep a zero-width interval
/// beside a noisy wall; a pixel whose samples missed a rare bright
/// path takes its compatible neighbours' variance.
#[test]
fn pooling_only_over_compatible_neighbours() {
    let h = header(3, 1);
    let mut records = Vec::new();
    for i in 0..16 {
        records.push(rec(0.5, 0.5, [10.0; 3]));
        let wall = if i % 4 == 0 { 4.0 } else { 0.0 };
        records.push(rec(1.5, 0.5, [wall; 3]));
        records.push(rec(2.5, 0.5, [if i == 0 { 0.3 } else { 0.2 }; 3]));
    }
    let ci = interval(&records, &h, Z);
    assert_eq!(ci.half_width.data[0], [0.0; 3]);
    // The wall (mean 1, s² = 3.2, SE ≈ 0.45) and the dim pixel (mean
    // 0.20625, SE 0.00625): |1 − 0.20625| ≤ 3 (0.45 + 0.006), so the dim
    // pixel takes the mean of its own and the wall's s².
    let wall_s2 = 16.0 * 4.0 * 0.75 / 15.0 * 1.0;
    let dim_s2 = (0.01f64 * 15.0 / 16.0) / 15.0;
    let want = Z * ((wall_s2 + dim_s2) / 2.0 / 16.0f64).sqrt();
    // (0.2 and 0.3 are f32 in a record.)
    assert!(
        (ci.half_width.data[2][0] - want).abs() < 1e-7,
        "{:?}",
        ci.half_width.data[2]
    );
}

/// The intervals made at chosen pixels alone are the film's there,
/// bit for bit: corners, edges, both frames, pixels with no sample
/// or one, a bright pixel beside dim ones.
#[test]
fn intervals_at_pixels_are_the_films() {
    let synth = crate::synth::SynthParams {
        width: 9,
        height: 7,
        frames: 2,
        spp: 5,
        firefly_fraction: 0.1,
        ..crate::synth::SynthParams::default()
    };
    let h = synth.header();
    // Pixel 10 of each frame loses every sample, pixel 20 all but one.
    let records: Vec<Record> = synth
        .records()
        .enumerate()
        .filter(|(i, _)| {
            let (px, s) = (i / 5, i % 5);
            px % 63 != 10 && (px % 63 != 20 || s == 0)
        })
        .map(|(_, r)| r)
        .collect();
    let moments = per_pixel::fold(&records, &h, 1, |_| true, Moments::add);
    let film = from_moments(&moments, &h, Z);
    let at = [
        0,
        8,
        10,
        20,
        21,
        31,
        54,
        62,
        63,
        63 + 10,
        63 + 20,
        63 + 40,
        125,
    ];
    let got = from_moments_at(&moments, |m| m, &h, Z, &at);
    let bits = |v: &[[f64; 3]]| -> Vec<u64> { v.iter().flatten().map(|x| x.to_bits()).collect() };
    let film_at = |img: &Image| -> Vec<[f64; 3]> { at.iter().map(|&px| img.data[px]).collect() };
    assert_eq!(bits(&got.centre.data), bits(&film_at(&film.centre)));
    assert_eq!(bits(&got.half_width.data), bits(&film_at(&film.half_width)));
    assert_eq!(bits(&got.own_se.data), bits(&film_at(&film.own_se)));
    let counts: Vec<u32> = at.iter().map(|&px| film.count[px]).collect();
    assert_eq!(got.count, counts);
    assert_eq!((got.count[2], got.count[3]), (0, 1));
    assert!(
        got.half_width
            .data
            .iter()
            .flatten()
            .any(|w| w.is_finite() && *w > 0.0)
    );
}

/// Large, nearly equal samples: Welford keeps the variance that a
/// one-pass Σx² − (Σx)²/n would lose to cancellation.
#[test]
fn no_cancellation_at_large_values() {
    let h = header(1, 1);
    let v = [1.0e7f32, 1.0e7 + 1.0, 1.0e7 + 2.0];
    let records: Vec<Record> = v.iter().map(|&v| rec(0.5, 0.5, [v; 3])).collect();
    let ci = interval(&records, &h, 1.0);
    // s² = 1, n = 3.
    assert!((ci.half_width.data[0][0] - (1.0f64 / 3.0).sqrt()).abs() < 1e-9);
    assert_eq!(ci.centre.data[0][0], 1.0e7 + 1.0);
}

#[test]
fn empty_pixels_have_an_empty_interval() {
    let h = header(2, 2);
    let ci = interval(&[rec(0.5, 0.5, [1.0; 3])], &h, Z);
    // One sample, no neighbour with two: unbounded.
    assert_eq!(ci.half_width.data[0], [f64::INFINITY; 3]);
    assert_eq!(ci.clamp(0, [4.0, 1.0, -1.0]), [4.0, 1.0, -1.0]);
    assert_eq!(ci.centre.data[3], [0.0; 3]);
    assert_eq!(ci.half_width.data[3], [0.0; 3]);
    assert_eq!(ci.clamp(3, [4.0, 1.0, -1.0]), [0.0; 3]);
}

fn film(w: usize, h: usize, frames: usize, v: f64) -> Image {
    Image {
        width: w,
        height: h,
        frames,
        data: vec![[v; 3]; w * h * frames],
    }
}

/// Every pixel's mean 10 with SE 1 (own SE 5, which blocks do not use).
fn tens(w: usize, h: usize, frames: usize) -> Interval {
    Interval {
        centre: film(w, h, frames, 10.0),
        half_width: film(w, h, frames, 2.0),
        count: vec![4; w * h * frames],
        own_se: film(w, h, frames, 5.0),
        z: 2.0,
    }
}

/// A 4 × 4 film: an image 9 on average is inside every 2 × 2 block's
/// interval (10 ± 3·√4/4) but not the whole film's (10 ± 3·√16/16), and
/// is scaled, not shifted, so that its mean sits on that edge; one
/// pixel at 14 moves no block's mean out of its interval.
#[test]
fn blocks_bound_a_regional_bias_and_not_an_outlier() {
    let ci = tens(4, 4, 1);
    let mut dim = film(4, 4, 1, 9.0);
    dim.data[0] = [4.5; 3];
    dim.data[1] = [13.5; 3];
    ci.hold_blocks(&mut dim, Z);
    let k = 9.25 / 9.0;
    for (px, v) in dim.data.iter().enumerate() {
        let want = [4.5 * k, 13.5 * k, 9.0 * k][px.min(2)];
        for c in v {
            assert!((c - want).abs() < 1e-12, "{px}: {c}");
        }
    }
    let mut outlier = film(4, 4, 1, 10.0);
    outlier.data[5] = [14.0; 3];
    let before = outlier.data.clone();
    ci.hold_blocks(&mut outlier, Z);
    assert_eq!(outlier.data, before);
}

/// Rows of blocks held in parallel give the bits of the blocks held
/// one after another over the whole image, on films whose sides are
/// no multiple of the blocks', with frames.
#[test]
fn blocks_held_by_rows_are_those_held_in_turn() {
    let mut unit = crate::synth::test_units(3);
    for (w, h, frames) in [(13, 7, 3), (1, 9, 2), (9, 1, 1), (32, 32, 1)] {
        let mut ci = tens(w, h, frames);
        let mut img = film(w, h, frames, 9.0);
        for px in 0..w * h * frames {
            ci.centre.data[px] = [10.0 + unit(); 3];
            ci.half_width.data[px] = [if unit() < 0.05 { f64::INFINITY } else { unit() }; 3];
            img.data[px] = std::array::from_fn(|_| 8.0 + 4.0 * unit());
        }
        let (mut want, before) = (img.clone(), img.clone());
        let mut b = 2;
        while b < 2 * w.max(h) {
            for f in 0..frames {
                for by in (0..h).step_by(b) {
                    for bx in (0..w).step_by(b) {
                        let (rows, cols) = (by..(by + b).min(h), bx..(bx + b).min(w));
                        let base = f * w * h;
                        let block = rows.flat_map(|y| cols.clone().map(move |x| base + y * w + x));
                        ci.hold_block(&mut want.data, 0, block, Z);
                    }
                }
            }
            b *= 2;
        }
        ci.hold_blocks(&mut img, Z);
        let bits = |i: &Image| {
            i.data
                .iter()
                .map(|p| p.map(f64::to_bits))
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&img), bits(&want), "{w} × {h} × {frames}");
        assert_ne!(bits(&img), bits(&before), "no block moved");
    }
}

/// A 5 × 3 film of two frames, blocks partial at its edges. Frame 0
/// is 9 everywhere but for one pixel of unbounded interval, which is
/// left out and alone; the coarsest block puts the mean of the 14
/// others on 10 − 3·√14/14. Frame 1 is 19 against 20, inside every
/// block that has no NaN, and a NaN pixel stops every block that has
/// it: frame 1 stays as it was (nothing crosses between frames).
#[test]
fn blocks_leave_unbounded_pixels_nan_and_other_frames_alone() {
    let mut ci = tens(5, 3, 2);
    let corner = 2 * 5 + 4;
    ci.half_width.data[corner] = [f64::INFINITY; 3];
    for v in &mut ci.centre.data[15..] {
        *v = [20.0; 3];
    }
    let mut img = film(5, 3, 2, 9.0);
    img.data[corner] = [100.0; 3];
    for v in &mut img.data[15..] {
        *v = [19.0; 3];
    }
    img.data[15 + 7] = [f64::NAN; 3];
    ci.hold_blocks(&mut img, Z);
    assert_eq!(img.data[corner], [100.0; 3]);
    let held: f64 = (0..15)
        .filter(|&px| px != corner)
        .map(|px| img.data[px][0])
        .sum();
    let edge = 10.0 - 3.0 * 14f64.sqrt() / 14.0;
    assert!((held / 14.0 - edge).abs() < 1e-12, "{}", held / 14.0);
    for (px, v) in img.data[15..].iter().enumerate() {
        if px == 7 {
            assert!(v[0].is_nan());
        } else {
            assert_eq!(*v, [19.0; 3], "{px}");
        }
    }
}
