//! The path-density filter (docs/filter.md): a replay of the dump in file
//! order that accepts a sample when the mean distance σ to its k nearest
//! stored samples is below 1 and stores it otherwise, then a final pass
//! that accepts each stored sample whose σ against the others is below 1.
//!
//! [`plain`] is that algorithm as written, one sample at a time: the
//! specification. [`run`] is the same replay made fast and parallel, with
//! the same bytes for any thread count: `schedule` overlaps a parallel
//! search of each batch (`batch`, accelerated by `seeds`) with the
//! in-order decisions (`in_order`), balanced by `deferral`.

mod batch;
mod deferral;
pub mod evidence;
mod in_order;
pub mod index;
mod kbest;
mod kept;
pub mod plain;
mod schedule;
mod seeds;
pub mod sigma;

pub use index::IndexKind;
pub use kept::Sigmas;

use index::grid::Grid;
use index::kdtree::KdTree;

use crate::dump::{Header, InvalidCounts, Order, Record};
use crate::joint::JointSpace;
use crate::progress::Progress;
use sigma::Goal;

/// The fate of one record, as written by `--decisions` (one byte each).
#[repr(u8)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Decision {
    Invalid = 0,
    AcceptedStreaming = 1,
    AcceptedFinal = 2,
    Rejected = 3,
}

impl Decision {
    /// True for samples splatted into the filtered image.
    pub fn accepted(byte: u8) -> bool {
        byte == Decision::AcceptedStreaming as u8 || byte == Decision::AcceptedFinal as u8
    }
}

/// Which samples the final pass judges a stored sample against
/// (docs/filter.md §2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FinalPass {
    /// The other stored samples, T \ {s}: the paper's step 3.
    #[default]
    Stored,
    /// Every valid sample but s (F6a, [`evidence`]).
    All,
}

impl FinalPass {
    pub fn name(self) -> &'static str {
        match self {
            FinalPass::Stored => "stored",
            FinalPass::All => "all",
        }
    }
}

impl std::str::FromStr for FinalPass {
    type Err = String;
    fn from_str(s: &str) -> Result<FinalPass, String> {
        match s {
            "stored" => Ok(FinalPass::Stored),
            "all" => Ok(FinalPass::All),
            _ => Err(format!("unknown final pass {s:?} (stored or all)")),
        }
    }
}

impl std::fmt::Display for FinalPass {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

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
    /// The HTML report's σ map (docs/filter.md §3): 8 exact σ in each
    /// pixel where the dump's order tells which samples those are, else
    /// about 16 (so that, picked by a hash, none misses a pixel); every σ
    /// when the dump has no more than that.
    pub fn for_map(h: &Header) -> ExactSigma {
        match Strata::new(h, h.spp / 8) {
            Some(s) => ExactSigma::Strata(s),
            None if h.spp / 16 >= 2 => ExactSigma::OneIn(h.spp / 16),
            None => ExactSigma::All,
        }
    }

    /// Whether any σ is computed.
    pub fn any(self) -> bool {
        self != ExactSigma::None
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

    #[inline]
    fn wants(self, rec: u64) -> bool {
        // Pixel-major: rec = p·spp + s (p counting frames in turn);
        // pass-major: rec = (f·spp + s)·pixels + p within frame f.
        let (pixel, s) = if self.pass_major {
            let (pass, p) = (rec / self.pixels, rec % self.pixels);
            let (f, s) = (pass / self.spp, pass % self.spp);
            (f * self.pixels + p, s)
        } else {
            (rec / self.spp, rec % self.spp)
        };
        (s + mix(pixel) % self.n as u64).is_multiple_of(self.n as u64)
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

/// How the replay runs. None of these change a decision.
#[derive(Clone, Debug)]
pub struct ReplayOptions {
    /// Which samples' exact σ to compute (for the σ map).
    pub exact_sigma: ExactSigma,
    /// Samples per parallel batch.
    pub batch: usize,
    /// The share of searches left to the in-order pass (see `deferral::Deferral`);
    /// `None` adapts it to balance the threads.
    pub deferral: Option<f64>,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        ReplayOptions {
            exact_sigma: ExactSigma::None,
            batch: 4096,
            deferral: None,
        }
    }
}

/// The filter's parameters and how to run it, as the replay uses them.
struct Params<'a> {
    k: usize,
    space: &'a JointSpace,
    exact_sigma: ExactSigma,
    batch: usize,
    deferral: Option<f64>,
}

#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct FilterCounts {
    pub records: u64,
    pub valid: u64,
    pub invalid: InvalidCounts,
    pub accepted_streaming: u64,
    pub accepted_final: u64,
    pub rejected: u64,
    /// |T| at the end of the replay.
    pub stored: u64,
}

#[derive(Clone)]
pub struct FilterResult {
    /// One [`Decision`] byte per record, in file order.
    pub decisions: Vec<u8>,
    /// With `exact_sigma`: the σ that decided each record it asks for.
    pub sigma: Option<Sigmas>,
    pub counts: FilterCounts,
    pub streaming_seconds: f64,
    pub final_seconds: f64,
}

/// Runs the filter (k nearest neighbours in the joint space `space`) over
/// `records` on the current rayon pool.
pub fn run(
    records: &[Record],
    header: &Header,
    space: &JointSpace,
    k: usize,
    index: IndexKind,
    options: &ReplayOptions,
    progress: &dyn Progress,
) -> FilterResult {
    assert!(k >= 1, "k must be at least 1");
    let params = &Params {
        k,
        space,
        exact_sigma: options.exact_sigma,
        batch: options.batch,
        deferral: options.deferral,
    };
    let extent = space.extent(header);
    match (header.animated(), index) {
        (false, IndexKind::Grid) => {
            schedule::replay::<5, _>(records, header, params, || Grid::new(extent), progress)
        }
        (true, IndexKind::Grid) => {
            schedule::replay::<6, _>(records, header, params, || Grid::new(extent), progress)
        }
        (false, IndexKind::Kdtree) => {
            schedule::replay::<5, _>(records, header, params, KdTree::default, progress)
        }
        (true, IndexKind::Kdtree) => {
            schedule::replay::<6, _>(records, header, params, KdTree::default, progress)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
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

    /// Without a declared order, or with samples other than the film's,
    /// the report's map falls back to about one in ⌊spp / 16⌋ by a hash.
    #[test]
    fn the_maps_share_needs_a_declared_complete_order() {
        let mut h = Header::still(8, 8, 64, Order::PassMajor);
        h.sample_count = 8 * 8 * 64;
        assert!(matches!(ExactSigma::for_map(&h), ExactSigma::Strata(s) if s.n == 8));
        h.sample_count -= 1;
        assert_eq!(ExactSigma::for_map(&h), ExactSigma::OneIn(4));
        h.order = Order::Unspecified;
        h.sample_count += 1;
        assert_eq!(ExactSigma::for_map(&h), ExactSigma::OneIn(4));
        h.spp = 16;
        assert_eq!(ExactSigma::for_map(&h), ExactSigma::All);
        h.order = Order::PixelMajor;
        h.sample_count = 8 * 8 * 16;
        assert_eq!(ExactSigma::for_map(&h).share(), Some(2));
        h.spp = 15;
        h.sample_count = 8 * 8 * 15;
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
