//! Which samples' exact σ a replay computes (docs/filter.md §2): none,
//! every one (`--sigma-map`), or the report's σ map's share, picked from
//! the record index alone so that they are the same for any thread count.

use super::sigma::Goal;
use crate::dump::{Header, Order};

/// The report's map asks for the exact σ of about one sample in this many:
/// each is a search that goes on past its decision, and at one in 8 they
/// added 60 % to the replay's streaming on a 1 M-sample Cycles dump
/// (docs/BENCHMARKS.md, "The σ map's share").
pub const MAP_SHARE: u32 = 32;

/// And for at most about this many in all on films up to this many
/// pixels (all frames), at least one a pixel beyond: at 8 a pixel a 1080p
/// film's added two fifths to the replay's time (docs/BENCHMARKS.md, "A
/// production frame").
pub const MAP_SEARCHES: u64 = 1 << 21;

/// Which samples' exact σ a replay computes. None of these changes a
/// decision: a search that only decides stops as soon as σ < 1 or σ ≥ 1
/// is proven, one that wants σ finds the k nearest.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ExactSigma {
    /// No σ: the fastest replay.
    #[default]
    None,
    /// Every valid sample's (`--sigma-map`).
    All,
    /// About one valid sample in n (n ≥ 2), picked by a hash of its record
    /// index, so the same ones for any order of work and thread count.
    OneIn(u32),
    /// Exactly one in n of each pixel's samples, where the dump's declared
    /// order tells which sample of which pixel a record is.
    Strata(Strata),
}

impl ExactSigma {
    /// The HTML report's σ map (docs/filter.md §2): p exact σ in each
    /// pixel where the dump's order tells which samples those are, else
    /// about max(2p, 8) (so that, picked by a hash, none misses a pixel);
    /// every σ when the dump has no more than that. p is spp /
    /// [`MAP_SHARE`], and at most [`MAP_SEARCHES`] / pixels (all frames),
    /// within 1 … 8.
    pub fn for_map(h: &Header) -> ExactSigma {
        let pixels = (h.pixels() as u64 * h.frames as u64).max(1);
        let p = (h.spp as u64 / MAP_SHARE as u64).min(MAP_SEARCHES / pixels);
        let p = p.clamp(1, 8) as u32;
        let hashed = h.spp / (2 * p).max(8);
        match Strata::new(h, h.spp / p) {
            Some(s) => ExactSigma::Strata(s),
            None if hashed >= 2 => ExactSigma::OneIn(hashed),
            None => ExactSigma::All,
        }
    }

    /// Whether any σ is computed.
    pub fn any(self) -> bool {
        self != ExactSigma::None
    }

    /// The bytes the kept σ of `records` records take
    /// ([`super::kept::Sigmas`]): exact but for `OneIn`, whose pairs are
    /// about one in n and whose vector may hold up to twice its length.
    pub fn bytes(self, records: u64) -> u64 {
        match self {
            ExactSigma::None => 0,
            ExactSigma::All => 8 * records,
            ExactSigma::OneIn(n) => 2 * 16 * (records / n.max(1) as u64),
            ExactSigma::Strata(s) => 8 * (records / s.spp * s.per_pixel()),
        }
    }

    /// One in how many samples has its σ computed (None: all or none).
    pub fn share(self) -> Option<u32> {
        match self {
            ExactSigma::OneIn(n) => Some(n),
            ExactSigma::Strata(s) => Some(s.n),
            ExactSigma::None | ExactSigma::All => None,
        }
    }

    /// Whether record `rec`'s exact σ is computed.
    #[inline]
    pub fn wants(self, rec: usize) -> bool {
        match self {
            ExactSigma::None => false,
            ExactSigma::All => true,
            ExactSigma::OneIn(n) => mix(rec as u64).is_multiple_of(n as u64),
            ExactSigma::Strata(s) => s.wants(rec as u64),
        }
    }

    /// Calls `f` on every record of `recs` whose σ is wanted, in order:
    /// the records [`ExactSigma::wants`] picks, found without testing
    /// each one where the dump's order tells which they are.
    pub fn for_each_wanted(self, recs: std::ops::Range<usize>, mut f: impl FnMut(usize)) {
        match self {
            ExactSigma::None => {}
            ExactSigma::All => recs.for_each(f),
            ExactSigma::OneIn(_) => recs.filter(|&r| self.wants(r)).for_each(f),
            ExactSigma::Strata(s) => {
                s.for_each_wanted(recs.start as u64..recs.end as u64, |r| f(r as usize))
            }
        }
    }

    /// What the search of record `rec` must establish.
    #[inline]
    pub(crate) fn goal(self, rec: usize) -> Goal {
        if self.wants(rec) {
            Goal::Exact
        } else {
            Goal::Decide
        }
    }
}

/// One in n of every pixel's samples, by their place in a pixel- or
/// pass-major dump: sample s of pixel p when (s + mix(p)) ≡ 0 (mod n), so
/// each pixel has ⌊spp / n⌋ or ⌈spp / n⌉ of them, from passes that differ
/// from pixel to pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Strata {
    n: u32,
    /// Pixels of a frame.
    pixels: u64,
    spp: u64,
    pass_major: bool,
}

impl Strata {
    /// For a dump that declares pixel- or pass-major order and holds
    /// exactly its film's samples (at least one), and n ≥ 2.
    pub fn new(h: &Header, n: u32) -> Option<Strata> {
        let pass_major = match h.order {
            Order::PixelMajor => false,
            Order::PassMajor => true,
            Order::Unspecified => return None,
        };
        let pixels = h.pixels() as u64;
        // A valid header's film and frames fit; with spp they may not.
        let film_samples = (pixels * h.frames as u64).checked_mul(h.spp as u64);
        let complete = h.sample_count > 0 && film_samples == Some(h.sample_count);
        (n >= 2 && complete).then_some(Strata {
            n,
            pixels,
            spp: h.spp as u64,
            pass_major,
        })
    }

    /// Record `rec`'s pixel (counting frames in turn) and its sample.
    #[inline]
    fn place(self, rec: u64) -> (u64, u64) {
        // Pixel-major: rec = p·spp + s (p counting frames in turn);
        // pass-major: rec = (f·spp + s)·pixels + p within frame f.
        if self.pass_major {
            let (pass, p) = (rec / self.pixels, rec % self.pixels);
            let (f, s) = (pass / self.spp, pass % self.spp);
            (f * self.pixels + p, s)
        } else {
            (rec / self.spp, rec % self.spp)
        }
    }

    #[inline]
    pub(super) fn wants(self, rec: u64) -> bool {
        let (pixel, s) = self.place(rec);
        (s + mix(pixel) % self.n as u64).is_multiple_of(self.n as u64)
    }

    /// The most samples a pixel has picked, ⌈spp / n⌉.
    fn per_pixel(self) -> u64 {
        self.spp.div_ceil(self.n as u64)
    }

    /// Slots for the picked samples of `records` records: ⌈spp / n⌉ a
    /// pixel (a pixel with ⌊spp / n⌋ leaves its last one empty).
    pub(super) fn slots(self, records: usize) -> usize {
        (records as u64 / self.spp * self.per_pixel()) as usize
    }

    /// The records behind `slots` slots ([`Strata::slots`]'s inverse).
    pub(super) fn records(self, slots: usize) -> u64 {
        slots as u64 / self.per_pixel() * self.spp
    }

    /// The slot of a picked record: its pixel's, then its rank among the
    /// pixel's picked samples, which is their order in the file.
    #[inline]
    pub(super) fn slot(self, rec: u64) -> usize {
        let (pixel, s) = self.place(rec);
        (pixel * self.per_pixel() + s / self.n as u64) as usize
    }
}

impl Strata {
    /// [`ExactSigma::for_each_wanted`]: in a pixel-major dump each pixel's
    /// picked samples are every n-th from the first, in a pass-major one
    /// each pass picks the pixels of one residue of mix(p) mod n.
    pub(super) fn for_each_wanted(self, recs: std::ops::Range<u64>, mut f: impl FnMut(u64)) {
        let n = self.n as u64;
        if recs.is_empty() {
            return;
        }
        if self.pass_major {
            // A frame's pixels by residue, made when a pass is walked over
            // most of its length (the σ map's walk over the whole dump).
            let mut residues: Option<(u64, Residues)> = None;
            for pass in recs.start / self.pixels..=(recs.end - 1) / self.pixels {
                let (frame, s) = (pass / self.spp, pass % self.spp);
                let residue = (n - s % n) % n;
                let first = pass * self.pixels;
                let (lo, hi) = (recs.start.max(first), recs.end.min(first + self.pixels));
                // A table costs about two hashes a pixel: made for a walk
                // over whole passes of a frame, not for a part of one.
                let whole = recs.end - recs.start >= 2 * self.pixels && hi - lo == self.pixels;
                if whole && n <= self.pixels && self.pixels <= u32::MAX as u64 {
                    if residues.as_ref().is_none_or(|r| r.0 != frame) {
                        residues = Some((frame, Residues::new(self, frame)));
                    }
                    let bucket = residues.as_ref().expect("just made").1.bucket(residue);
                    let from = bucket.partition_point(|&p| (p as u64) < lo - first);
                    for &p in bucket[from..]
                        .iter()
                        .take_while(|&&p| (p as u64) < hi - first)
                    {
                        f(first + p as u64);
                    }
                    continue;
                }
                for rec in lo..hi {
                    if mix(frame * self.pixels + rec - first) % n == residue {
                        f(rec);
                    }
                }
            }
        } else {
            for pixel in recs.start / self.spp..=(recs.end - 1) / self.spp {
                let first = pixel * self.spp + (n - mix(pixel) % n) % n;
                for rec in (first..(pixel + 1) * self.spp).step_by(self.n as usize) {
                    if recs.contains(&rec) {
                        f(rec);
                    }
                }
            }
        }
    }
}

/// One frame's pixels (within the frame) grouped by mix(pixel) mod n,
/// ascending within each group: a pass-major dump's pass picks one group.
struct Residues {
    /// Where each residue's pixels start in `pixels`; n + 1 entries.
    starts: Vec<usize>,
    pixels: Vec<u32>,
}

impl Residues {
    fn new(s: Strata, frame: u64) -> Residues {
        let n = s.n as usize;
        let residue = |p: u64| (mix(frame * s.pixels + p) % n as u64) as usize;
        let mut starts = vec![0usize; n + 1];
        for p in 0..s.pixels {
            starts[residue(p) + 1] += 1;
        }
        for r in 0..n {
            starts[r + 1] += starts[r];
        }
        let mut next = starts.clone();
        let mut pixels = vec![0u32; s.pixels as usize];
        for p in 0..s.pixels {
            let r = residue(p);
            pixels[next[r]] = p as u32;
            next[r] += 1;
        }
        Residues { starts, pixels }
    }

    fn bucket(&self, residue: u64) -> &[u32] {
        let r = residue as usize;
        &self.pixels[self.starts[r]..self.starts[r + 1]]
    }
}

/// SplitMix64's finaliser: consecutive indices to unrelated bits, so that
/// one in n of them is picked evenly over pixels in any dump order.
#[inline]
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58476d1ce4e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d049bb133111eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dump::Record;
    use crate::synth::SynthParams;

    /// One in n of each pixel's samples, in both declared orders and with
    /// frames, found from the record index alone; the samples picked are
    /// not the same pass in every pixel.
    #[test]
    fn strata_pick_one_in_n_of_every_pixels_samples() {
        for order in [Order::PixelMajor, Order::PassMajor] {
            let synth = SynthParams {
                width: 5,
                height: 4,
                frames: 3,
                spp: 16,
                order,
                ..SynthParams::default()
            };
            let (h, records): (Header, Vec<Record>) = (synth.header(), synth.records().collect());
            for n in [2, 3, 4, 8] {
                let share = ExactSigma::Strata(Strata::new(&h, n).unwrap());
                let mut per_pixel = vec![Vec::new(); h.pixels() * h.frames as usize];
                for (i, r) in records.iter().enumerate() {
                    if share.wants(i) {
                        let (px, s) = (r.pixel_index(&h), per_pixel[r.pixel_index(&h)].len());
                        per_pixel[px].push((i, s));
                    }
                }
                let (lo, hi) = (16 / n as usize, 16usize.div_ceil(n as usize));
                assert!(
                    per_pixel.iter().all(|v| (lo..=hi).contains(&v.len())),
                    "{order} n {n}"
                );
                let firsts: std::collections::BTreeSet<usize> = per_pixel
                    .iter()
                    .map(|v| {
                        // Which of the pixel's samples came first.
                        let first = v[0].0;
                        records[..first]
                            .iter()
                            .filter(|r| r.pixel_index(&h) == records[first].pixel_index(&h))
                            .count()
                    })
                    .collect();
                assert!(firsts.len() > 1, "{order} n {n}: the same pass everywhere");
            }
        }
    }

    /// Walking the picked records gives exactly those `wants` picks, in
    /// order, from any range, for every kind of pick.
    #[test]
    fn walking_the_picked_records_finds_what_wants_picks() {
        for order in [Order::PixelMajor, Order::PassMajor] {
            let mut h = Header::still(5, 4, 24, order);
            h.frames = 3;
            h.sample_count = 5 * 4 * 3 * 24;
            let all = h.sample_count as usize;
            let mut picks = vec![ExactSigma::None, ExactSigma::All, ExactSigma::OneIn(3)];
            picks.extend([2, 5, 8, 24].map(|n| ExactSigma::Strata(Strata::new(&h, n).unwrap())));
            for pick in picks {
                for (lo, hi) in [
                    (0, all),
                    (0, 0),
                    (7, 8),
                    (13, 700),
                    (19, 20),
                    (all - 3, all),
                ] {
                    let mut walked = Vec::new();
                    pick.for_each_wanted(lo..hi, |r| walked.push(r));
                    let want: Vec<usize> = (lo..hi).filter(|&r| pick.wants(r)).collect();
                    assert_eq!(walked, want, "{order} {pick:?} {lo}..{hi}");
                }
            }
        }
    }

    /// One exact σ in 32 samples: 2 a pixel at 64 spp, 8 at 256 spp
    /// and beyond, at least 1; fewer on a large film, so that the map's
    /// searches stay near [`MAP_SEARCHES`] (1 a pixel at 1080p, whatever
    /// its spp); without a declared order, about 8 a pixel
    /// by the hash (so that none misses a pixel).
    #[test]
    fn the_maps_share_follows_the_samples_and_the_film() {
        let share = |w: u32, h: u32, frames: u32, spp: u32, order: Order| {
            let mut hd = Header::still(w, h, spp, order);
            hd.frames = frames;
            hd.sample_count = w as u64 * h as u64 * frames as u64 * spp as u64;
            ExactSigma::for_map(&hd).share()
        };
        let pass = Order::PassMajor;
        assert_eq!(share(128, 128, 1, 64, pass), Some(32));
        assert_eq!(share(128, 128, 1, 256, pass), Some(32));
        assert_eq!(share(128, 128, 1, 1024, pass), Some(128));
        assert_eq!(share(128, 128, 1, 16, pass), Some(16));
        assert_eq!(share(128, 128, 1, 8, Order::PixelMajor), Some(8));
        assert_eq!(share(1920, 1080, 1, 64, pass), Some(64));
        assert_eq!(share(1920, 1080, 1, 256, pass), Some(256));
        assert_eq!(share(1024, 1024, 1, 256, pass), Some(128));
        assert_eq!(share(512, 512, 8, 64, Order::PixelMajor), Some(64));
        assert_eq!(share(1920, 1080, 1, 64, Order::Unspecified), Some(8));
        for (w, h, spp) in [(128, 128, 64), (1024, 1024, 256), (1920, 1080, 64)] {
            let n = share(w, h, 1, spp, pass).unwrap() as u64;
            let picks = (w * h) as u64 * spp as u64 / n;
            assert!(
                picks <= MAP_SEARCHES.max((w * h) as u64),
                "{w} × {h}: {picks}"
            );
            assert!(n >= MAP_SHARE as u64, "{w} × {h}: one in {n}");
        }
    }

    /// Without a declared order, or with samples other than the film's,
    /// the report's map falls back to about one in ⌊spp / max(2p, 8)⌋ by
    /// a hash, and to every sample where that is below 2.
    #[test]
    fn the_maps_share_needs_a_declared_complete_order() {
        let mut h = Header::still(8, 8, 64, Order::PassMajor);
        h.sample_count = 8 * 8 * 64;
        assert!(matches!(ExactSigma::for_map(&h), ExactSigma::Strata(s) if s.n == 32));
        h.sample_count -= 1;
        assert_eq!(ExactSigma::for_map(&h), ExactSigma::OneIn(8));
        h.order = Order::Unspecified;
        h.sample_count += 1;
        assert_eq!(ExactSigma::for_map(&h), ExactSigma::OneIn(8));
        h.spp = 16;
        assert_eq!(ExactSigma::for_map(&h), ExactSigma::OneIn(2));
        h.spp = 15;
        assert_eq!(ExactSigma::for_map(&h), ExactSigma::All);
        h.order = Order::PixelMajor;
        h.sample_count = 8 * 8 * 15;
        assert_eq!(ExactSigma::for_map(&h).share(), Some(15));
        h.spp = 1;
        h.sample_count = 8 * 8;
        assert_eq!(ExactSigma::for_map(&h), ExactSigma::All);
        // spp × film past u64, an empty dump: no strata, and no panic.
        let mut big = Header::still(8192, 8192, u32::MAX, Order::PassMajor);
        big.frames = 1 << 20;
        big.sample_count = 1;
        assert_eq!(Strata::new(&big, 8), None);
        assert_eq!(
            Strata::new(&Header::still(8, 8, 64, Order::PassMajor), 8),
            None
        );
    }
}
