//! The k nearest candidates of one query, by squared distance, as a
//! search collects them.

use super::sigma::{Sum, classify, sigma};

/// The k smallest squared distances seen so far, with the ids of their
/// points.
///
/// Squared distances order exactly as distances (sqrt is correctly rounded,
/// hence monotone), so candidates never pay a square root: only the k that
/// enter σ do, when it is evaluated.
///
/// The contents are kept either sorted ascending or, after
/// [`KBest::set_unordered`] or an unsorted [`KBest::load`], as an unordered
/// set with its largest element last: most searches decide from the
/// distances in any order ([`classify`]) and never pay for the sort.
/// [`KBest::sort`] restores the order that the canonical σ needs; [`super::sigma::judge`]
/// calls it.
///
/// Many candidates at once (a recheck's new points) go through
/// [`KBest::offer`], which only collects those below the current k-th;
/// [`KBest::settle`] then selects the k smallest in one pass.
///
/// Invariants: `len ≤ k`; when `sorted`, `d2[..len]` ascends; otherwise
/// `d2[len - 1]` is still the largest of `d2[..len]`. Offered
/// candidates wait in `spill` until [`KBest::settle`]; the contents are
/// only read once it is empty.
#[derive(Clone, Debug)]
pub struct KBest {
    k: usize,
    len: usize,
    d2: Vec<f64>,
    /// The stored-point id of each distance (`u32::MAX` when unknown).
    ids: Vec<u32>,
    /// Bumped on every change, so callers can skip re-judging.
    version: u64,
    sorted: bool,
    /// Offered candidates not yet merged.
    spill: Vec<(f64, u32)>,
}

impl KBest {
    pub fn new(k: usize) -> KBest {
        assert!(k >= 1, "k must be at least 1");
        KBest {
            k,
            len: 0,
            d2: vec![0.0; k],
            ids: vec![u32::MAX; k],
            version: 0,
            sorted: true,
            spill: Vec::new(),
        }
    }

    pub fn k(&self) -> usize {
        self.k
    }

    pub fn clear(&mut self) {
        self.len = 0;
        self.sorted = true;
        self.spill.clear();
    }

    /// Replaces the contents with (squared distance, id) pairs in no order
    /// (at most k of them); `largest_last` when the last is known to be the
    /// largest (as `select_nth_unstable` leaves it).
    pub fn set_unordered(&mut self, nearest: &[(f64, u32)], largest_last: bool) {
        self.spill.clear();
        self.len = nearest.len();
        for (i, &(d2, id)) in nearest.iter().enumerate() {
            self.d2[i] = d2;
            self.ids[i] = id;
        }
        self.sorted = false;
        if !largest_last {
            self.largest_to_end();
        }
        self.version += 1;
    }

    /// Replaces the contents with squared distances of unknown points (≤ k
    /// values): ascending when `sorted`, else in any order with the largest
    /// last (as [`KBest::as_slice`] gives them).
    pub fn load(&mut self, d2: &[f64], sorted: bool) {
        debug_assert!(if sorted {
            d2.is_sorted()
        } else {
            d2.iter().all(|&x| x <= d2[d2.len() - 1])
        });
        self.spill.clear();
        self.len = d2.len();
        self.d2[..self.len].copy_from_slice(d2);
        self.ids[..self.len].fill(u32::MAX);
        self.sorted = sorted;
        self.version += 1;
    }

    /// Moves the largest distance last: its value in four lanes (packed
    /// maxima), then its position. Measured at k = 50 this is 2–3× cheaper
    /// than one pass that tracks the position, and merging a recheck's few
    /// new points calls it once per point.
    fn largest_to_end(&mut self) {
        let d = &self.d2[..self.len];
        let Some(last) = self.len.checked_sub(1) else {
            return;
        };
        // Squared distances are never NaN, so `>` is a total order here.
        let max = |a: f64, b: f64| if b > a { b } else { a };
        let mut m = [0.0f64; 4];
        let chunks = d.chunks_exact(4);
        for &x in chunks.remainder() {
            m[0] = max(m[0], x);
        }
        for c in chunks {
            for j in 0..4 {
                m[j] = max(m[j], c[j]);
            }
        }
        let top = max(max(m[0], m[1]), max(m[2], m[3]));
        let w = d.iter().rposition(|&x| x == top).unwrap_or(last);
        self.d2.swap(w, last);
        self.ids.swap(w, last);
    }

    /// The contents and the offered candidates together, in the spill's
    /// buffer (so nothing is allocated once it has grown); give it back with
    /// [`KBest::restore_spill`].
    fn take_all(&mut self) -> Vec<(f64, u32)> {
        let mut all = std::mem::take(&mut self.spill);
        all.extend((0..self.len).map(|i| (self.d2[i], self.ids[i])));
        all
    }

    fn restore_spill(&mut self, mut all: Vec<(f64, u32)>) {
        all.clear();
        self.spill = all;
    }

    /// Puts the contents in ascending order (the canonical σ needs it).
    pub fn sort(&mut self) {
        self.settle();
        if self.sorted {
            return;
        }
        let mut all = self.take_all();
        // Non-negative, non-NaN squared distances order as their bits.
        all.sort_unstable_by_key(|c| c.0.to_bits());
        for (i, &(d2, id)) in all.iter().enumerate() {
            self.d2[i] = d2;
            self.ids[i] = id;
        }
        self.restore_spill(all);
        self.sorted = true;
    }

    pub fn is_sorted(&self) -> bool {
        self.sorted
    }

    /// The squared distances: ascending when [`KBest::is_sorted`].
    pub fn as_slice(&self) -> &[f64] {
        debug_assert!(self.spill.is_empty(), "settle offered candidates first");
        &self.d2[..self.len]
    }

    /// The ids of the points behind [`KBest::as_slice`] (`u32::MAX` for
    /// distances given to [`KBest::load`]).
    pub fn ids(&self) -> &[u32] {
        debug_assert!(self.spill.is_empty(), "settle offered candidates first");
        &self.ids[..self.len]
    }

    /// Changes whenever the contents change.
    pub fn version(&self) -> u64 {
        self.version
    }

    pub fn is_full(&self) -> bool {
        self.len == self.k
    }

    /// Offers one squared distance (from [`crate::joint::dist2`]) and takes
    /// it in at once if it is among the k smallest.
    #[inline]
    pub fn push(&mut self, dist2: f64, id: u32) {
        if self.sorted {
            self.push_sorted(dist2, id);
        } else {
            self.push_unordered(dist2, id);
        }
    }

    #[inline]
    fn push_sorted(&mut self, dist2: f64, id: u32) {
        let mut i = self.len;
        if i == self.k {
            if dist2 >= self.d2[i - 1] {
                return;
            }
            i -= 1;
        } else {
            self.len += 1;
        }
        while i > 0 && self.d2[i - 1] > dist2 {
            self.d2[i] = self.d2[i - 1];
            self.ids[i] = self.ids[i - 1];
            i -= 1;
        }
        self.d2[i] = dist2;
        self.ids[i] = id;
        self.version += 1;
    }

    #[inline]
    fn push_unordered(&mut self, dist2: f64, id: u32) {
        let n = self.len;
        if n < self.k {
            self.d2[n] = dist2;
            self.ids[n] = id;
            self.len += 1;
            // Keep the largest last.
            if n > 0 && dist2 < self.d2[n - 1] {
                self.d2.swap(n - 1, n);
                self.ids.swap(n - 1, n);
            }
        } else {
            if dist2 >= self.d2[n - 1] {
                return;
            }
            self.d2[n - 1] = dist2;
            self.ids[n - 1] = id;
            self.largest_to_end();
        }
        self.version += 1;
    }

    /// Offers one squared distance to be merged by [`KBest::settle`]:
    /// cheaper than [`KBest::push`] when many may enter.
    #[inline]
    pub fn offer(&mut self, dist2: f64, id: u32) {
        if dist2 < self.worst2() {
            self.spill.push((dist2, id));
            self.version += 1;
        }
    }

    /// Merges the offered candidates into the contents.
    pub fn settle(&mut self) {
        /// Up to this many, one at a time; beyond, one selection.
        const ONE_BY_ONE: usize = 8;
        if self.spill.is_empty() {
            return;
        }
        if self.spill.len() <= ONE_BY_ONE {
            let spill = std::mem::take(&mut self.spill);
            for &(d2, id) in &spill {
                self.push(d2, id);
            }
            self.restore_spill(spill);
            return;
        }
        let mut all = self.take_all();
        let k = self.k;
        let selected = all.len() > k;
        if selected {
            all.select_nth_unstable_by_key(k - 1, |c| c.0.to_bits());
            all.truncate(k);
        }
        self.set_unordered(&all, selected);
        self.restore_spill(all);
    }

    /// The k-th smallest squared distance so far, +∞ while fewer than k are
    /// known.
    #[inline]
    pub fn worst2(&self) -> f64 {
        // Before `settle` this is the k-th of the contents alone: an upper
        // bound, so pruning with it stays exact.
        if self.is_full() {
            self.d2[self.k - 1]
        } else {
            f64::INFINITY
        }
    }

    /// The k-th smallest distance so far, +∞ while fewer than k are known.
    #[inline]
    pub fn worst(&self) -> f64 {
        self.worst2().sqrt()
    }

    /// The canonical σ of the contents (+∞ while fewer than k); needs them
    /// sorted ([`KBest::sort`]).
    #[inline]
    pub fn sigma(&self) -> f64 {
        assert!(self.sorted, "the canonical σ needs sorted distances");
        sigma(self.as_slice(), self.k)
    }

    /// What the contents prove on their own ([`classify`]); `Unknown`
    /// while fewer than k.
    #[inline]
    pub fn classify(&mut self) -> Sum {
        self.settle();
        if self.is_full() {
            classify(self.as_slice(), self.k)
        } else {
            Sum::Unknown
        }
    }
}
