//! The spread against a serial oracle that writes the rule out, and its
//! behaviours one by one.

use super::*;

/// The spread source by source, each over its whole window (its own
/// kernel and window, no bands), with the standing-out test of
/// docs/filter.md written out: the oracle. Also the numbers of
/// sources spread and left removed.
fn serial(
    filtered: &Image,
    removed: &Image,
    occupancy: &[u32],
    sigma: f64,
) -> (Image, usize, usize, usize) {
    use crate::joint::lab::luminance;
    let (w, h) = (filtered.width, filtered.height);
    let r = (3.0 * sigma).ceil().max(0.0) as isize;
    let kernel: Vec<f64> = (-r..=r)
        .map(|d| (-((d * d) as f64) / (2.0 * sigma * sigma)).exp())
        .collect();
    let n = w * h;
    let window = |src: usize, visit: &mut dyn FnMut(usize, f64)| {
        let frame = src / n * n;
        let (x, y) = (((src % n) % w) as isize, ((src % n) / w) as isize);
        for dy in -r..=r {
            let qy = y + dy;
            if qy < 0 || qy >= h as isize {
                continue;
            }
            for dx in -r..=r {
                let qx = x + dx;
                if qx < 0 || qx >= w as isize {
                    continue;
                }
                let q = frame + qy as usize * w + qx as usize;
                if occupancy[q] > 0 {
                    visit(q, kernel[(dy + r) as usize] * kernel[(dx + r) as usize]);
                }
            }
        }
    };
    let (mut sum, mut count) = (0.0, 0);
    for (p, &o) in filtered.data.iter().zip(occupancy) {
        if o > 0 {
            sum += luminance(*p);
            count += 1;
        }
    }
    let mean = sum / count.max(1) as f64;
    let film = if mean > 0.0 { mean } else { f64::MIN_POSITIVE };
    let ln = |q: usize| (luminance(filtered.data[q]).max(1e-4 * film).ln() - film.ln()) as f32;
    let sources: Vec<usize> = (0..removed.data.len())
        .filter(|&s| removed.data[s] != [0.0; 3] && occupancy[s] > 0)
        .collect();
    let (mut totals, mut levels) = (vec![0.0; removed.data.len()], vec![0.0; removed.data.len()]);
    let mut peaks = vec![0f32; removed.data.len()];
    for &src in &sources {
        let (mut total, mut log_level) = (0.0, 0.0);
        window(src, &mut |q, k| {
            total += k;
            log_level += k * ln(q) as f64;
        });
        totals[src] = total;
        levels[src] = (log_level / total + film.ln()).exp();
        peaks[src] = (luminance(removed.data[src]).max(0.0) / total) as f32;
    }
    // Rounds: every source still given back is judged against the
    // others still given back; those that stand out are taken out
    // together, until a round takes none.
    let mut given: Vec<bool> = vec![true; sources.len()];
    let mut rounds = 0;
    loop {
        let mut now = Vec::new();
        for (i, &src) in sources.iter().enumerate() {
            if !given[i] {
                continue;
            }
            let mut others = 0.0;
            window(src, &mut |q, k| {
                let j = sources.binary_search(&q);
                if q != src && j.is_ok_and(|j| given[j]) {
                    others += k * peaks[q] as f64;
                }
            });
            if luminance(removed.data[src]) / totals[src] > STANDOUT * (levels[src] + others) {
                now.push(i);
            }
        }
        if now.is_empty() {
            break;
        }
        rounds += 1;
        for i in now {
            given[i] = false;
        }
    }
    let mut out = filtered.clone();
    let (mut spread, mut left) = (0, 0);
    let given_all = given.clone();
    for (&src, &given) in sources.iter().zip(&given) {
        if !given {
            left += 1;
            continue;
        }
        // Given back to the window's pixels near its level, each
        // pixel's the brightest of its 3 × 3 neighbourhood.
        let brightest = |q: usize| {
            let (frame, x, y) = (q / n * n, (q % n) % w, (q % n) / w);
            let mut m = f32::NEG_INFINITY;
            for qy in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                for qx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                    m = m.max(ln(frame + qy * w + qx));
                }
            }
            m
        };
        let own = brightest(src);
        let weight = |q: usize| {
            let d = (brightest(q) - own) as f64;
            (-d * d / (2.0 * RANGE * RANGE)).exp()
        };
        let (mut by_level, mut others) = (0.0, 0.0);
        window(src, &mut |q, k| {
            by_level += k * weight(q);
            let j = sources.binary_search(&q);
            if q != src && j.is_ok_and(|j| given_all[j]) {
                others += k * peaks[q] as f64;
            }
        });
        // By level unless its peak there would exceed what it lands
        // on; then plain.
        let plain = luminance(removed.data[src]) / by_level > levels[src] + others;
        let (weight, total): (&dyn Fn(usize) -> f64, f64) = match plain {
            true => (&|_| 1.0, totals[src]),
            false => (&weight, by_level),
        };
        let e = removed.data[src];
        spread += 1;
        window(src, &mut |q, k| {
            let k = k * weight(q);
            for (o, v) in out.data[q].iter_mut().zip(e) {
                *o += v * k / total;
            }
        });
    }
    (out, spread, left, rounds)
}

/// [`energy_aware`]'s image, checked bit for bit against the oracle's,
/// with the oracle's numbers of sources spread and left removed.
fn checked(
    filtered: &Image,
    removed: &Image,
    occupancy: &[u32],
    sigma: f64,
) -> (Image, usize, usize) {
    let out = energy_aware(filtered, removed, occupancy, sigma);
    let (want, spread, left, _) = serial(filtered, removed, occupancy, sigma);
    assert_eq!(out.data, want.data);
    (out, spread, left)
}

/// Bands of every height against the serial spread, bit for bit, on
/// films of two frames, sparse sources, black and empty pixels,
/// windows wider and narrower than a band, for one and three threads;
/// on each film but the single pixel some sources are spread and some
/// left removed.
#[test]
fn bands_are_the_serial_spread() {
    let mut unit = crate::synth::test_units(99);
    let films = [
        (37, 45, 8.0, 1.0),
        (5, 70, 1.5, 20.0),
        (60, 3, 0.4, 40.0),
        (1, 1, 2.0, 1.0),
    ];
    let mut most_rounds = 0;
    for (w, h, sigma, background) in films {
        let mut removed = Image::new(w, h, 2);
        let mut filtered = Image::new(w, h, 2);
        let occupancy: Vec<u32> = (0..w * h * 2).map(|_| u32::from(unit() < 0.9)).collect();
        for (f, e) in filtered.data.iter_mut().zip(&mut removed.data) {
            if unit() < 0.9 {
                *f = std::array::from_fn(|_| background * unit());
            }
            if unit() < 0.1 {
                *e = std::array::from_fn(|_| 100.0 * unit() - 10.0);
            }
        }
        // A lone spike that stands out on any of these backgrounds.
        let mut occupancy = occupancy;
        let centre = h / 2 * w + w / 2;
        (removed.data[centre], occupancy[centre]) = ([1e5; 3], 1);
        let (want, spread, left, rounds) = serial(&filtered, &removed, &occupancy, sigma);
        most_rounds = most_rounds.max(rounds);
        if w * h > 1 {
            assert!(
                spread > 0 && left > 0,
                "{w} × {h}: {spread} spread, {left} left"
            );
        }
        for threads in [1, 3] {
            let got = crate::par::pool(threads)
                .unwrap()
                .install(|| energy_aware(&filtered, &removed, &occupancy, sigma));
            let bits =
                |i: &Image| -> Vec<u64> { i.data.iter().flatten().map(|v| v.to_bits()).collect() };
            assert_eq!(bits(&got), bits(&want), "{w} × {h}, σ_e {sigma}");
        }
    }
    // Some source stood out only once a source beside it was taken out.
    assert!(most_rounds >= 2, "{most_rounds} rounds");
}

/// Whether a source's window holds one of a list of pixels, against
/// every pixel of the window tried: frames, edges, the window's rim.
#[test]
fn reaches_is_the_window() {
    let mut unit = crate::synth::test_units(5);
    for (w, h, sigma) in [(9, 7, 1.0), (4, 11, 0.7), (13, 3, 2.0)] {
        let img = Image::new(w, h, 2);
        let occupancy = vec![1; w * h * 2];
        let spread = Spread::new(&img, sigma, &occupancy);
        let r = spread.r as isize;
        for _ in 0..200 {
            let pixels: Vec<usize> = (0..w * h * 2).filter(|_| unit() < 0.05).collect();
            for src in 0..w * h * 2 {
                let (f, x, y) = (src / (w * h), src % w, src % (w * h) / w);
                let near = pixels.iter().any(|&q| {
                    let (qf, qx, qy) = (q / (w * h), q % w, q % (w * h) / w);
                    let d = |a: usize, b: usize| (a as isize - b as isize).abs();
                    qf == f && d(qx, x) <= r && d(qy, y) <= r
                });
                assert_eq!(spread.reaches(&pixels, src), near, "{w} × {h}, {src}");
            }
        }
    }
}

/// The rim of a sub-pixel light: a source beside a spike that stays
/// removed does not stand out of the spike's peak, and would be given
/// back as a halo; judged without the spike, it stands out and stays
/// removed too. Beside a spike that is given back (a field of them),
/// it is given back.
#[test]
fn a_source_beside_a_removed_spike_is_judged_without_it() {
    let (w, h, sigma) = (21, 21, 2.0);
    let mut filtered = Image::new(w, h, 1);
    filtered.data.fill([0.03; 3]);
    let occupancy = vec![1; w * h];
    let centre = 10 * w + 10;
    let mut removed = Image::new(w, h, 1);
    removed.data[centre] = [350.0; 3];
    removed.data[centre - 1] = [50.0; 3];
    let (want, spread, left, rounds) = serial(&filtered, &removed, &occupancy, sigma);
    assert_eq!((spread, left, rounds), (0, 2, 2));
    let out = energy_aware(&filtered, &removed, &occupancy, sigma);
    assert_eq!(out.data, want.data);
    assert_eq!(out.data, filtered.data);
    // The same pair inside a 5 × 5 field of equal spikes: all given back.
    for y in 8..13 {
        for x in 8..13 {
            if y * w + x != centre - 1 {
                removed.data[y * w + x] = [350.0; 3];
            }
        }
    }
    let (_, spread, left) = checked(&filtered, &removed, &occupancy, sigma);
    assert_eq!((spread, left), (25, 0));
}

/// A source among many is part of one smooth field and is spread; the
/// same source alone on the same dim background stands out and stays
/// removed.
#[test]
fn a_lone_source_stands_out_and_a_field_of_them_does_not() {
    let (w, h, sigma) = (40, 20, 2.0);
    let mut filtered = Image::new(w, h, 1);
    filtered.data.fill([0.01; 3]);
    let mut removed = Image::new(w, h, 1);
    // A 7 × 7 field of sources around (8, 10), one alone at (32, 10).
    for y in 7..14 {
        for x in 5..12 {
            removed.data[y * w + x] = [1.0; 3];
        }
    }
    removed.data[10 * w + 32] = [1.0; 3];
    let occupancy = vec![1; w * h];
    let (out, spread, left) = checked(&filtered, &removed, &occupancy, sigma);
    assert_eq!((spread, left), (49, 1));
    let given_back = |xs: std::ops::Range<usize>| -> f64 {
        (0..h)
            .flat_map(|y| xs.clone().map(move |x| y * w + x))
            .map(|p| out.data[p][0] - filtered.data[p][0])
            .sum()
    };
    assert!((given_back(0..20) - 49.0).abs() < 1e-9);
    assert_eq!(given_back(20..40), 0.0);
}

/// A streak's removed energy goes back along the streak: sources on a
/// bright column of a dark film (a glossy reflection's rejected rare
/// paths) are given back to the column and the columns beside it, not
/// spread as a haze over the film.
#[test]
fn a_streak_is_given_back_along_itself() {
    let (w, h, sigma) = (31, 31, 3.0);
    let mut filtered = Image::new(w, h, 1);
    filtered.data.fill([0.05; 3]);
    let mut removed = Image::new(w, h, 1);
    for y in 0..h {
        filtered.data[y * w + 15] = [1.0; 3];
        removed.data[y * w + 15] = [0.1; 3];
    }
    let occupancy = vec![1; w * h];
    let (out, spread, left) = checked(&filtered, &removed, &occupancy, sigma);
    assert_eq!((spread, left), (31, 0));
    let added = |p: usize| out.data[p][0] - filtered.data[p][0];
    // The streak and the columns beside it, whose 3 × 3 neighbourhoods
    // hold it.
    let streak: f64 = (0..h)
        .flat_map(|y| (14..17).map(move |x| added(y * w + x)))
        .sum();
    let all: f64 = (0..w * h).map(added).sum();
    assert!((all - 3.1).abs() < 1e-9, "{all}");
    assert!(streak > 0.99 * all, "{streak} of {all} on the streak");
}

/// A source in a lone bright pixel (noise in a dim room) would be
/// gathered by level into the few pixels around it, a peak the rule
/// never passed: it is spread by the plain Gaussian instead.
#[test]
fn a_source_few_pixels_share_the_level_of_is_spread_plain() {
    let (w, h, sigma) = (31, 31, 4.0);
    let mut filtered = Image::new(w, h, 1);
    filtered.data.fill([1.0; 3]);
    let centre = 15 * w + 15;
    filtered.data[centre] = [50.0; 3];
    let mut removed = Image::new(w, h, 1);
    removed.data[centre] = [15.0; 3];
    let occupancy = vec![1; w * h];
    let (out, spread, left) = checked(&filtered, &removed, &occupancy, sigma);
    assert_eq!((spread, left), (1, 0));
    // Three pixels away, beyond the bright pixel's 3 × 3 level, the
    // plain Gaussian's share arrives.
    let added = out.data[centre + 3][0] - filtered.data[centre + 3][0];
    let plain = 15.0 * (-9.0f64 / 32.0).exp() / (2.0 * std::f64::consts::PI * 16.0);
    assert!(
        (added - plain).abs() < 0.01 * plain,
        "{added} against {plain}"
    );
}

/// A pixel left dark among bright ones (all its samples rejected)
/// receives as its neighbours do: the level a share is weighed by is
/// the brightest of a pixel's 3 × 3 neighbourhood.
#[test]
fn a_dark_pixel_among_bright_ones_still_receives() {
    let (w, h, sigma) = (21, 21, 2.0);
    let mut filtered = Image::new(w, h, 1);
    filtered.data.fill([1.0; 3]);
    let hole = 10 * w + 10;
    filtered.data[hole] = [0.0; 3];
    let mut removed = Image::new(w, h, 1);
    for y in 6..15 {
        for x in 6..15 {
            removed.data[y * w + x] = [0.2; 3];
        }
    }
    let occupancy = vec![1; w * h];
    let (out, spread, left) = checked(&filtered, &removed, &occupancy, sigma);
    assert_eq!((spread, left), (81, 0));
    let added = |p: usize| out.data[p][0] - filtered.data[p][0];
    assert!((added(hole) - added(hole + 1)).abs() < 0.05 * added(hole + 1));
}

/// A film whose mean luminance is not positive, with pixels near the
/// largest f32 of either sign, gives finite levels and a finite
/// image.
#[test]
fn absurd_films_stay_finite() {
    let (w, h) = (9, 7);
    let mut filtered = Image::new(w, h, 1);
    let mut removed = Image::new(w, h, 1);
    for (i, (f, e)) in filtered.data.iter_mut().zip(&mut removed.data).enumerate() {
        let v = [3.4e38, -3.4e38, 1e-40, 0.5, -3.4e38][i % 5];
        *f = [v, 0.5 * v, -v];
        *e = [-v, v, 0.25 * v];
    }
    let occupancy = vec![1; w * h];
    let out = energy_aware(&filtered, &removed, &occupancy, 2.0);
    assert!(out.data.iter().flatten().all(|v| v.is_finite()));
    let (want, ..) = serial(&filtered, &removed, &occupancy, 2.0);
    assert_eq!(out.data, want.data);
}

/// The rule reads luminances relative to the film's, so a dump in
/// other units (the same film × 10⁻⁶ or × 10⁶) has the same sources
/// given back, black pixels and all.
#[test]
fn the_rule_does_not_depend_on_units() {
    let mut unit = crate::synth::test_units(7);
    let (w, h) = (30, 24);
    let mut filtered = Image::new(w, h, 1);
    let mut removed = Image::new(w, h, 1);
    for (i, (f, e)) in filtered.data.iter_mut().zip(&mut removed.data).enumerate() {
        if i % 5 != 0 {
            *f = std::array::from_fn(|_| 0.5 + unit());
        }
        if unit() < 0.2 {
            *e = std::array::from_fn(|_| 400.0 * unit() * unit());
        }
    }
    let occupancy = vec![1; w * h];
    let (base, spread, left, _) = serial(&filtered, &removed, &occupancy, 3.0);
    assert!(spread > 0 && left > 0, "{spread} spread, {left} left");
    for scale in [1e-6, 1e6] {
        let times = |i: &Image| {
            let mut i = i.clone();
            i.data.iter_mut().flatten().for_each(|v| *v *= scale);
            i
        };
        let out = energy_aware(&times(&filtered), &times(&removed), &occupancy, 3.0);
        for (a, b) in out.data.iter().flatten().zip(base.data.iter().flatten()) {
            assert!(
                (a / scale - b).abs() <= 1e-9 * b.abs().max(1.0),
                "× {scale}"
            );
        }
    }
}

#[test]
fn spreading_conserves_each_channel_and_skips_empty_pixels() {
    // A background no share stands out of, an empty pixel (4), a
    // bright source in frame 0 and a dark one in frame 1.
    let mut filtered = Image::new(7, 4, 2);
    filtered.data.fill([4.0; 3]);
    filtered.data[4] = [0.0; 3];
    let mut mean = filtered.clone();
    mean.data[3] = [10.0, 5.0, -1.0];
    mean.data[7 * 4 + 27] = [0.0, 0.0, 8.0]; // frame 1's last pixel
    let mut occupancy = vec![1u32; 56];
    occupancy[4] = 0;
    let rem = removed(&mean, &filtered);
    let out = energy_aware(&filtered, &rem, &occupancy, 1.5);
    let before = channel_sums(&mean);
    let after = channel_sums(&out);
    for c in 0..3 {
        assert!((before[c] - after[c]).abs() < 1e-12, "{before:?} {after:?}");
    }
    assert_eq!(out.data[4], [0.0; 3], "an empty pixel receives nothing");
    // Frame 0's energy stays in frame 0.
    let sum = |i: &Image| -> f64 { i.data[..28].iter().map(|p| p[0] + p[1] + p[2]).sum() };
    assert!((sum(&out) - sum(&mean)).abs() < 1e-12);
    assert!(
        out.data[3][0] < 5.0 && out.data[2][0] > 4.0,
        "the source was spread"
    );
}
