//! statmc's window against its definition: by blocks, runs and tiles
//! against a loop over each output pixel's own window, the pairs'
//! squared pre-test against its written form, the vector run against
//! the portable one.

use super::*;
use crate::dump::Record;
use crate::recon::statmc::welch::agree;
use crate::recon::statmc::{Guide, denoise, stats_of};
use crate::recon::{Image, test_header};

/// The squared pre-test decides as the written form does, on random
/// pairs and on pairs built at the boundary, one ulp either side, in
/// the subnormal range and at zero spread; so does the window's loop
/// over a run ([`pair_weights`]) wherever it decides a pair itself.
#[test]
fn agree_is_the_written_test() {
    let written = |d: f64, s: f64, crit: f64| d.abs() <= crit * s.sqrt();
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    // Both outcomes occur at the boundary: the cases test something.
    let (mut outcomes, mut by_run) = ([0usize; 2], 0);
    for i in 0..200_000 {
        let crit = 1.0 + 3.0 * next();
        let scale = 10f64.powi((next() * 40.0) as i32 - 20);
        let (se_p, se_q) = (next() * scale, next() * scale);
        let mut d = crit * (se_p + se_q).sqrt();
        match i % 4 {
            0 => d *= 0.5 + next(),
            1 => {}
            2 => d = f64::from_bits(d.to_bits() + 1),
            _ => d = f64::from_bits(d.to_bits().saturating_sub(1)),
        }
        let tiny = d * 1e-150;
        for (sp, sq, d) in [
            (se_p, se_q, d),
            (se_p * 1e-300, se_q * 1e-300, tiny),
            (0.0, 0.0, d),
            (0.0, 0.0, 0.0),
        ] {
            let want = written(d, sp + sq, crit);
            assert_eq!(
                agree(0.0, d, sp + sq, crit, crit * crit),
                want,
                "{d} {sp} {sq} {crit}"
            );
            // The same pair as pixels of 8 samples, four times in a
            // run (in vector registers where the CPU has them) and
            // once pair by pair.
            let f = Fields {
                features: None,
                n: vec![8; 8],
                mean: std::array::from_fn(|_| vec![0.0; 8]),
                y_mean: std::array::from_fn(|_| [[0.0; 4], [d; 4]].concat()),
                se2: std::array::from_fn(|_| [[sp; 4], [sq; 4]].concat()),
                spread: vec![0.0; 8],
                limit: vec![f64::INFINITY; 8],
                patch_spread: vec![f64::NAN; 8],
            };
            let k = Kernel {
                t: vec![crit; 15],
                t2: vec![crit * crit; 15],
                spatial: [1.0; RADIUS + 1],
                patch: Kernel::new(1).patch,
            };
            let weight = if want { 8.0 } else { 0.0 };
            let mut wq = [0.0; 4];
            let pairs = Pairs {
                ws: 1.0,
                p: 0,
                q: 4,
            };
            if !pair_weights(&f, &k, &pairs, &mut wq) {
                assert_eq!(wq, [weight; 4], "{d} {sp} {sq} {crit}");
                by_run += 1;
            }
            if !pair_weights_portable(&f, &k, &pairs, &mut wq[..1], 0) {
                assert_eq!(wq[0], weight, "{d} {sp} {sq} {crit}");
            }
            assert_eq!(f.compatible(0, 4, &k), want);
            if i % 4 != 0 {
                outcomes[usize::from(want)] += 1;
            }
        }
    }
    assert!(outcomes[0] > 1000 && outcomes[1] > 1000, "{outcomes:?}");
    assert!(by_run > 400_000, "{by_run} pairs decided in the run");
}

/// The window as its definition says it, one output pixel at a time:
/// the compatible neighbours' means whose patches pass, each weighted
/// by its count, the spatial Gaussian and the features' weight, the
/// others skipped (every patch passing where `patched` is false).
fn denoise_per_pixel(
    f: &Fields,
    k: &Kernel,
    (w, ht): (usize, usize),
    patched: bool,
) -> Vec<[f64; 3]> {
    // The patch test's sums of the pair (p, q), pixels of one frame
    // at (x, y) and (nx, ny): along each row, then over the rows.
    let patches = |base: usize, (x, y): (usize, usize), (nx, ny): (usize, usize)| {
        let on = |x: usize, u: isize, len: usize| x.checked_add_signed(u).filter(|&v| v < len);
        // Σ a, Σ S_p, Σ S_q and the count m.
        let mut sums = [0.0f64; 4];
        for uy in -1..=1 {
            let mut row = [0.0f64; 4];
            for ux in -1..=1 {
                let (Some(px), Some(py)) = (on(x, ux, w), on(y, uy, ht)) else {
                    continue;
                };
                let (Some(qx), Some(qy)) = (on(nx, ux, w), on(ny, uy, ht)) else {
                    continue;
                };
                let pair = f.patch_term(base + py * w + px, base + qy * w + qx);
                if let Some((a, sp, sq)) = pair {
                    row = [row[0] + a, row[1] + sp, row[2] + sq, row[3] + 1.0];
                }
            }
            sums = std::array::from_fn(|i| sums[i] + row[i]);
        }
        let [a, sp, sq, m] = sums;
        !patched || patch_passes(k, a, sp + sq, m)
    };
    (0..f.n.len())
        .map(|px| {
            let n = f.n[px];
            if n < 2 {
                return std::array::from_fn(|c| if n == 1 { f.mean[c][px] } else { 0.0 });
            }
            let (base, i) = (px - px % (w * ht), px % (w * ht));
            let (x, y) = (i % w, i / w);
            let (mut sum, mut weight) = ([0.0f64; 3], 0.0f64);
            for ny in y.saturating_sub(RADIUS)..(y + RADIUS + 1).min(ht) {
                for nx in x.saturating_sub(RADIUS)..(x + RADIUS + 1).min(w) {
                    let q = base + ny * w + nx;
                    if !f.compatible(px, q, k) || !patches(base, (x, y), (nx, ny)) {
                        continue;
                    }
                    let wq = k.spatial[ny.abs_diff(y)] * k.spatial[nx.abs_diff(x)];
                    let wq = wq * f.n[q] as f64;
                    let wq = f.features.as_ref().map_or(wq, |g| wq * g.weight(px, q));
                    for (c, s) in sum.iter_mut().enumerate() {
                        *s += wq * f.mean[c][q];
                    }
                    weight += wq;
                }
            }
            sum.map(|s| s / weight)
        })
        .collect()
}

/// The window taken offset by offset along runs of a block's rows
/// gives each pixel the bits of its own window's loop: films narrower
/// than the window and wider than a run, blocks across frames, pixels
/// with 0, 1 and many samples, zero-variance pixels (equal and
/// unequal), outliers, patches that fail where the pairs pass.
#[test]
fn the_window_by_runs_is_the_per_pixel_window() {
    let mut unit = crate::synth::test_units(7);
    let mut patched = 0;
    let films = [
        (1, 1, 1),
        (5, 3, 2),
        (19, 23, 1),
        (7, 11, 2),
        (2 * RUN + 37, 4, 2),
    ];
    for (w, ht, frames) in films {
        let mut h = test_header(w as u32, ht as u32);
        h.frames = frames;
        let mut recs = Vec::new();
        for px in 0..w * ht * frames as usize {
            let (f, i) = (px / (w * ht), px % (w * ht));
            let (x, y) = ((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
            let kind = (unit() * 8.0) as usize;
            let n = [0, 1, 2, 8, 8, 8, 16, 3][kind];
            let level = if x < w as f32 / 2.0 { 1.0 } else { 4.0 };
            for s in 0..n {
                let v = match kind {
                    // Zero variance: one level, or the level of a
                    // neighbouring column.
                    3 => level,
                    4 => level + (x as usize % 2) as f32,
                    _ if unit() < 0.02 => 300.0 * unit() as f32,
                    _ => level * (0.5 + unit() as f32),
                };
                let c = [v, v * (0.5 + 0.1 * s as f32), 0.0];
                recs.push(Record::new(x, y, f as f32 + 0.5, c));
            }
        }
        // Features of a few levels: equal (weight 1), near and far.
        let mut feature = || -> Vec<f32> {
            let levels = [0.2, 0.2, 0.21, 0.5, 0.9];
            let len = 3 * w * ht * frames as usize;
            (0..len).map(|_| levels[(unit() * 5.0) as usize]).collect()
        };
        let (albedo, normal) = (feature(), feature());
        let guides = [
            None,
            Some(Guide::new(&albedo, None)),
            Some(Guide::new(&albedo, Some(&normal))),
        ];
        let stats = stats_of(&recs, &h, |i| i % 31 != 5);
        let k = Kernel::new(stats.iter().map(|s| s.x.n).max().unwrap_or(0));
        for guide in guides {
            let img = denoise(&recs, &h, |i| i % 31 != 5, guide);
            let fields = Fields::new(&stats, w, ht, guide);
            let want = denoise_per_pixel(&fields, &k, (w, ht), true);
            let unpatched = denoise_per_pixel(&fields, &k, (w, ht), false);
            patched += want.iter().zip(&unpatched).filter(|(a, b)| a != b).count();
            for (px, (got, want)) in img.data.iter().zip(&want).enumerate() {
                let bits = |v: &[f64; 3]| v.map(f64::to_bits);
                let guided = guide.is_some();
                assert_eq!(
                    bits(got),
                    bits(want),
                    "{w} × {ht} × {frames}, {guided}, {px}"
                );
            }
        }
    }
    // The patches left some pairs out that the pairs' own test passed.
    assert!(patched > 50, "{patched}");
}

/// The window at chosen pixels is the film's window there, bit for
/// bit: a tile's pixels dense (taken as one block of rows), scattered
/// (runs of a row each), a long row and the film's edges, both frames.
#[test]
fn the_window_at_pixels_is_the_films_window_there() {
    let (w, ht, frames) = (RUN + 44, 20, 2);
    let mut h = test_header(w as u32, ht as u32);
    h.frames = frames;
    let mut unit = crate::synth::test_units(19);
    let mut recs = Vec::new();
    for px in 0..w * ht * frames as usize {
        let (f, i) = (px / (w * ht), px % (w * ht));
        let (x, y) = ((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
        let level = 1.0 + (x / 40.0).floor();
        for _ in 0..(2 + (unit() * 8.0) as usize) {
            let v = level * (0.6 + 0.8 * unit() as f32);
            recs.push(Record::new(x, y, f as f32 + 0.5, [v, 0.5 * v, 0.2]));
        }
    }
    let stats = stats_of(&recs, &h, |_| true);
    let fields = Fields::new(&stats, w, ht, None);
    let k = Kernel::new(stats.iter().map(|s| s.x.n).max().unwrap_or(0));
    let mut film = Image::for_header(&h);
    window(&fields, &k, &h, 0, &mut film.data);
    let frame = w * ht;
    // Dense: rows 2–6 of the first block, columns 10–60.
    let dense: Vec<usize> = (2..7)
        .flat_map(|y| (10..61).map(move |x| y * w + x))
        .collect();
    let scattered: Vec<usize> = (0..2 * frame).step_by(37).collect();
    let mut mixed: Vec<usize> = dense.iter().chain(&scattered).copied().collect();
    mixed.extend((9 * w..10 * w).chain([0, frame - 1, frame, 2 * frame - 1]));
    mixed.sort();
    mixed.dedup();
    assert_eq!(plan(&dense, w, ht).len(), 1);
    assert_eq!(plan(&scattered[..3], w, ht).len(), 3);
    for pixels in [dense, scattered, mixed] {
        let got = window_at(&fields, &k, &h, &pixels);
        for (px, got) in pixels.iter().zip(got) {
            let want = film.data[*px];
            assert_eq!(got.map(f64::to_bits), want.map(f64::to_bits), "pixel {px}");
        }
    }
}

/// Where the squares cannot decide (t²·s in the subnormal range, or
/// a pair on the boundary itself), the window takes the written form,
/// pair by pair, as the per-pixel window does.
#[test]
fn the_window_decides_the_pairs_its_run_cannot() {
    let (w, ht) = (40, 3);
    let crit = 2.0f64;
    let k = Kernel {
        t: vec![crit; 64],
        t2: vec![crit * crit; 64],
        ..Kernel::new(1)
    };
    let px = w * ht;
    let tiny: f64 = 1e-300;
    // y at 0, 1 or 2 times exactly t·√(2·se2): on the boundary, subnormal.
    let on_edge = crit * (2.0 * tiny).sqrt();
    let y: Vec<f64> = (0..px).map(|i| (i % 3) as f64 * on_edge).collect();
    let f = Fields {
        features: None,
        n: vec![8; px],
        mean: std::array::from_fn(|c| (0..px).map(|i| (i * (c + 1)) as f64).collect()),
        y_mean: std::array::from_fn(|_| y.clone()),
        se2: std::array::from_fn(|_| vec![tiny; px]),
        // Far above the patches' differences: every patch passes, and
        // the pairs' own test decides.
        spread: vec![1.0; px],
        limit: vec![f64::INFINITY; px],
        patch_spread: super::super::fields::patch_spreads(&vec![8; px], &vec![1.0; px], w, ht),
    };
    let h = test_header(w as u32, ht as u32);
    let mut got = Image::for_header(&h);
    window(&f, &k, &h, 0, &mut got.data);
    let want = denoise_per_pixel(&f, &k, (w, ht), true);
    for (px, (got, want)) in got.data.iter().zip(&want).enumerate() {
        assert_eq!(got.map(f64::to_bits), want.map(f64::to_bits), "pixel {px}");
    }
    // Levels one apart agree and two apart do not: the window left
    // some pairs out, so it is not the mean of the whole window.
    let all = denoise_per_pixel(
        &Fields {
            y_mean: std::array::from_fn(|_| vec![0.0; px]),
            ..f
        },
        &k,
        (w, ht),
        true,
    );
    assert!(got.data.iter().zip(&all).any(|(g, a)| g != a));
}

/// The four-at-a-time loop gives the pair-by-pair loop's weights and
/// verdict on runs of any length whose pixels differ lane by lane:
/// counts (0, 1, 2 and more), spreads and their limits, zero
/// variances, equal and unequal means.
#[test]
fn the_vector_run_is_the_portable_run() {
    let mut unit = crate::synth::test_units(11);
    let px = 256;
    for trial in 0..300 {
        let mut pick = |choices: &[f64]| choices[(unit() * choices.len() as f64) as usize];
        let n: Vec<u32> = (0..px)
            .map(|_| pick(&[0.0, 1.0, 2.0, 5.0, 8.0, 16.0]) as u32)
            .collect();
        let y: Vec<f64> = (0..px).map(|_| pick(&[0.0, 1.0, 1.5, 2.0, 9.0])).collect();
        let se2: Vec<f64> = (0..px).map(|_| pick(&[0.0, 0.0, 0.01, 0.3, 2.0])).collect();
        let f = Fields {
            features: None,
            mean: std::array::from_fn(|c| (0..px).map(|i| (i + c) as f64).collect()),
            y_mean: std::array::from_fn(|c| y.iter().map(|v| v + c as f64 * 0.1).collect()),
            se2: std::array::from_fn(|_| se2.clone()),
            spread: se2.iter().map(|v| 3.0 * v).collect(),
            limit: (0..px)
                .map(|_| pick(&[0.0, 0.5, 5.0, f64::INFINITY]))
                .collect(),
            patch_spread: vec![f64::NAN; px],
            n,
        };
        let k = Kernel::new(16);
        let len = 1 + trial % 120;
        let (mut vector, mut portable) = (vec![0.0; len], vec![-1.0; len]);
        let pairs = Pairs {
            ws: 0.7,
            p: 3,
            q: 130,
        };
        let undecided = pair_weights(&f, &k, &pairs, &mut vector);
        let undecided_portable = pair_weights_portable(&f, &k, &pairs, &mut portable, 0);
        assert_eq!(undecided, undecided_portable, "trial {trial}");
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&vector), bits(&portable), "trial {trial}");
    }
}
