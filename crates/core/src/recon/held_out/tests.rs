//! The halves: their folds against the whole film's, in bands and
//! around the decided pixels, and what the decision takes.

use super::*;
use crate::recon::test_header as header;

/// Every pixel's [`Halves`], the film folded as one band.
fn whole<S: Default + Clone + Send>(
    records: &[Record],
    h: &Header,
    accepted: impl Fn(usize) -> bool + Sync,
    add: impl Fn(&mut S, [f64; 3]) + Sync,
) -> Vec<Halves<S>> {
    let mut film = Vec::new();
    let keep = |_: &RowBand, folds: &[Halves<S>]| film = folds.to_vec();
    fold_halves(records, h, &[RowBand::film(h)], None, accepted, add, keep);
    film
}

/// Half `k` of every pixel's [`Halves`].
fn half_k<S: Clone>(halves: &[Halves<S>], k: usize) -> Vec<HalfFold<S>> {
    halves.iter().map(|f| f.half[k].clone()).collect()
}

/// The halves alternate within each pixel, in file order, and skip
/// what is not a valid sample; the accepted samples are those of the
/// half.
#[test]
fn halves_alternate_within_each_pixel() {
    let h = header(2, 1);
    let at = |x: f32, v: f32| Record::new(x, 0.5, 0.0, [v; 3]);
    let records = [
        at(0.5, 1.0),
        at(1.5, 10.0),
        at(0.5, 2.0),
        Record::new(f32::NAN, 0.5, 0.0, [1.0; 3]),
        at(1.5, 20.0),
        at(0.5, 4.0),
        at(1.5, 40.0),
        at(0.5, 8.0),
    ];
    let push = |v: &mut Vec<f64>, x: [f64; 3]| v.push(x[0]);
    let all_but_the_last = |i: usize| i != 7;
    let halves = whole(&records, &h, all_but_the_last, push);
    let [first, second] = [0, 1].map(|k| half_k(&halves, k));
    assert_eq!((first[0].all.n, first[0].all.mean[0]), (2, 2.5));
    assert_eq!((second[0].all.n, second[0].all.mean[0]), (2, 5.0));
    assert_eq!((first[1].all.n, second[1].all.n), (2, 1));
    assert_eq!(first[0].accepted, [1.0, 4.0]);
    assert_eq!(second[0].accepted, [2.0]);
    assert_eq!(first[1].accepted, [10.0, 40.0]);
    assert_eq!(second[1].accepted, [20.0]);
}

/// A pixel- or pass-major dump, read in place, folds its halves as a
/// scan of the same records in no declared order does.
#[test]
fn a_placed_dump_folds_its_halves_as_a_scan_does() {
    use crate::dump::Order;
    use crate::synth::SynthParams;
    for order in [Order::PassMajor, Order::PixelMajor] {
        let synth = SynthParams {
            width: 7,
            height: 5,
            frames: 2,
            spp: 6,
            order,
            ..SynthParams::default()
        };
        let (h, records): (Header, Vec<Record>) = (synth.header(), synth.records().collect());
        let scan = Header {
            order: Order::Unspecified,
            ..h.clone()
        };
        let accepted = |i: usize| !i.is_multiple_of(3);
        let push = |v: &mut Vec<f64>, x: [f64; 3]| v.push(x[0]);
        let placed = whole(&records, &h, accepted, push);
        let scanned = whole(&records, &scan, accepted, push);
        for (a, b) in placed.iter().zip(&scanned) {
            for (a, b) in a.half.iter().zip(&b.half) {
                assert_eq!((a.all.n, a.all.mean), (b.all.n, b.all.mean));
                assert_eq!(a.accepted, b.accepted);
            }
        }
        let three_each = |f: &Halves<_>| f.half.iter().all(|k| k.all.n == 3);
        assert!(placed.iter().all(|f| f.seen == 6 && three_each(f)));
    }
}

/// A half's intervals and statmc's window made band by band, each band
/// with its halo, are the whole film's, bit for bit, in either placed
/// order and across frames, with and without the renderer's features
/// (each band given its rows' share); the bands' own rows cover the
/// film once.
#[test]
fn bands_make_the_films_intervals_and_window() {
    use crate::dump::Order;
    use crate::recon::confidence::{self, Interval};
    use crate::recon::statmc::{self, Stats};
    use crate::synth::SynthParams;
    for order in [Order::PassMajor, Order::PixelMajor] {
        let synth = SynthParams {
            width: 24,
            height: 40,
            frames: 2,
            spp: 6,
            order,
            firefly_fraction: 0.05,
            light: Some((5, 12, 4, 40.0)),
            ..SynthParams::default()
        };
        let (h, records): (Header, Vec<Record>) = (synth.header(), synth.records().collect());
        let accepted = |i: usize| i % 7 != 3;
        let add = statmc::stats_adder();
        let film = half_k(&whole(&records, &h, accepted, add), 1);
        let interval = confidence::from_moments_of(&film, |f| &f.all, &h, 3.0);
        // Features of a few levels, different in each frame.
        let mut unit = crate::synth::test_units(5);
        let albedo: Vec<f32> = (0..3 * film.len())
            .map(|_| [0.3, 0.3, 0.31, 0.8][(unit() * 4.0) as usize])
            .collect();
        let guide = statmc::Guide::new(&albedo, None);
        let denoised = statmc::Window::new(&film, &h, None).denoise(&h);
        let guided = statmc::Window::new(&film, &h, Some(guide)).denoise(&h);
        assert_ne!(denoised, guided);

        // Bands of 2 rows (a budget of two rows of folds), the halos as
        // the halves' (one row for the intervals, HALO for the window),
        // and one row fewer.
        let budget = 2 * 24 * size_of::<Halves<Stats>>();
        let banded = |halo: usize, guide: Option<statmc::Guide>| {
            let bands = bands::<Stats>(&h, halo, budget);
            assert_eq!(bands.len(), 40);
            let mut own = vec![0; film.len()];
            let mut banded = Interval::empty(&h, 3.0);
            let mut banded_denoised = Image::for_header(&h);
            fold_halves(
                &records,
                &h,
                &bands,
                None,
                accepted,
                add,
                |band, folds: &[Halves<Stats>]| {
                    band.own_of(&mut own).iter_mut().for_each(|n| *n += 1);
                    let folds = half_of(folds, 1);
                    let bh = &band.header;
                    let i = confidence::from_moments_of(&folds, |f| &f.all, bh, 3.0);
                    banded.put(band, &i);
                    let out = band.own_of(&mut banded_denoised.data);
                    let g = guide.map(|g| g.of(band.pixels.clone()));
                    statmc::Window::new(&folds, bh, g).denoise_into(bh, band.own.start, out);
                },
            );
            assert!(own.iter().all(|&n| n == 1));
            (banded, banded_denoised)
        };
        let bits =
            |img: &Image| -> Vec<u64> { img.data.iter().flatten().map(|v| v.to_bits()).collect() };
        let (one_row, _) = banded(1, None);
        assert_eq!(bits(&one_row.centre), bits(&interval.centre));
        assert_eq!(bits(&one_row.half_width), bits(&interval.half_width));
        assert_eq!(bits(&one_row.own_se), bits(&interval.own_se));
        assert_eq!(one_row.count, interval.count);
        let (_, window) = banded(statmc::HALO, None);
        assert_eq!(bits(&window), bits(&denoised));
        let (_, window) = banded(statmc::HALO, Some(guide));
        assert_eq!(bits(&window), bits(&guided));
        // Each reads all its halo: one row fewer and a band's edge
        // differs.
        let (no_row, _) = banded(0, None);
        assert_ne!(bits(&no_row.half_width), bits(&interval.half_width));
        let (_, short) = banded(statmc::HALO - 1, None);
        assert_ne!(bits(&short), bits(&denoised));
    }
}

/// A half folded only around the decided pixels (within statmc's
/// [`HALO`](statmc::HALO)) gives, at those pixels, the window and the
/// intervals of the half folded whole, bit for bit, whether its bands
/// are the film, a frame or a few rows each: a run of the window longer than
/// its runs, pixels near enough to share one, scattered pixels, film
/// edges, both frames; and where a record out of its place sends the
/// bands back to the whole film. One pixel of margin less changes them.
#[test]
fn a_half_folded_around_the_decided_pixels_is_the_whole_halfs_there() {
    use crate::dump::Order;
    use crate::recon::confidence;
    use crate::recon::statmc::{self, Stats};
    use crate::synth::SynthParams;
    let synth = SynthParams {
        width: 300,
        height: 24,
        frames: 2,
        spp: 8,
        order: Order::PassMajor,
        firefly_fraction: 0.05,
        light: Some((40, 10, 4, 40.0)),
        ..SynthParams::default()
    };
    let (h, records): (Header, Vec<Record>) = (synth.header(), synth.records().collect());
    let film = h.pixels() * 2;
    let mut px: Vec<usize> = (5 * 300 + 10..5 * 300 + 290).collect();
    px.extend([0, 299, 23 * 300 + 150, 23 * 300 + 160, 23 * 300 + 192]);
    px.extend([300 * 24 + 7 * 300 + 3, film - 1]);
    px.sort();
    let decided = Decided(px);
    let accepted = |i: usize| i % 7 != 3;
    let add = statmc::stats_adder();
    let first = half_k(&whole(&records, &h, accepted, add), 0);
    let whole_film = statmc::Window::new(&first, &h, None).denoise(&h);
    let half = |records: &[Record], h: &Header, wanted: &[bool], bands: &[RowBand]| {
        let mut denoised = vec![[0.0; 3]; decided.len()];
        let mut at = decided.empty_interval(3.0);
        fold_halves(
            records,
            h,
            bands,
            Some(wanted),
            accepted,
            add,
            |band, folds: &[Halves<Stats>]| {
                let folds = half_of(folds, 0);
                decided.window_at(band, &folds, None, &mut denoised);
                let (places, pixels) = decided.in_band(band);
                let bh = &band.header;
                let all = confidence::from_moments_at(&folds, |f| &f.all, bh, 3.0, &pixels);
                at.put_at(places, &all);
            },
        );
        let bits =
            |v: &[[f64; 3]]| -> Vec<u64> { v.iter().flatten().map(|v| v.to_bits()).collect() };
        (
            bits(&denoised),
            bits(&at.centre.data),
            bits(&at.half_width.data),
            bits(&at.own_se.data),
            at.count,
        )
    };
    let film_band = [RowBand::film(&h)];
    let everything = half(&records, &h, &vec![true; film], &film_band);
    let at_decided: Vec<[f64; 3]> = decided.0.iter().map(|&px| whole_film.data[px]).collect();
    let whole_bits: Vec<u64> = at_decided.iter().flatten().map(|v| v.to_bits()).collect();
    assert_eq!(everything.0, whole_bits);
    let around = decided.around(&h, statmc::HALO);
    assert!(around.iter().filter(|&&w| w).count() < film / 2);
    for budget in [usize::MAX, 2 * 300 * size_of::<Halves<Stats>>()] {
        let bands = bands::<Stats>(&h, statmc::HALO, budget);
        assert!(bands.len() >= 2);
        assert_eq!(half(&records, &h, &around, &bands), everything);
    }
    assert_eq!(half(&records, &h, &around, &film_band), everything);
    let less = decided.around(&h, statmc::HALO - 1);
    assert_ne!(half(&records, &h, &less, &film_band).0, everything.0);
    // Pass 2's sample of pixel (150, 20) lies in row 5's decided run: the
    // bands read in place before the one that finds it are made again
    // from the whole film, as a scan of the same records makes them.
    let mut moved = records.clone();
    let r = &mut moved[2 * h.pixels() + 20 * 300 + 150];
    (r.x, r.y) = (100.5, 5.5);
    let scan = Header {
        order: Order::Unspecified,
        ..h.clone()
    };
    let bands = bands::<Stats>(&h, statmc::HALO, 2 * 300 * size_of::<Halves<Stats>>());
    let placed = half(&moved, &h, &around, &bands);
    assert_eq!(
        placed,
        half(&moved, &scan, &around, &[RowBand::film(&scan)])
    );
    assert_ne!(placed, everything);
}

/// The pixels around the decided ones are those within r each way in
/// their frame.
#[test]
fn around_stays_in_the_frame() {
    let h = Header {
        frames: 2,
        ..header(5, 4)
    };
    let around = Decided(vec![0, 20 + 19]).around(&h, 1);
    let want: Vec<usize> = vec![0, 1, 5, 6, 20 + 13, 20 + 14, 20 + 18, 20 + 19];
    let got: Vec<usize> = (0..40).filter(|&px| around[px]).collect();
    assert_eq!(got, want);
}

use crate::recon::test_pixel as one;

/// A half made from the whole film's `image` and `all`.
fn half(image: Image, all: Interval, decided: &Decided) -> Half {
    Half::new(&decided.image(&image), &decided.interval(&all))
}

fn interval(mean: f64, se: f64, n: u32) -> Interval {
    Interval {
        centre: one(mean),
        half_width: one(3.0 * se),
        count: vec![n],
        own_se: one(se),
        z: 3.0,
    }
}

/// A white pixel takes its mean where the halves' denoised images lie
/// farther from the other half's mean than that mean's noise explains
/// (a neighbour's energy spread into it), and keeps the denoiser's where
/// the two half means scatter about it (the mean is the noisy one).
/// Nothing below white, and nothing with a half of fewer than two
/// samples, is decided.
#[test]
fn white_pixels_take_the_estimate_the_other_half_prefers() {
    let decide = |g: f64, halves: [(f64, f64); 2], g_halves: f64, white: f64, n: u32| {
        let all = interval(10.0, 1.0, 2 * n);
        let mut out = one(g);
        let decided = Decided::of(&out, &all, white, Whites::Pixels);
        let a = halves.map(|(m, se)| half(one(g_halves), interval(m, se, n), &decided));
        let halves = [&a[0], &a[1]];
        prefer_mean(
            &mut out,
            &all,
            &all.count,
            halves,
            &decided,
            white,
            Whites::Pixels,
        );
        out.data[0][0]
    };
    // ((20 − 11)² + (20 − 9)²)/2 − 1 − 1 = 99 > 0: the mean.
    assert_eq!(decide(20.0, [(9.0, 1.0), (11.0, 1.0)], 20.0, 1.0, 8), 10.0);
    // (25 + 25)/2 − 25 − 25 < 0: the denoiser's.
    assert_eq!(decide(11.0, [(5.0, 5.0), (15.0, 5.0)], 10.0, 1.0, 8), 11.0);
    // Not white, or a half of one sample: as it was.
    assert_eq!(decide(20.0, [(9.0, 1.0), (11.0, 1.0)], 20.0, 15.0, 8), 20.0);
    assert_eq!(decide(20.0, [(9.0, 1.0), (11.0, 1.0)], 20.0, 1.0, 1), 20.0);
}

/// On a 2 × 1 film a pixel whose own estimate mildly prefers the
/// denoiser is outvoted by its neighbour's strong one, unless it holds
/// a rejected sample: then only its own estimate may restore it.
#[test]
fn a_neighbour_does_not_restore_a_pixel_with_a_rejected_sample() {
    let two = |v: [f64; 2]| Image {
        width: 2,
        height: 1,
        frames: 1,
        data: v.map(|v| [v; 3]).to_vec(),
    };
    let intervals = |m: [f64; 2], se: [f64; 2], n: u32| Interval {
        centre: two(m),
        half_width: two(se.map(|s| 3.0 * s)),
        count: vec![n; 2],
        own_se: two(se),
        z: 3.0,
    };
    let all = intervals([10.0, 10.0], [1.0, 1.0], 16);
    // Pixel 0: δ = ((20 − 11)² + (20 − 9)²)/2 − 2 = 99 per channel;
    // pixel 1: δ = (1 + 1)/2 − 2 = −1 per channel.
    let decided = Decided::of(&two([20.0, 12.0]), &all, 1.0, Whites::Pixels);
    let halves = [
        intervals([9.0, 9.0], [1.0, 1.0], 8),
        intervals([11.0, 11.0], [1.0, 1.0], 8),
    ]
    .map(|a| half(two([20.0, 10.0]), a, &decided));
    let decide = |accepted: [u32; 2]| {
        let mut out = two([20.0, 12.0]);
        let halves = [&halves[0], &halves[1]];
        let whites = Whites::Pixels;
        prefer_mean(&mut out, &all, &accepted, halves, &decided, 1.0, whites);
        [out.data[0][0], out.data[1][0]]
    };
    assert_eq!(decide([16, 16]), [10.0, 10.0]);
    assert_eq!(decide([16, 15]), [10.0, 12.0]);
    // Its own strong estimate restores a pixel with a rejected sample.
    assert_eq!(decide([15, 16]), [10.0, 10.0]);
}

/// Only the decided pixels of a half are kept, in their order, and
/// each is decided by its own window: on a 40 × 1 film whose pixels
/// 0, 20 and 39 are white (their windows apart), 0 and 39 take their
/// mean (δ = 99, 48) and 20 keeps the denoiser's (δ = −1); the other
/// pixels' half values, which would say the mean, are not read.
#[test]
fn a_half_is_kept_at_the_decided_pixels_alone() {
    const W: usize = 40;
    let film = |at: [f64; 3], elsewhere: f64| Image {
        width: W,
        height: 1,
        frames: 1,
        data: (0..W)
            .map(|x| match x {
                0 => [at[0]; 3],
                20 => [at[1]; 3],
                39 => [at[2]; 3],
                _ => [elsewhere; 3],
            })
            .collect(),
    };
    let intervals = |mean: f64, elsewhere: f64, n: u32| Interval {
        centre: film([mean; 3], elsewhere),
        half_width: film([3.0; 3], 3.0),
        count: vec![n; W],
        own_se: film([1.0; 3], 1.0),
        z: 3.0,
    };
    let all = intervals(10.0, 0.5, 16);
    let mut out = film([20.0, 12.0, 17.0], 0.7);
    let decided = Decided::of(&out, &all, 1.0, Whites::Pixels);
    assert_eq!(decided.0, [0, 20, 39]);
    // ((g − 11)² + (g − 9)²)/2 − 2 = (g − 10)² − 1 a channel.
    let halves = [9.0, 11.0].map(|m| {
        half(
            film([20.0, 10.0, 17.0], 50.0),
            intervals(m, 0.0, 8),
            &decided,
        )
    });
    let halves = [&halves[0], &halves[1]];
    let accepted = vec![16; W];
    prefer_mean(
        &mut out,
        &all,
        &accepted,
        halves,
        &decided,
        1.0,
        Whites::Pixels,
    );
    let reds: Vec<f64> = out.data.iter().map(|v| v[0]).collect();
    assert_eq!(
        reds,
        film([10.0, 12.0, 10.0], 0.7)
            .data
            .iter()
            .map(|v| v[0])
            .collect::<Vec<_>>()
    );
}

/// A coloured highlight white on its blue channel alone: by channels
/// the blue takes its mean and red and green keep G; by pixels
/// nothing is decided. By pixels a white pixel's channels go together,
/// on the sum of their estimates.
#[test]
fn white_channels_are_decided_alone_or_with_their_pixel() {
    let pixel = |v: [f64; 3]| Image {
        data: vec![v],
        ..one(0.0)
    };
    let interval = |centre: [f64; 3], n: u32| Interval {
        centre: pixel(centre),
        half_width: pixel([0.3; 3]),
        count: vec![n],
        own_se: pixel([0.1; 3]),
        z: 3.0,
    };
    // Each half's image lies about 10 from the other half's blue mean.
    let decide = |x: [f64; 3], halves: [[f64; 3]; 2], g: [f64; 3], whites| {
        let all = interval(x, 16);
        let mut out = pixel(g);
        let decided = Decided::of(&out, &all, 1.0, whites);
        let image = pixel([x[0], x[1], 20.0]);
        let halves = halves.map(|m| half(image.clone(), interval(m, 8), &decided));
        let halves = [&halves[0], &halves[1]];
        prefer_mean(&mut out, &all, &all.count, halves, &decided, 1.0, whites);
        out.data[0]
    };
    let coloured = [[0.4, 0.4, 9.9], [0.6, 0.6, 10.1]];
    let x = [0.5, 0.5, 10.0];
    assert_eq!(
        decide(x, coloured, [0.7, 0.7, 20.0], Whites::Channels),
        [0.7, 0.7, 10.0]
    );
    assert_eq!(
        decide(x, coloured, [0.7, 0.7, 20.0], Whites::Pixels),
        [0.7, 0.7, 20.0]
    );
    assert_eq!(
        decide(x, coloured, [0.7, 1.0, 20.0], Whites::Channels),
        [0.7, 1.0, 10.0]
    );
    // White on every channel: red's and green's estimates (−0.01 each)
    // follow the blue's (99.99) under Pixels, and keep G under Channels.
    let (x, grey) = ([10.0; 3], [[9.9; 3], [10.1; 3]]);
    let g = [10.05, 10.05, 20.0];
    assert_eq!(decide(x, grey, g, Whites::Pixels), [10.0; 3]);
    assert_eq!(decide(x, grey, g, Whites::Channels), [10.05, 10.05, 10.0]);
}

#[test]
fn window_sums_stay_in_their_frame() {
    // Two 3 × 2 frames of ones: each window counts its frame's pixels.
    let s = window_sums(&[1.0; 12], 3, 2, 1);
    assert_eq!(&s[..6], &[4.0, 6.0, 4.0, 4.0, 6.0, 4.0]);
    assert_eq!(&s[..6], &s[6..]);
    let far = window_sums(&[1.0; 12], 3, 2, 8);
    assert!(far.iter().all(|&x| x == 6.0));
}
