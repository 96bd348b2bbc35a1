//! The replay of SPEC §3, exact and parallel.
//!
//! Parallelism that cannot change results: T only grows, and a larger T can
//! only lower σ. A batch of consecutive samples is searched in parallel
//! against an earlier state of T; then, in file order, a sample found
//! accepted stays accepted, and any other is completed with the points
//! stored since that state (see [`NeighbourIndex::recheck`]) before it is
//! decided. The in-order pass over batch b overlaps the search of batch
//! b + 1, which therefore reads a copy of T one batch behind, and the
//! preparation of batch b + 2 (classification and joint-space points,
//! which need no T; a batch is sorted into its search order when its
//! search starts). Searches
//! likely to fail against that copy may be left to the in-order pass
//! ([`Deferral`]), which searches the current T instead. The final pass
//! searches a fixed T, so it is parallel as is.

use std::sync::atomic::Ordering::{Acquire, Relaxed, Release};
use std::sync::atomic::{AtomicBool, AtomicU32};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use rayon::prelude::*;

use super::index::grid::Grid;
use super::index::kdtree::KdTree;
use super::index::{Found, IndexKind, NeighbourIndex};
use super::sigma::{Goal, KBest, Sum, Verdict, classify};
use crate::dump::{Header, InvalidCounts, Record, Validity};
use crate::joint::{JointSpace, dist2};
use crate::progress::Progress;

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

/// How the replay runs. None of these change a decision.
#[derive(Clone, Debug)]
pub struct ReplayOptions {
    /// Compute every sample's exact σ (needed for the σ map).
    pub exact_sigma: bool,
    /// Samples per parallel batch.
    pub batch: usize,
    /// The share of searches left to the in-order pass (see [`Deferral`]);
    /// `None` adapts it to balance the threads.
    pub deferral: Option<f64>,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        ReplayOptions {
            exact_sigma: false,
            batch: 4096,
            deferral: None,
        }
    }
}

/// The filter's parameters and how to run it, as the replay uses them.
struct Params<'a> {
    k: usize,
    space: &'a JointSpace,
    exact_sigma: bool,
    batch: usize,
    deferral: Option<f64>,
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
    let s = space;
    let extent = [
        header.width as f64 / s.sigma_image,
        header.height as f64 / s.sigma_image,
        header.frames as f64 / s.sigma_time,
    ];
    match (header.animated(), index) {
        (false, IndexKind::Grid) => {
            replay::<5, _>(records, header, params, || Grid::new(extent), progress)
        }
        (true, IndexKind::Grid) => {
            replay::<6, _>(records, header, params, || Grid::new(extent), progress)
        }
        (false, IndexKind::Kdtree) => {
            replay::<5, _>(records, header, params, KdTree::default, progress)
        }
        (true, IndexKind::Kdtree) => {
            replay::<6, _>(records, header, params, KdTree::default, progress)
        }
    }
}

/// Accepted without a full search (σ < 1 proven by seeds).
const ACCEPTED: Found = Found {
    verdict: Verdict::Accept,
    bound: 0.0,
    reach: 0,
};

/// One record of a batch mapped to the joint space; meaningful only where
/// the batch's `validity` says the record is valid.
#[derive(Clone, Copy)]
struct Slot<const D: usize> {
    /// The index's locality key of `p`.
    key: u32,
    /// The key its seeds are cached under ([`SeedKeys`]).
    seed_key: u32,
    p: [f32; D],
}

/// The parallel search of one valid record.
#[derive(Clone, Copy)]
struct Hit {
    found: Found,
    /// How many distances of `kbuf` belong to this hit.
    klen: usize,
    /// Whether they are in ascending order.
    sorted: bool,
    /// Not searched: the in-order pass searches the current T instead.
    deferred: bool,
}

/// Records per job of the preparation, and the smallest batch.
const SUB_BLOCK: usize = 256;

/// Records per job of the parallel search: small, because the last job of
/// a batch is waited for (pass-major, k = 50: 256 records took 66 µs on
/// average, and jobs of 64 cut the threads' idle time from ~9% to ~6%).
const SEARCH_BLOCK: usize = 64;

/// Deferred searches in a row before a worker searches again to refresh
/// its seeds (see [`Deferral`]).
const REFRESH: u32 = 16;

/// The k nearest stored points of a worker's last full search, tried first
/// on its next sample: neighbouring samples of a dump mostly share their
/// neighbours, and k distances are far cheaper than a search. Exact: stored
/// points never leave T, and any k of them whose σ is provably below 1
/// prove the sample accepted ([`classify`]).
struct Seeds {
    /// The locality key of the sample they were found for.
    key: u32,
    /// Whether that sample's search failed to accept it (the lagging T
    /// lacked the points its recheck then supplies).
    failed: bool,
    /// Searches deferred since they were found.
    deferred: u32,
    /// The cache key of the sample they were found or fetched for.
    seed_key: u32,
    /// Whether the cache holds `ids` under `seed_key` already (they were
    /// fetched from it and not replaced since), so filing them is moot.
    filed: bool,
    ids: Vec<u32>,
    /// Their squared distances to the current query.
    d2: Vec<f64>,
    /// The seeds last found under each key, so that a worker coming back
    /// to a pixel or cell starts from them rather than from the last one's.
    /// The parallel workers share one (the lagging T's ids); the in-order
    /// pass has its own (ids of the current T, not all in the lagging one).
    cache: Arc<SeedCache>,
}

/// What seeds are cached by: the pixel when the cache can hold every
/// pixel's, else the grid cell. A pass-major dump brings a worker back to a
/// pixel once per pass, a batch holding one sample of it, and seeds found
/// for the pixel's previous sample prove far more than a neighbour's (at
/// k = 50 on the benchmark dump, 1.8× faster than seeds by cell).
#[derive(Clone, Copy, Debug, PartialEq)]
struct SeedKeys {
    by_pixel: bool,
    slots: usize,
}

impl SeedKeys {
    /// At most 2^22 ids (16 MB) per worker by pixel; by cell, at most 16384
    /// slots and 2^20 ids.
    fn new(header: &Header, k: usize) -> SeedKeys {
        let pixels = header.pixels().saturating_mul(header.frames as usize);
        if pixels.saturating_mul(k) <= 1 << 22 {
            SeedKeys {
                by_pixel: true,
                slots: pixels.max(1),
            }
        } else {
            SeedKeys {
                by_pixel: false,
                slots: ((1usize << 20) / k).clamp(1, 1 << 14),
            }
        }
    }
}

/// Seeds by key ([`SeedKeys`]), direct-mapped, shared by threads. Slots
/// are read and written without locks: a slot read while another thread
/// writes it may mix two searches' ids, which is harmless, since any ids
/// of stored points are valid seeds (exactness never rests on them). With
/// relaxed ordering a reader may even see a key before its ids: it then
/// reads the initial zeros, id 0, which exists once anything is cached.
struct SeedCache {
    k: usize,
    /// The key each slot holds (`u32::MAX`: none).
    keys: Vec<AtomicU32>,
    /// k ids per slot.
    ids: Vec<AtomicU32>,
}

impl SeedCache {
    fn new(k: usize, slots: usize) -> SeedCache {
        SeedCache {
            k,
            keys: (0..slots).map(|_| AtomicU32::new(u32::MAX)).collect(),
            ids: (0..slots * k).map(|_| AtomicU32::new(0)).collect(),
        }
    }

    fn slot(&self, key: u32) -> usize {
        key as usize % self.keys.len()
    }

    fn store(&self, key: u32, ids: &[u32]) {
        let s = self.slot(key);
        for (a, &id) in self.ids[s * self.k..(s + 1) * self.k].iter().zip(ids) {
            a.store(id, Relaxed);
        }
        self.keys[s].store(key, Relaxed);
    }

    /// Copies the seeds of `key` into `ids`, if the cache has them, and
    /// says whether it had.
    fn load(&self, key: u32, ids: &mut [u32]) -> bool {
        let s = self.slot(key);
        let hit = self.keys[s].load(Relaxed) == key;
        if hit {
            for (id, a) in ids.iter_mut().zip(&self.ids[s * self.k..(s + 1) * self.k]) {
                *id = a.load(Relaxed);
            }
        }
        hit
    }
}

impl Seeds {
    fn new(k: usize, cache: Arc<SeedCache>) -> Seeds {
        Seeds {
            key: u32::MAX,
            failed: false,
            deferred: 0,
            seed_key: u32::MAX,
            filed: false,
            ids: Vec::with_capacity(k),
            d2: Vec::with_capacity(k),
            cache,
        }
    }

    /// Before a sample of cell `key` whose seeds are cached under
    /// `seed_key`: on a change of that key, files the seeds away and takes
    /// the key's own, if it has any (else keeps the last, which may still
    /// serve). A new cell clears the failure (a deferral waits for a
    /// failure against this batch's T).
    fn visit(&mut self, key: u32, seed_key: u32) {
        let k = self.cache.k;
        if seed_key == self.seed_key || self.ids.len() != k {
            return;
        }
        if self.seed_key != u32::MAX && !self.filed {
            self.cache.store(self.seed_key, &self.ids);
        }
        self.filed = self.cache.load(seed_key, &mut self.ids);
        self.seed_key = seed_key;
        if key != self.key {
            self.key = key;
            self.failed = false;
            self.deferred = 0;
        }
    }

    /// True when the seeds prove `q` accepted.
    fn accept<const D: usize, I: NeighbourIndex<D>>(
        &mut self,
        index: &I,
        q: &[f32; D],
        k: usize,
    ) -> bool {
        if self.ids.len() != k {
            return false;
        }
        self.d2.clear();
        self.d2
            .extend(self.ids.iter().map(|&id| dist2(index.point(id), q)));
        classify(&self.d2, k) == Sum::BelowK
    }

    fn remember(&mut self, kb: &KBest, key: u32, seed_key: u32, found: &Found) {
        if kb.is_full() {
            self.key = key;
            self.seed_key = seed_key;
            self.failed = !found.verdict.accepted();
            self.deferred = 0;
            self.filed = false;
            self.ids.clear();
            self.ids.extend_from_slice(kb.ids());
        }
    }
}

/// One batch's records after the parallel search.
struct Batch<const D: usize> {
    /// In file order; the first `len` are prepared. A slot holds a point
    /// only where `validity` says the record is valid.
    slots: Vec<Slot<D>>,
    validity: Vec<Validity>,
    len: usize,
    /// (locality key << 32 | position in the batch), sorted: the order the
    /// records are searched in, so that neighbours share a worker's caches
    /// whatever the order of the dump.
    order: Vec<u64>,
    /// Search results in `order`'s order, and the k nearest squared
    /// distances each found (`k` per hit).
    hits: Vec<Hit>,
    /// In `order`'s order: accepted by the search for good (while deciding,
    /// not deferred). The in-order pass reads this byte rather than the
    /// record's slot and hit: those were written on another core and most
    /// records need nothing else.
    accepted: Vec<bool>,
    kbuf: Vec<f64>,
    /// Position in `hits` of each record of the batch.
    pos: Vec<u32>,
    /// |T| when the batch was searched: points with larger ids are new to it.
    base: u32,
}

impl<const D: usize> Batch<D> {
    fn new(len: usize, k: usize) -> Batch<D> {
        let slot = Slot {
            key: 0,
            seed_key: 0,
            p: [0.0; D],
        };
        let hit = Hit {
            found: ACCEPTED,
            klen: 0,
            sorted: true,
            deferred: false,
        };
        Batch {
            slots: vec![slot; len],
            validity: vec![Validity::NonFinite; len],
            len: 0,
            order: Vec::with_capacity(len),
            hits: vec![hit; len],
            accepted: vec![false; len],
            kbuf: vec![0.0; len * k],
            pos: vec![0; len],
            base: 0,
        }
    }

    /// Classifies `recs`, maps them to the joint space and computes
    /// `index`'s locality key of each, in parallel. Needs no stored point,
    /// so it runs a batch ahead, beside the in-order pass.
    fn prepare<I: NeighbourIndex<D>>(
        &mut self,
        recs: &[Record],
        index: &I,
        header: &Header,
        space: &JointSpace,
        seed_keys: SeedKeys,
    ) {
        let m = recs.len();
        self.slots[..m]
            .par_chunks_mut(SUB_BLOCK)
            .zip(self.validity[..m].par_chunks_mut(SUB_BLOCK))
            .zip(recs.par_chunks(SUB_BLOCK))
            .for_each(|((slots, validity), recs)| {
                for ((slot, v), rec) in slots.iter_mut().zip(validity).zip(recs) {
                    *v = rec.validity(header);
                    if *v == Validity::Valid {
                        slot.p = space.point::<D>(rec);
                        slot.key = index.locality(&slot.p);
                        slot.seed_key = if seed_keys.by_pixel {
                            // Fits: pixels × k ≤ 2^22.
                            rec.pixel_index(header) as u32
                        } else {
                            slot.key
                        };
                    }
                }
            });
        self.len = m;
    }

    /// Serial: sorts the prepared records by locality key, the order they
    /// are searched in. Done at the start of the search rather than at the
    /// end of the preparation, so that no thread waits on it.
    fn order_by_locality(&mut self) {
        self.order.clear();
        self.order.extend(
            self.slots[..self.len]
                .iter()
                .zip(&self.validity)
                .zip(0u64..)
                .filter(|((_, v), _)| **v == Validity::Valid)
                .map(|((slot, _), i)| (slot.key as u64) << 32 | i),
        );
        self.order.sort_unstable();
        for (j, &key) in self.order.iter().enumerate() {
            self.pos[(key & u32::MAX as u64) as usize] = j as u32;
        }
    }

    /// Parallel: searches the prepared records against `index` as it
    /// stands, in locality order.
    fn search<I: NeighbourIndex<D>>(
        &mut self,
        index: &I,
        k: usize,
        goal: Goal,
        defer: f64,
        workers: &[Mutex<Worker<I::Scratch>>],
    ) {
        self.order_by_locality();
        self.base = index.len() as u32;
        let (slots, valid) = (&self.slots, self.order.len());
        self.hits[..valid]
            .par_chunks_mut(SEARCH_BLOCK)
            .zip(self.accepted[..valid].par_chunks_mut(SEARCH_BLOCK))
            .zip(self.kbuf[..valid * k].par_chunks_mut(SEARCH_BLOCK * k))
            .zip(self.order.par_chunks(SEARCH_BLOCK))
            .for_each(|(((hits, accepted), kbuf), order)| {
                // Each thread keeps its state from job to job and batch
                // to batch (buffers, the tile's block, the seeds): the
                // lock is only ever taken by the thread it belongs to.
                let slot = rayon::current_thread_index().unwrap_or(0) % workers.len();
                let mut guard = workers[slot].lock().unwrap_or_else(|e| e.into_inner());
                let Worker {
                    kb,
                    scratch,
                    seeds,
                    share,
                } = &mut *guard;
                for ((hit, kd), &key) in hits.iter_mut().zip(kbuf.chunks_mut(k)).zip(order) {
                    let Slot { p, seed_key, .. } = &slots[(key & u32::MAX as u64) as usize];
                    let cell = (key >> 32) as u32;
                    hit.deferred = false;
                    seeds.visit(cell, *seed_key);
                    if goal == Goal::Decide && seeds.accept(index, p, k) {
                        hit.found = ACCEPTED;
                        continue;
                    }
                    // Defer a share of the searches that would likely
                    // fail like the last one in this cell did (and so
                    // need a recheck), but search the first sample of
                    // each cell, whose neighbours seed the next ones,
                    // and now and then refresh the seeds.
                    if seeds.key == cell && seeds.failed && seeds.deferred < REFRESH {
                        *share += defer;
                        if *share >= 1.0 {
                            *share -= 1.0;
                            seeds.deferred += 1;
                            hit.deferred = true;
                            continue;
                        }
                    }
                    hit.found = index.search(p, None, goal, kb, scratch);
                    seeds.remember(kb, cell, *seed_key, &hit.found);
                    hit.klen = kb.as_slice().len();
                    hit.sorted = kb.is_sorted();
                    kd[..hit.klen].copy_from_slice(kb.as_slice());
                }
                for (a, hit) in accepted.iter_mut().zip(&*hits) {
                    *a = goal == Goal::Decide && !hit.deferred && hit.found.verdict.accepted();
                }
            });
    }
}

/// One thread's working state for the parallel search.
struct Worker<S> {
    kb: KBest,
    scratch: S,
    seeds: Seeds,
    /// Accumulated share of deferrable searches (see [`Deferral`]).
    share: f64,
}

impl<S: Default> Worker<S> {
    fn new(k: usize, cache: Arc<SeedCache>) -> Worker<S> {
        Worker {
            kb: KBest::new(k),
            scratch: S::default(),
            seeds: Seeds::new(k, cache),
            share: 0.0,
        }
    }

    /// One per thread of the current rayon pool, sharing one seed cache.
    fn per_thread(k: usize, slots: usize) -> Vec<Mutex<Worker<S>>> {
        let cache = Arc::new(SeedCache::new(k, slots));
        (0..rayon::current_num_threads())
            .map(|_| Mutex::new(Worker::new(k, cache.clone())))
            .collect()
    }
}

/// How many searches the in-order pass takes over from the parallel one.
///
/// A sample searched in parallel against the lagging T mostly needs a
/// recheck in order as well (at k = 50 on the benchmark dump, 2.4 M of
/// 4.2 M do). Searching it in order instead, against the current T, costs
/// the in-order pass a little more than the recheck would but saves the
/// parallel search altogether. With one thread that is pure gain; with
/// more, the in-order pass must not become the bottleneck, so the share
/// follows the timings: up while the in-order pass finishes first, down
/// while it is the one waited for and has deferred searches to hand back.
/// Only the timings depend on the share.
struct Deferral {
    share: f64,
    fixed: bool,
}

impl Deferral {
    fn new(fixed: Option<f64>) -> Deferral {
        match fixed {
            Some(s) => Deferral {
                share: s.clamp(0.0, 1.0),
                fixed: true,
            },
            None if rayon::current_num_threads() == 1 => Deferral {
                share: 1.0,
                fixed: true,
            },
            None => Deferral {
                share: 0.5,
                fixed: false,
            },
        }
    }

    /// Adjusts the share after a batch whose in-order pass took
    /// `in_order` seconds and ran `deferred` deferred searches while the
    /// search of the next batch took `search`. An in-order pass that is
    /// slower without running any deferred search (the first samples of a
    /// region, checked against a T that grows under them) has nothing to
    /// hand back: lowering the share then would only cost the parallel
    /// searches their deferrals once the pass is fast again.
    fn update(&mut self, in_order: f64, search: f64, deferred: usize) {
        const STEP: f64 = 1.0 / 32.0;
        if !self.fixed {
            let step = if in_order < search {
                STEP
            } else if deferred > 0 {
                -STEP
            } else {
                0.0
            };
            self.share = (self.share + step).clamp(0.0, 1.0);
        }
    }
}

/// Waits for `flag` without parking the thread: runs pending pool jobs,
/// else yields the core. Both sides of a batch wait this way for each
/// other, so neither is parked at the batch's end. rayon parks a thread
/// after ~32 idle rounds; on the benchmark machine (a 2-core VM) the
/// search of a batch then started 0.8 µs late at the median but 43 µs at
/// the 90th percentile and 0.8 ms at the 99th, 42 ms of a 0.68 s replay
/// (pixel-major, k = 10, 2 threads).
fn wait_for(flag: &AtomicBool) {
    while !flag.load(Acquire) {
        if rayon::yield_now() != Some(rayon::Yield::Executed) {
            std::thread::yield_now();
        }
    }
}

/// The streaming pass's results, filled in file order.
struct Streaming<'a> {
    decisions: &'a mut [u8],
    sigma: Option<&'a mut [f64]>,
    counts: &'a mut FilterCounts,
    /// Record index of every stored point, by id.
    stored_at: &'a mut Vec<u64>,
}

/// Sequential, in file order: completes each search of `batch` (records from
/// `start`) with the points stored since it ran, then decides and stores.
/// Before a search or a recheck it tries the k nearest of its last search,
/// as the parallel workers do: consecutive samples mostly share neighbours.
/// Returns how many deferred searches it ran.
#[allow(clippy::too_many_arguments)]
fn decide_in_order<const D: usize, I: NeighbourIndex<D>>(
    batch: &Batch<D>,
    start: usize,
    m: usize,
    index: &mut I,
    goal: Goal,
    worker: &mut Worker<I::Scratch>,
    out: &mut Streaming,
) -> usize {
    let Worker {
        kb, scratch, seeds, ..
    } = worker;
    let k = kb.k();
    let mut deferred = 0;
    for (i, &validity) in batch.validity[..m].iter().enumerate() {
        let rec = start + i;
        if validity != Validity::Valid {
            out.counts.invalid.add(validity);
            continue;
        }
        out.counts.valid += 1;
        let j = batch.pos[i] as usize;
        if batch.accepted[j] {
            out.decisions[rec] = Decision::AcceptedStreaming as u8;
            out.counts.accepted_streaming += 1;
            continue;
        }
        // Not accepted by the search: its verdict stands only if nothing
        // was stored since.
        let (slot, hit) = (&batch.slots[i], &batch.hits[j]);
        let settled = !hit.deferred && index.len() == batch.base as usize;
        if !settled {
            // Only the samples that need them visit the seeds: in a
            // pass-major dump every sample is a new pixel, and filing and
            // fetching seeds for the many the parallel search settled
            // took a third of the in-order pass (k = 10).
            seeds.visit(slot.key, slot.seed_key);
        }
        let found = if settled {
            hit.found
        } else if goal == Goal::Decide && seeds.accept(&*index, &slot.p, k) {
            ACCEPTED
        } else if hit.deferred {
            deferred += 1;
            let found = index.search(&slot.p, None, goal, kb, scratch);
            seeds.remember(kb, slot.key, slot.seed_key, &found);
            found
        } else {
            kb.load(&batch.kbuf[j * k..j * k + hit.klen], hit.sorted);
            index.recheck(&slot.p, batch.base, hit.found, goal, kb, scratch)
        };
        if let (Some(sig), Some(v)) = (out.sigma.as_mut(), found.verdict.sigma()) {
            sig[rec] = v;
        }
        if found.verdict.accepted() {
            out.decisions[rec] = Decision::AcceptedStreaming as u8;
            out.counts.accepted_streaming += 1;
        } else {
            index.insert(slot.p);
            out.stored_at.push(rec as u64);
            out.decisions[rec] = Decision::Rejected as u8;
        }
    }
    deferred
}

fn replay<const D: usize, I: NeighbourIndex<D>>(
    records: &[Record],
    header: &Header,
    params: &Params,
    make_index: impl Fn() -> I,
    progress: &dyn Progress,
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
    let mut stored_at: Vec<u64> = Vec::new();

    let t0 = Instant::now();
    let batch = params.batch.max(SUB_BLOCK);
    // Two copies of T: `index` is current; `lagging` trails it by one batch.
    // While one worker decides batch b in order (inserting into `index`)
    // and then prepares batch b + 2, the others search batch b + 1 against
    // `lagging` (each side helps the other when done); the rechecks then
    // offer everything stored since, so the lag changes no result. The
    // serial steps (the in-order pass, the sort of a batch's search order)
    // thus overlap parallel work.
    let mut index = make_index();
    let mut lagging = make_index();
    // This batch (decided in order), the next (searched), the one after
    // (prepared); rotated after each batch.
    let mut batches: [Batch<D>; 3] = std::array::from_fn(|_| Batch::new(batch, k));
    let seed_keys = SeedKeys::new(header, k);
    let mut in_order_worker = Worker::new(k, Arc::new(SeedCache::new(k, seed_keys.slots)));
    let range = |start: usize| start..(start + batch).min(n);
    let mut deferral = Deferral::new(params.deferral);
    let workers = Worker::<I::Scratch>::per_thread(k, seed_keys.slots);
    for (j, start) in (0..n).step_by(batch).take(2).enumerate() {
        batches[j].prepare(
            &records[range(start)],
            &lagging,
            header,
            params.space,
            seed_keys,
        );
    }
    if n > 0 {
        // Nothing is stored yet: the first batch is decided in order
        // whatever its search finds.
        batches[0].search(&lagging, k, goal, 0.0, &workers);
    }
    for start in (0..n).step_by(batch) {
        let m = range(start).len();
        let [cur, next, after] = &mut batches;
        let mut out = Streaming {
            decisions: &mut decisions,
            sigma: sigma.as_deref_mut(),
            counts: &mut counts,
            stored_at: &mut stored_at,
        };
        let (lagging_ref, workers) = (&lagging, &workers);
        let share = deferral.share;
        // Set when this batch's in-order pass and the preparation after it
        // are done, and when the next batch's search is.
        let (decided, searched) = (&AtomicBool::new(false), &AtomicBool::new(false));
        // The search job is pushed first, so it is the one an idle thread
        // steals; the preparation waits on this thread's own queue, taken
        // by whichever thread runs out of work first. The thread that owns
        // the join thus mostly finishes last, and nobody sleeps on a latch.
        // Each side then waits for the other ([`wait_for`]), helping with
        // what is left, so the searching thread is awake for the next batch.
        let ((in_order, deferred), search) = rayon::join(
            || {
                let in_order = rayon::join(
                    || {
                        let t = Instant::now();
                        let deferred = decide_in_order(
                            cur,
                            start,
                            m,
                            &mut index,
                            goal,
                            &mut in_order_worker,
                            &mut out,
                        );
                        (t.elapsed().as_secs_f64(), deferred)
                    },
                    || {
                        if start + 2 * batch < n {
                            let recs = &records[range(start + 2 * batch)];
                            after.prepare(recs, lagging_ref, header, params.space, seed_keys);
                        }
                    },
                )
                .0;
                decided.store(true, Release);
                wait_for(searched);
                in_order
            },
            || {
                let t = Instant::now();
                if start + batch < n {
                    next.search(lagging_ref, k, goal, share, workers);
                }
                let search = t.elapsed().as_secs_f64();
                searched.store(true, Release);
                wait_for(decided);
                search
            },
        );
        deferral.update(in_order, search, deferred);
        for id in lagging.len()..index.len() {
            lagging.insert(*index.point(id as u32));
        }
        batches.rotate_left(1);
        progress.inc(m as u64);
    }
    drop(lagging);
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

#[cfg(test)]
mod tests {
    use super::{ACCEPTED, Deferral, KBest, SeedCache, SeedKeys, Seeds};
    use std::sync::Arc;

    /// A worker coming back to a key gets that key's seeds back, not the
    /// last key's; a key without any keeps the last; a new cell clears
    /// the failure (it was against an older T), a new pixel of the same
    /// cell does not.
    #[test]
    fn seeds_follow_the_worker_back_to_each_key() {
        let mut s = Seeds::new(2, Arc::new(SeedCache::new(2, 16)));
        // As `remember` leaves them after a failed search in cell 7.
        s.key = 7;
        s.seed_key = 7;
        s.ids.extend([1, 2]);
        s.failed = true;
        s.visit(8, 8);
        assert_eq!((s.key, &s.ids[..], s.failed), (8, &[1, 2][..], false));
        s.ids.copy_from_slice(&[3, 4]);
        s.visit(7, 7);
        assert_eq!(&s.ids[..], &[1, 2]);
        s.visit(8, 8);
        assert_eq!(&s.ids[..], &[3, 4]);
        // A key mapping to 7's slot evicts it.
        s.visit(7 + 16, 7 + 16);
        s.ids.copy_from_slice(&[5, 6]);
        s.visit(7, 7);
        assert_eq!(&s.ids[..], &[5, 6], "evicted: the last seeds stay");
        // By pixel: pixels 3 and 4 of one cell 9.
        s.visit(9, 3);
        s.ids.copy_from_slice(&[8, 9]);
        s.failed = true;
        s.visit(9, 4);
        assert!(s.failed, "same cell: the failure stands");
        s.ids.copy_from_slice(&[10, 11]);
        s.visit(9, 3);
        assert_eq!(&s.ids[..], &[8, 9]);
    }

    /// Seeds fetched from the shared cache and not replaced are not filed
    /// back: the write would be redundant, and would undo another worker's
    /// newer seeds for the same key.
    #[test]
    fn seeds_only_read_are_not_filed_back() {
        let cache = Arc::new(SeedCache::new(2, 16));
        let (mut a, mut b) = (Seeds::new(2, cache.clone()), Seeds::new(2, cache.clone()));
        a.key = 7;
        a.seed_key = 7;
        a.ids.extend([1, 2]);
        a.visit(8, 8); // files [1, 2] under 7
        b.ids.extend([0, 0]);
        b.visit(7, 7);
        assert_eq!(&b.ids[..], &[1, 2]);
        // Meanwhile `a` finds newer seeds for 7 and files them.
        a.visit(7, 7);
        let mut kb = KBest::new(2);
        kb.push(0.25, 5);
        kb.push(0.5, 6);
        a.remember(&kb, 7, 7, &ACCEPTED);
        a.visit(8, 8);
        b.visit(9, 9);
        let mut ids = [0; 2];
        assert!(cache.load(7, &mut ids));
        assert_eq!(ids, [5, 6]);
    }

    /// Seeds go by pixel while every pixel's fit in 2^22 ids, else by cell.
    #[test]
    fn seeds_are_kept_by_pixel_when_the_film_is_small() {
        use crate::dump::{Header, Order};
        let keys = SeedKeys::new(&Header::still(256, 256, 64, Order::PassMajor), 50);
        assert_eq!((keys.by_pixel, keys.slots), (true, 65536));
        let keys = SeedKeys::new(&Header::still(1920, 1080, 64, Order::PassMajor), 10);
        assert!(!keys.by_pixel && keys.slots * 10 <= 1 << 20);
    }

    /// The adaptive share rises while the in-order pass finishes first,
    /// falls while the search waits for it, and stays within [0, 1]; a
    /// fixed share never moves.
    #[test]
    fn deferral_share_follows_the_slower_side() {
        let mut d = Deferral {
            share: 0.5,
            fixed: false,
        };
        d.update(1.0, 2.0, 0);
        assert!(d.share > 0.5);
        for _ in 0..100 {
            d.update(1.0, 2.0, 7);
        }
        assert_eq!(d.share, 1.0);
        // Slower in order but with no deferred search to give back.
        d.update(2.0, 1.0, 0);
        assert_eq!(d.share, 1.0);
        d.update(2.0, 1.0, 7);
        assert!(d.share < 1.0);
        for _ in 0..100 {
            d.update(2.0, 1.0, 7);
        }
        assert_eq!(d.share, 0.0);
        let mut fixed = Deferral::new(Some(0.25));
        fixed.update(2.0, 1.0, 7);
        assert_eq!(fixed.share, 0.25);
    }
}
