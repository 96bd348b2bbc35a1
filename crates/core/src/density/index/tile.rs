//! The block of grid cells around a query, gathered once and searched by
//! whole columns.
//!
//! Consecutive samples of a dump mostly fall in the same cell (a pixel's
//! samples are adjacent in a pixel-major dump), so a worker keeps the points
//! of the block around the last cell, one f64 array per coordinate. The
//! squared distances to all of them are then a few straight loops the
//! compiler vectorises, with the canonical arithmetic of
//! [`crate::joint::dist2`] (each point's terms added in coordinate order).
//! The k nearest are selected among the few candidates below a threshold
//! learnt from the previous query, and handed to [`KBest`] unsorted.

use crate::density::sigma::{KBest, Sum};

/// A stored point and its id, as a grid cell lists them.
#[derive(Clone, Copy)]
pub struct Entry<const D: usize> {
    pub p: [f32; D],
    pub id: u32,
}

/// Per-worker cache of one block of cells; see the module doc.
pub struct Tile<const D: usize> {
    /// (cell, |T|) the block was gathered for; `None` before the first.
    key: Option<(usize, usize)>,
    /// Whether its points are in id order ([`Tile::fill_by_id`]). Not part
    /// of `key`: a key of both made the bare replay's streaming pass up to
    /// 6 % slower (docs/BENCHMARKS.md).
    by_id: bool,
    /// Coordinate j of every gathered point, widened to f64.
    cols: [Vec<f64>; D],
    ids: Vec<u32>,
    /// The block's entries while [`Tile::fill_by_id`] sorts them.
    sorting: Vec<Entry<D>>,
    d2: Vec<f64>,
    /// Candidates below the threshold: (squared distance, id).
    pick: Vec<(f64, u32)>,
    /// The last query's k-th nearest squared distance (+∞ before one
    /// found k): the next query's threshold lies a little above it, and
    /// its candidates are partitioned around it. Only speed depends on it.
    last2: f64,
}

impl<const D: usize> Default for Tile<D> {
    fn default() -> Self {
        Tile {
            key: None,
            by_id: false,
            cols: std::array::from_fn(|_| Vec::new()),
            ids: Vec::new(),
            sorting: Vec::new(),
            d2: Vec::new(),
            pick: Vec::new(),
            last2: f64::INFINITY,
        }
    }
}

/// The threshold for the next query, relative to the last k-th squared
/// distance: measured on the benchmark dump, 1.3 keeps the candidates to
/// about 1.3 k while rarely falling short of k.
const TAU_MARGIN: f64 = 1.3;

impl<const D: usize> Tile<D> {
    /// True when the tile holds the block gathered for `key` by
    /// [`Tile::fill`].
    pub fn holds(&self, key: (usize, usize)) -> bool {
        self.key == Some(key) && !self.by_id
    }

    /// True when the tile holds the block gathered for `key` by
    /// [`Tile::fill_by_id`].
    pub fn holds_by_id(&self, key: (usize, usize)) -> bool {
        self.key == Some(key) && self.by_id
    }

    /// Replaces the contents with the points of `cells` for `key`.
    pub fn fill(&mut self, key: (usize, usize), cells: &[&[Entry<D>]]) {
        self.gather(cells);
        self.key = Some(key);
        self.by_id = false;
    }

    /// Replaces the contents with the points of `cells` for `key`, in id
    /// order: the points stored before any given id are then a prefix,
    /// which [`Tile::nearest_before`] searches alone.
    pub fn fill_by_id(&mut self, key: (usize, usize), cells: &[&[Entry<D>]]) {
        let mut sorting = std::mem::take(&mut self.sorting);
        sorting.clear();
        sorting.extend(cells.iter().flat_map(|c| c.iter()));
        sorting.sort_unstable_by_key(|e| e.id);
        self.gather(&[&sorting]);
        self.sorting = sorting;
        self.key = Some(key);
        self.by_id = true;
    }

    fn gather(&mut self, cells: &[&[Entry<D>]]) {
        let n = cells.iter().map(|c| c.len()).sum();
        // Sized once, then written in place, a cell at a time, column by
        // column: a refill per cell change is a large share of a
        // pass-major replay, where a worker meets each cell for a few
        // samples only.
        for c in self.cols.iter_mut() {
            c.resize(n, 0.0);
        }
        self.ids.resize(n, 0);
        let points = cells.iter().flat_map(|c| c.iter());
        for (i, e) in points.enumerate() {
            for (c, &v) in self.cols.iter_mut().zip(&e.p) {
                c[i] = v as f64;
            }
            self.ids[i] = e.id;
        }
    }

    /// Replaces the contents of `kb` with the k nearest gathered points to
    /// `q`, skipping the point `exclude`. With `decide_early`, their
    /// distances in any order may already tell the verdict
    /// ([`KBest::classify`]); `kb` then holds them unordered, which saves
    /// sorting them. Otherwise `kb` is sorted and the result is
    /// [`Sum::Unknown`].
    pub fn nearest(
        &mut self,
        q: &[f32; D],
        exclude: Option<u32>,
        kb: &mut KBest,
        decide_early: bool,
    ) -> Sum {
        let n = self.ids.len();
        self.nearest_among(n, q, exclude, kb, decide_early)
    }

    /// Replaces the contents of `kb` with the k nearest points to `q` among
    /// those with ids below `before`, sorted. The tile must have been
    /// filled by [`Tile::fill_by_id`].
    pub fn nearest_before(&mut self, q: &[f32; D], before: u32, kb: &mut KBest) {
        debug_assert!(self.by_id);
        let n = self.ids.partition_point(|&id| id < before);
        self.nearest_among(n, q, None, kb, false);
    }

    /// [`Tile::nearest`] among the first `n` points.
    fn nearest_among(
        &mut self,
        n: usize,
        q: &[f32; D],
        exclude: Option<u32>,
        kb: &mut KBest,
        decide_early: bool,
    ) -> Sum {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            return unsafe { self.nearest_avx2(n, q, exclude, kb, decide_early) };
        }
        self.nearest_portable(n, q, exclude, kb, decide_early)
    }

    /// [`Tile::nearest`] compiled for AVX2: the same code and the same
    /// arithmetic (no fused multiply-add), in wider vectors.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn nearest_avx2(
        &mut self,
        n: usize,
        q: &[f32; D],
        exclude: Option<u32>,
        kb: &mut KBest,
        decide_early: bool,
    ) -> Sum {
        self.nearest_portable(n, q, exclude, kb, decide_early)
    }

    #[inline(always)]
    fn nearest_portable(
        &mut self,
        n: usize,
        q: &[f32; D],
        exclude: Option<u32>,
        kb: &mut KBest,
        decide_early: bool,
    ) -> Sum {
        let k = kb.k();
        self.d2.clear();
        self.d2.resize(n, 0.0);
        // Column by column: adding coordinate j's term to every point in
        // turn keeps each point's canonical order of additions.
        for (col, &qj) in self.cols.iter().zip(q) {
            let qj = qj as f64;
            for (s, &v) in self.d2.iter_mut().zip(&col[..n]) {
                let d = v - qj;
                *s += d * d;
            }
        }
        if self.pick.len() < n + 1 {
            self.pick.resize(n + 1, (0.0, 0));
        }
        let last2 = self.last2;
        let mut tau2 = if last2 > 0.0 {
            last2 * TAU_MARGIN
        } else {
            f64::INFINITY
        };
        let mut m;
        loop {
            // Branch-free compaction of the candidates at or below tau2.
            m = 0;
            let pick = &mut self.pick[..n + 1];
            for (&d2, &id) in self.d2.iter().zip(&self.ids[..n]) {
                pick[m] = (d2, id);
                m += (d2 <= tau2) as usize;
            }
            if let Some(x) = exclude
                && let Some(i) = pick[..m].iter().position(|c| c.1 == x)
            {
                pick.copy_within(i + 1..m, i);
                m -= 1;
            }
            // Fewer than k below the threshold: the k nearest may lie above.
            if m >= k || tau2 == f64::INFINITY {
                break;
            }
            tau2 = f64::INFINITY;
        }
        let pick = &mut self.pick[..m];
        // Squared distances are never negative or NaN, so their bits order
        // as they do: an integer comparison.
        let by_d2 = |c: &(f64, u32)| c.0.to_bits();
        // The last query's k-th nearest is usually close to this one's:
        // partitioned around it, at most one side needs a selection, and
        // often a small one.
        let mut a = 0;
        if m > k && last2 < tau2 {
            for i in 0..m {
                let below = pick[i].0 <= last2;
                pick.swap(i, a);
                a += below as usize;
            }
        }
        // Any k points whose distances sum below k prove σ < 1 (the k
        // nearest can only sum lower): the first k after the partition,
        // mostly within the last k-th, often do, without a selection.
        if decide_early && m > k {
            kb.set_unordered(&pick[..k], false);
            if kb.classify() == Sum::BelowK {
                return Sum::BelowK;
            }
        }
        let largest_last = if m <= k {
            false
        } else if a >= k {
            if a > k {
                pick[..a].select_nth_unstable_by_key(k - 1, by_d2);
            }
            a > k
        } else {
            // All below the pivot, then the nearest above it.
            pick[a..].select_nth_unstable_by_key(k - a - 1, by_d2);
            true
        };
        kb.set_unordered(&pick[..m.min(k)], largest_last);
        if kb.is_full() {
            self.last2 = kb.worst2();
        }
        if decide_early {
            let verdict = kb.classify();
            if verdict != Sum::Unknown {
                return verdict;
            }
        }
        kb.sort();
        Sum::Unknown
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::joint::dist2;

    /// The tile's k nearest equal a plain sort of every point's canonical
    /// squared distance, whatever threshold the previous query left.
    #[test]
    fn tile_nearest_equals_sorting_every_distance() {
        let mut unit = crate::synth::test_units(12345);
        let mut next = || (unit() * 4.0) as f32;
        let pts: Vec<[f32; 5]> = (0..300).map(|_| std::array::from_fn(|_| next())).collect();
        let mut tile = Tile::<5>::default();
        let entries: Vec<Entry<5>> = pts
            .iter()
            .zip(0u32..)
            .map(|(&p, id)| Entry { p, id })
            .collect();
        tile.fill((0, 0), &[&entries[..]]);
        for (i, k) in [
            (0usize, 1usize),
            (1, 10),
            (2, 10),
            (3, 50),
            (4, 300),
            (5, 7),
        ] {
            let q: [f32; 5] = std::array::from_fn(|_| next());
            let exclude = (i % 2 == 1).then_some(i as u32);
            let mut kb = KBest::new(k);
            assert_eq!(tile.nearest(&q, exclude, &mut kb, false), Sum::Unknown);
            let mut all: Vec<f64> = pts
                .iter()
                .zip(0u32..)
                .filter(|(_, id)| Some(*id) != exclude)
                .map(|(p, _)| dist2(p, &q))
                .collect();
            all.sort_by(f64::total_cmp);
            all.truncate(k);
            assert_eq!(kb.as_slice(), &all[..], "query {i}, k = {k}");
            for (&d2, &id) in kb.as_slice().iter().zip(kb.ids()) {
                assert_eq!(d2, dist2(&pts[id as usize], &q));
            }
        }
    }

    /// Queries in a row at one k, each leaving the pivot and threshold for
    /// the next (the case the partition is built for: the pivot falls below,
    /// at and above the next query's k-th nearest): the contents always
    /// equal the k smallest of a plain sort, with the largest last.
    #[test]
    fn tile_partition_around_the_last_kth_keeps_the_k_smallest() {
        let mut unit = crate::synth::test_units(777);
        let pts: Vec<[f32; 5]> = (0..400)
            .map(|_| std::array::from_fn(|_| (unit() * 4.0) as f32))
            .collect();
        let mut tile = Tile::<5>::default();
        let entries: Vec<Entry<5>> = pts
            .iter()
            .zip(0u32..)
            .map(|(&p, id)| Entry { p, id })
            .collect();
        tile.fill((0, 0), &[&entries[..]]);
        let mut selected = 0;
        for k in [1usize, 10, 50] {
            let mut kb = KBest::new(k);
            for _ in 0..200 {
                let q: [f32; 5] = std::array::from_fn(|_| (unit() * 4.0) as f32);
                if tile.nearest(&q, None, &mut kb, true) == Sum::BelowK {
                    // Accepted: the contents need only prove it.
                    assert_eq!(
                        crate::density::sigma::classify(kb.as_slice(), k),
                        Sum::BelowK
                    );
                    for (&d2, &id) in kb.as_slice().iter().zip(kb.ids()) {
                        assert_eq!(d2, dist2(&pts[id as usize], &q));
                    }
                    continue;
                }
                selected += 1;
                let mut got = kb.as_slice().to_vec();
                let largest = got.iter().cloned().fold(0.0, f64::max);
                assert_eq!(*got.last().unwrap(), largest, "k = {k}: largest not last");
                got.sort_by(f64::total_cmp);
                let mut all: Vec<f64> = pts.iter().map(|p| dist2(p, &q)).collect();
                all.sort_by(f64::total_cmp);
                all.truncate(k);
                assert_eq!(got, all, "k = {k}");
            }
        }
        assert!(
            selected >= 300,
            "only {selected} of 600 queries reached the selection"
        );
    }

    /// Any k points within the threshold that prove σ < 1 settle a query
    /// without a selection, and only then: a query is accepted exactly
    /// when the k nearest prove it (near and far queries mixed).
    #[test]
    fn tile_accepts_on_any_k_that_prove_it() {
        let mut unit = crate::synth::test_units(4242);
        let pts: Vec<[f32; 5]> = (0..400)
            .map(|_| std::array::from_fn(|_| (unit() * 0.8) as f32))
            .collect();
        let entries: Vec<Entry<5>> = pts
            .iter()
            .zip(0u32..)
            .map(|(&p, id)| Entry { p, id })
            .collect();
        let mut tile = Tile::<5>::default();
        tile.fill((0, 0), &[&entries[..]]);
        let k = 10;
        let mut kb = KBest::new(k);
        let (mut near, mut far) = (0, 0);
        for _ in 0..300 {
            let q: [f32; 5] = std::array::from_fn(|_| (unit() * 3.0 - 1.1) as f32);
            let got = tile.nearest(&q, None, &mut kb, true);
            let mut all: Vec<f64> = pts.iter().map(|p| dist2(p, &q)).collect();
            all.sort_by(f64::total_cmp);
            let sigma = crate::density::sigma::sigma(&all[..k], k);
            if got == Sum::BelowK {
                assert!(sigma < 1.0, "accepted with σ = {sigma}");
                near += 1;
            } else {
                assert!(sigma >= 0.99, "not accepted with σ = {sigma}");
                far += 1;
            }
        }
        assert!(near > 30 && far > 30, "{near} near, {far} far");
    }
}
