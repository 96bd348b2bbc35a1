//! Seeds: the k nearest stored points of a worker's last full search,
//! tried first on its next sample, and the cache that keeps them by pixel
//! or grid cell. An accelerator only: any k stored points are valid seeds,
//! so no decision rests on them.

use std::sync::Arc;
use std::sync::atomic::AtomicU32;
use std::sync::atomic::Ordering::Relaxed;

use super::index::{Found, NeighbourIndex};
use super::sigma::{KBest, Sum, classify};
use crate::dump::Header;
use crate::joint::dist2;

/// The k nearest stored points of a worker's last full search, tried first
/// on its next sample: neighbouring samples of a dump mostly share their
/// neighbours, and k distances are far cheaper than a search. Exact: stored
/// points never leave T, and any k of them whose σ is provably below 1
/// prove the sample accepted ([`classify`]).
pub(super) struct Seeds {
    /// The locality key of the sample they were found for.
    pub(super) key: u32,
    /// Whether that sample's search failed to accept it (the lagging T
    /// lacked the points its recheck then supplies).
    pub(super) failed: bool,
    /// Searches deferred since they were found.
    pub(super) deferred: u32,
    /// The cache key of the sample they were found or fetched for.
    pub(super) seed_key: u32,
    /// Whether the cache holds `ids` under `seed_key` already (they were
    /// fetched from it and not replaced since), so filing them is moot.
    pub(super) filed: bool,
    pub(super) ids: Vec<u32>,
    /// Their squared distances to the current query.
    pub(super) d2: Vec<f64>,
    /// The seeds last found under each key, so that a worker coming back
    /// to a pixel or cell starts from them rather than from the last one's.
    /// The parallel workers share one (the lagging T's ids); the in-order
    /// pass has its own (ids of the current T, not all in the lagging one).
    pub(super) cache: Arc<SeedCache>,
}

/// What seeds are cached by: the pixel when the cache can hold every
/// pixel's, else the grid cell. A pass-major dump brings a worker back to a
/// pixel once per pass, a batch holding one sample of it, and seeds found
/// for the pixel's previous sample prove far more than a neighbour's
/// (docs/BENCHMARKS.md, "The replay's constants").
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct SeedKeys {
    pub(super) by_pixel: bool,
    pub(super) slots: usize,
}

impl SeedKeys {
    /// By pixel where the dump comes back to its pixels (two samples a
    /// pixel or more: a pixel's seeds serve its next sample) and the
    /// cache holds up to 2^25 ids (128 MB, and 4 bytes a pixel of keys),
    /// a 1080p film's at k ≤ 16: by cell, a pass-major replay of that
    /// film was 1.6× slower (docs/BENCHMARKS.md, "A production frame").
    /// By cell, at most 16384 slots and 2^20 ids. There are two caches:
    /// the parallel workers' and the in-order pass's.
    pub(super) fn new(header: &Header, k: usize) -> SeedKeys {
        let pixels = header.pixels().saturating_mul(header.frames as usize);
        let revisited = header.sample_count >= 2 * pixels as u64;
        if revisited && pixels.saturating_mul(k) <= 1 << 25 {
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
pub(super) struct SeedCache {
    pub(super) k: usize,
    /// The key each slot holds (`u32::MAX`: none).
    pub(super) keys: Vec<AtomicU32>,
    /// k ids per slot.
    pub(super) ids: Vec<AtomicU32>,
}

impl SeedCache {
    pub(super) fn new(k: usize, slots: usize) -> SeedCache {
        SeedCache {
            k,
            keys: (0..slots).map(|_| AtomicU32::new(u32::MAX)).collect(),
            ids: (0..slots * k).map(|_| AtomicU32::new(0)).collect(),
        }
    }

    pub(super) fn slot(&self, key: u32) -> usize {
        key as usize % self.keys.len()
    }

    pub(super) fn store(&self, key: u32, ids: &[u32]) {
        let s = self.slot(key);
        for (a, &id) in self.ids[s * self.k..(s + 1) * self.k].iter().zip(ids) {
            a.store(id, Relaxed);
        }
        self.keys[s].store(key, Relaxed);
    }

    /// Copies the seeds of `key` into `ids`, if the cache has them, and
    /// says whether it had.
    pub(super) fn load(&self, key: u32, ids: &mut [u32]) -> bool {
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
    pub(super) fn new(k: usize, cache: Arc<SeedCache>) -> Seeds {
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
    pub(super) fn visit(&mut self, key: u32, seed_key: u32) {
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
    pub(super) fn accept<const D: usize, I: NeighbourIndex<D>>(
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

    pub(super) fn remember(&mut self, kb: &KBest, key: u32, seed_key: u32, found: &Found) {
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

#[cfg(test)]
mod tests {
    use super::{KBest, SeedCache, SeedKeys, Seeds};
    use crate::density::batch::ACCEPTED;
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

    /// Seeds go by pixel while every pixel's fit in 2^25 ids and the dump
    /// has two samples a pixel, else by cell.
    #[test]
    fn seeds_are_kept_by_pixel_when_the_film_is_small() {
        use crate::dump::{Header, Order};
        let film = |w: u32, h: u32, samples: u64| Header {
            sample_count: samples,
            ..Header::still(w, h, 64, Order::PassMajor)
        };
        let keys = SeedKeys::new(&film(256, 256, 256 * 256 * 64), 50);
        assert_eq!((keys.by_pixel, keys.slots), (true, 65536));
        let keys = SeedKeys::new(&film(1920, 1080, 1920 * 1080 * 2), 16);
        assert_eq!((keys.by_pixel, keys.slots), (true, 1920 * 1080));
        for (few, k) in [
            (film(3840, 2160, 3840 * 2160 * 64), 10),
            (film(2048, 2048, 1000), 8),
        ] {
            let keys = SeedKeys::new(&few, k);
            assert!(!keys.by_pixel && keys.slots * k <= 1 << 20);
        }
        assert!(!SeedKeys::new(&film(1920, 1080, 1920 * 1080 * 2 - 1), 8).by_pixel);
    }
}
