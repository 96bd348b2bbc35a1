//! A batch of consecutive records: prepared (classified and mapped to the
//! joint space) ahead of time, then searched in parallel against a copy of
//! T, in an order that keeps neighbours on one worker.

use std::sync::{Arc, Mutex};

use crate::par::prelude::*;

use super::index::{Found, NeighbourIndex};
use super::seeds::{SeedCache, SeedKeys, Seeds};
use super::sigma::{Goal, KBest, Verdict};
use crate::dump::{Header, Record, Validity};
use crate::joint::JointSpace;

/// Accepted without a full search (σ < 1 proven by seeds).
pub(super) const ACCEPTED: Found = Found {
    verdict: Verdict::Accept,
    bound: 0.0,
    reach: 0,
};

/// One record of a batch mapped to the joint space; meaningful only where
/// the batch's `validity` says the record is valid.
#[derive(Clone, Copy)]
pub(super) struct Slot<const D: usize> {
    /// The index's locality key of `p`.
    pub(super) key: u32,
    /// The key its seeds are cached under ([`SeedKeys`]).
    pub(super) seed_key: u32,
    pub(super) p: [f32; D],
}

/// The parallel search of one valid record.
#[derive(Clone, Copy)]
pub(super) struct Hit {
    pub(super) found: Found,
    /// How many distances of `kbuf` belong to this hit.
    pub(super) klen: usize,
    /// Whether they are in ascending order.
    pub(super) sorted: bool,
    /// Not searched: the in-order pass searches the current T instead.
    pub(super) deferred: bool,
}

/// Records per job of the preparation, and the smallest batch.
pub(super) const SUB_BLOCK: usize = 256;

/// Records per job of the parallel search: small, because the last job of
/// a batch is waited for, and small jobs leave less idle time at its end
/// (docs/BENCHMARKS.md, "The replay's constants").
pub(super) const SEARCH_BLOCK: usize = 64;

/// Deferred searches in a row before a worker searches again to refresh
/// its seeds (see [`super::deferral::Deferral`]).
pub(super) const REFRESH: u32 = 16;

/// One batch's records after the parallel search.
pub(super) struct Batch<const D: usize> {
    /// In file order; the first `len` are prepared. A slot holds a point
    /// only where `validity` says the record is valid.
    pub(super) slots: Vec<Slot<D>>,
    pub(super) validity: Vec<Validity>,
    pub(super) len: usize,
    /// (locality key << 32 | position in the batch), sorted: the order the
    /// records are searched in, so that neighbours share a worker's caches
    /// whatever the order of the dump.
    pub(super) order: Vec<u64>,
    /// Search results in `order`'s order, and the k nearest squared
    /// distances each found (`k` per hit).
    pub(super) hits: Vec<Hit>,
    /// In `order`'s order: accepted by the search for good (while deciding,
    /// not deferred). The in-order pass reads this byte rather than the
    /// record's slot and hit: those were written on another core and most
    /// records need nothing else.
    pub(super) accepted: Vec<bool>,
    pub(super) kbuf: Vec<f64>,
    /// Position in `hits` of each record of the batch.
    pub(super) pos: Vec<u32>,
    /// |T| when the batch was searched: points with larger ids are new to it.
    pub(super) base: u32,
}

impl<const D: usize> Batch<D> {
    pub(super) fn new(len: usize, k: usize) -> Batch<D> {
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
    pub(super) fn prepare<I: NeighbourIndex<D>>(
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
                            // Fits: pixels × k ≤ 2^25 (`SeedKeys`).
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
    pub(super) fn order_by_locality(&mut self) {
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
    pub(super) fn search<I: NeighbourIndex<D>>(
        &mut self,
        index: &I,
        k: usize,
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
                let slot = crate::par::current_thread_index().unwrap_or(0) % workers.len();
                let mut guard = workers[slot].lock().unwrap_or_else(|e| e.into_inner());
                let Worker {
                    kb,
                    scratch,
                    seeds,
                    share,
                } = &mut *guard;
                for ((hit, kd), &key) in hits.iter_mut().zip(kbuf.chunks_mut(k)).zip(order) {
                    let Slot { p, seed_key, .. } = slots[(key & u32::MAX as u64) as usize];
                    let p = &p;
                    let cell = (key >> 32) as u32;
                    hit.deferred = false;
                    seeds.visit(cell, seed_key);
                    if seeds.accept(index, p, k) {
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
                    hit.found = index.search(p, None, Goal::Decide, kb, scratch);
                    seeds.remember(kb, cell, seed_key, &hit.found);
                    hit.klen = kb.as_slice().len();
                    hit.sorted = kb.is_sorted();
                    kd[..hit.klen].copy_from_slice(kb.as_slice());
                }
                for (a, hit) in accepted.iter_mut().zip(&*hits) {
                    *a = !hit.deferred && hit.found.verdict.accepted();
                }
            });
    }
}

/// One thread's working state for the parallel search.
pub(super) struct Worker<S> {
    pub(super) kb: KBest,
    pub(super) scratch: S,
    pub(super) seeds: Seeds,
    /// Accumulated share of deferrable searches (see [`super::deferral::Deferral`]).
    pub(super) share: f64,
}

impl<S: Default> Worker<S> {
    pub(super) fn new(k: usize, cache: Arc<SeedCache>) -> Worker<S> {
        Worker {
            kb: KBest::new(k),
            scratch: S::default(),
            seeds: Seeds::new(k, cache),
            share: 0.0,
        }
    }

    /// One per thread of the current rayon pool, sharing one seed cache,
    /// found by the pool's thread index. Not `thread_local::ThreadLocal`:
    /// the workers live for one replay and belong to its pool, not to the
    /// threads, and each lock is only ever taken by its own thread.
    pub(super) fn per_thread(k: usize, slots: usize) -> Vec<Mutex<Worker<S>>> {
        let cache = Arc::new(SeedCache::new(k, slots));
        (0..crate::par::current_num_threads())
            .map(|_| Mutex::new(Worker::new(k, cache.clone())))
            .collect()
    }
}
