//! The replay of SPEC §3, exact and parallel.
//!
//! Parallelism that cannot change results: T only grows, and a larger T can
//! only lower σ. A batch of consecutive samples is searched in parallel
//! against T as it stood at the batch start; then, in file order, a sample
//! found accepted stays accepted, and any other is completed with the points
//! stored earlier in the same batch (see [`NeighbourIndex::recheck`]) before
//! it is decided. The final pass searches a fixed T, so it is parallel as is.

use std::time::Instant;

use indicatif::ProgressBar;
use rayon::prelude::*;

use super::index::grid::Grid;
use super::index::kdtree::KdTree;
use super::index::{Found, IndexKind, NeighbourIndex};
use super::sigma::{Goal, KBest, Verdict, surely_below_k};
use crate::dump::{Header, InvalidCounts, Record, Validity};
use crate::joint::{JointSpace, dist2};

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

#[derive(Clone, Debug, serde::Serialize)]
pub struct FilterParams {
    pub k: usize,
    pub space: JointSpace,
    pub index: IndexKind,
    /// Compute every sample's exact σ (needed for the σ map).
    pub exact_sigma: bool,
    /// Samples per parallel batch; results do not depend on it.
    #[serde(skip)]
    pub batch: usize,
}

impl Default for FilterParams {
    fn default() -> Self {
        FilterParams {
            k: 10,
            space: JointSpace::default(),
            index: IndexKind::Grid,
            exact_sigma: false,
            batch: 16384,
        }
    }
}

#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
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

pub struct FilterResult {
    /// One [`Decision`] byte per record, in file order.
    pub decisions: Vec<u8>,
    /// With `exact_sigma`: the σ that decided each record (NaN for invalid ones).
    pub sigma: Option<Vec<f64>>,
    pub counts: FilterCounts,
    pub streaming_seconds: f64,
    pub final_seconds: f64,
}

/// Runs the filter over `records` on the current rayon pool.
pub fn run(
    records: &[Record],
    header: &Header,
    params: &FilterParams,
    progress: &ProgressBar,
) -> FilterResult {
    assert!(params.k >= 1, "k must be at least 1");
    let s = &params.space;
    let extent = [
        header.width as f64 / s.sigma_image,
        header.height as f64 / s.sigma_image,
        header.frames as f64 / s.sigma_time,
    ];
    match (header.animated(), params.index) {
        (false, IndexKind::Grid) => {
            replay::<5, _>(records, header, params, Grid::new(extent), progress)
        }
        (true, IndexKind::Grid) => {
            replay::<6, _>(records, header, params, Grid::new(extent), progress)
        }
        (false, IndexKind::Kdtree) => {
            replay::<5, _>(records, header, params, KdTree::default(), progress)
        }
        (true, IndexKind::Kdtree) => {
            replay::<6, _>(records, header, params, KdTree::default(), progress)
        }
    }
}

/// Accepted without a full search (σ < 1 proven by seeds).
const ACCEPTED: Found = Found {
    verdict: Verdict::Accept,
    bound: 0.0,
    reach: 0,
};

/// One record of a batch after the parallel search.
#[derive(Clone, Copy)]
struct Slot<const D: usize> {
    validity: Validity,
    p: [f32; D],
    found: Found,
    /// How many distances of `kbuf` belong to this slot.
    klen: usize,
}

const SUB_BLOCK: usize = 256;

/// The k nearest stored points of a worker's last full search, tried first
/// on its next sample: neighbouring samples of a dump mostly share their
/// neighbours, and k distances are far cheaper than a search. Exact: stored
/// points never leave T, and any k of them whose σ is provably below 1
/// prove the sample accepted ([`surely_below_k`]).
struct Seeds {
    ids: Vec<u32>,
}

impl Seeds {
    fn new(k: usize) -> Seeds {
        Seeds {
            ids: Vec::with_capacity(k),
        }
    }

    /// True when the seeds prove `q` accepted.
    fn accept<const D: usize, I: NeighbourIndex<D>>(
        &self,
        index: &I,
        q: &[f32; D],
        k: usize,
    ) -> bool {
        self.ids.len() == k
            && surely_below_k(self.ids.iter().map(|&id| dist2(index.point(id), q)), k)
    }

    fn remember(&mut self, kb: &KBest) {
        if kb.is_full() {
            self.ids.clear();
            self.ids.extend_from_slice(kb.ids());
        }
    }
}

fn replay<const D: usize, I: NeighbourIndex<D>>(
    records: &[Record],
    header: &Header,
    params: &FilterParams,
    mut index: I,
    progress: &ProgressBar,
) -> FilterResult {
    let k = params.k;
    let goal = if params.exact_sigma {
        Goal::Exact
    } else {
        Goal::Decide
    };
    let n = records.len();
    let mut decisions = vec![Decision::Invalid as u8; n];
    let mut sigma = params.exact_sigma.then(|| vec![f64::NAN; n]);
    let mut counts = FilterCounts {
        records: n as u64,
        ..Default::default()
    };
    // Record index of every stored point, by id.
    let mut stored_at: Vec<u64> = Vec::new();

    let t0 = Instant::now();
    let batch = params.batch.max(SUB_BLOCK);
    let placeholder = Found {
        verdict: Verdict::Reject,
        bound: 0.0,
        reach: 0,
    };
    let mut slots = vec![
        Slot {
            validity: Validity::NonFinite,
            p: [0.0; D],
            found: placeholder,
            klen: 0,
        };
        batch
    ];
    let mut kbuf = vec![0.0f64; batch * k];
    let mut kb = KBest::new(k);
    let mut scratch = I::Scratch::default();

    for start in (0..n).step_by(batch) {
        let chunk = &records[start..(start + batch).min(n)];
        let m = chunk.len();
        // Parallel: classify, map to the joint space, search T as it stands.
        let index_ref = &index;
        slots[..m]
            .par_chunks_mut(SUB_BLOCK)
            .zip(kbuf[..m * k].par_chunks_mut(SUB_BLOCK * k))
            .zip(chunk.par_chunks(SUB_BLOCK))
            .for_each(|((slots, kbuf), recs)| {
                let mut kb = KBest::new(k);
                let mut scratch = I::Scratch::default();
                let mut seeds = Seeds::new(k);
                for ((slot, kd), rec) in slots.iter_mut().zip(kbuf.chunks_mut(k)).zip(recs) {
                    slot.validity = rec.validity(header);
                    if slot.validity != Validity::Valid {
                        continue;
                    }
                    slot.p = params.space.point::<D>(rec);
                    if goal == Goal::Decide && seeds.accept(index_ref, &slot.p, k) {
                        slot.found = ACCEPTED;
                        continue;
                    }
                    slot.found = index_ref.search(&slot.p, None, goal, &mut kb, &mut scratch);
                    seeds.remember(&kb);
                    slot.klen = kb.as_slice().len();
                    kd[..slot.klen].copy_from_slice(kb.as_slice());
                }
            });
        // Sequential, in file order: complete with this batch's insertions.
        let first_new = index.len() as u32;
        for (i, slot) in slots[..m].iter().enumerate() {
            let rec = start + i;
            if slot.validity != Validity::Valid {
                counts.invalid.add(slot.validity);
                continue;
            }
            counts.valid += 1;
            let found = if index.len() == first_new as usize
                || (goal == Goal::Decide && slot.found.verdict.accepted())
            {
                slot.found
            } else {
                kb.load(&kbuf[i * k..i * k + slot.klen]);
                index.recheck(&slot.p, first_new, slot.found, goal, &mut kb, &mut scratch)
            };
            if let (Some(sig), Some(v)) = (sigma.as_mut(), found.verdict.sigma()) {
                sig[rec] = v;
            }
            if found.verdict.accepted() {
                decisions[rec] = Decision::AcceptedStreaming as u8;
                counts.accepted_streaming += 1;
            } else {
                index.insert(slot.p);
                stored_at.push(rec as u64);
                decisions[rec] = Decision::Rejected as u8;
            }
        }
        progress.inc(m as u64);
    }
    let streaming_seconds = t0.elapsed().as_secs_f64();

    // Final pass: every stored point against T without itself.
    let t1 = Instant::now();
    let finals: Vec<Verdict> = (0..index.len() as u32)
        .into_par_iter()
        .map_init(
            || (KBest::new(k), I::Scratch::default()),
            |(kb, scratch), id| {
                index
                    .search(index.point(id), Some(id), goal, kb, scratch)
                    .verdict
            },
        )
        .collect();
    for (&rec, v) in stored_at.iter().zip(&finals) {
        if let (Some(sig), Some(s)) = (sigma.as_mut(), v.sigma()) {
            sig[rec as usize] = s;
        }
        if v.accepted() {
            decisions[rec as usize] = Decision::AcceptedFinal as u8;
            counts.accepted_final += 1;
        } else {
            counts.rejected += 1;
        }
    }
    counts.stored = index.len() as u64;
    FilterResult {
        decisions,
        sigma,
        counts,
        streaming_seconds,
        final_seconds: t1.elapsed().as_secs_f64(),
    }
}
