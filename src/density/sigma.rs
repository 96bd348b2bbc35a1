//! σ(s, T): the mean distance from a sample to its k nearest stored points
//! (SPEC §3), and the bounds that let a search stop early without changing
//! any decision.

/// The k smallest squared distances seen so far, with the ids of their
/// points.
///
/// Squared distances order exactly as distances (sqrt is correctly rounded,
/// hence monotone), so candidates never pay a square root: only the k that
/// enter σ do, when it is evaluated.
///
/// The contents are kept either sorted ascending or, after
/// [`KBest::set_unordered`] / [`KBest::load_unordered`], as an unordered set
/// with its largest element tracked: most searches decide from an
/// unordered sum ([`surely_below_k`], [`surely_at_least_k`]) and never pay
/// for the sort. [`KBest::sort`] restores the order that the canonical σ
/// needs; [`judge`] calls it.
///
/// Many candidates at once (a recheck's new points) go through
/// [`KBest::offer`], which only collects those below the current k-th;
/// [`KBest::settle`] then selects the k smallest in one pass.
///
/// Invariants: `len ≤ k`; when `sorted`, `d2[..len]` ascends; otherwise
/// `d2[worst_i]` is the largest of `d2[..len]` (when `len > 0`). Offered
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
    /// Position of the largest distance while unordered.
    worst_i: usize,
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
            worst_i: 0,
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
    /// (at most k of them).
    pub fn set_unordered(&mut self, nearest: &[(f64, u32)]) {
        self.spill.clear();
        self.len = nearest.len();
        for (i, &(d2, id)) in nearest.iter().enumerate() {
            self.d2[i] = d2;
            self.ids[i] = id;
        }
        self.mark_unordered();
    }

    /// Replaces the contents with squared distances of unknown points (≤ k
    /// values), ascending when `sorted`, else in any order.
    pub fn load(&mut self, d2: &[f64], sorted: bool) {
        self.spill.clear();
        self.len = d2.len();
        self.d2[..self.len].copy_from_slice(d2);
        self.ids[..self.len].fill(u32::MAX);
        if sorted {
            debug_assert!(d2.is_sorted());
            self.sorted = true;
            self.version += 1;
        } else {
            self.mark_unordered();
        }
    }

    fn mark_unordered(&mut self) {
        self.sorted = false;
        self.find_worst();
        self.version += 1;
    }

    fn find_worst(&mut self) {
        let mut w = 0;
        for i in 1..self.len {
            if self.d2[i] > self.d2[w] {
                w = i;
            }
        }
        self.worst_i = w;
    }

    /// Puts the contents in ascending order (the canonical σ needs it).
    pub fn sort(&mut self) {
        self.settle();
        if self.sorted {
            return;
        }
        let mut pairs: [(u64, u32); 64] = [(0, 0); 64];
        if self.len <= pairs.len() {
            // Non-negative, non-NaN squared distances order as their bits.
            for (i, p) in pairs[..self.len].iter_mut().enumerate() {
                *p = (self.d2[i].to_bits(), self.ids[i]);
            }
            pairs[..self.len].sort_unstable_by_key(|p| p.0);
            for (i, p) in pairs[..self.len].iter().enumerate() {
                self.d2[i] = f64::from_bits(p.0);
                self.ids[i] = p.1;
            }
        } else {
            let mut v: Vec<(u64, u32)> = (0..self.len)
                .map(|i| (self.d2[i].to_bits(), self.ids[i]))
                .collect();
            v.sort_unstable_by_key(|p| p.0);
            for (i, p) in v.into_iter().enumerate() {
                self.d2[i] = f64::from_bits(p.0);
                self.ids[i] = p.1;
            }
        }
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

    /// Offers one squared distance (from [`crate::joint::dist2`]), keeping
    /// sorted contents sorted.
    #[inline]
    pub fn push(&mut self, dist2: f64, id: u32) {
        if !self.sorted {
            self.offer(dist2, id);
            return;
        }
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

    /// Offers one squared distance to be merged by [`KBest::settle`]:
    /// cheaper than [`KBest::push`] when several may enter.
    #[inline]
    pub fn offer(&mut self, dist2: f64, id: u32) {
        if dist2 < self.worst2() {
            self.spill.push((dist2, id));
            self.version += 1;
        }
    }

    /// Merges the offered candidates: the k smallest of contents and
    /// candidates, unordered.
    pub fn settle(&mut self) {
        if self.spill.is_empty() {
            return;
        }
        let mut all = std::mem::take(&mut self.spill);
        all.extend((0..self.len).map(|i| (self.d2[i], self.ids[i])));
        let k = self.k;
        if all.len() > k {
            // Non-negative, non-NaN squared distances order as their bits.
            all.select_nth_unstable_by_key(k - 1, |c| c.0.to_bits());
            all.truncate(k);
        }
        self.set_unordered(&all);
        all.clear();
        self.spill = all;
    }

    /// The k-th smallest squared distance so far, +∞ while fewer than k are
    /// known.
    #[inline]
    pub fn worst2(&self) -> f64 {
        // Before `settle` this is the k-th of the contents alone: an upper
        // bound, so pruning with it stays exact.
        if !self.is_full() {
            f64::INFINITY
        } else if self.sorted {
            self.d2[self.k - 1]
        } else {
            self.d2[self.worst_i]
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

    /// The unordered sum of the contents' distances, when full.
    #[inline]
    pub fn unordered_sum(&mut self) -> Option<f64> {
        self.settle();
        self.is_full()
            .then(|| unordered_sum(self.as_slice().iter().copied()))
    }
}

/// The canonical σ (SPEC §3) from the k smallest squared distances, sorted
/// ascending: their square roots added one at a time from the smallest in
/// f64 and divided by k; +∞ when fewer than k are given. Every σ in this
/// crate comes from this function, so the search path that found the
/// neighbours cannot change the bits.
///
/// ```
/// use pathdensity::density::sigma::sigma;
/// assert_eq!(sigma(&[0.25, 1.0, 2.25], 3), 1.0);
/// assert_eq!(sigma(&[0.25], 3), f64::INFINITY);
/// ```
#[inline]
pub fn sigma(sorted2: &[f64], k: usize) -> f64 {
    if sorted2.len() < k {
        return f64::INFINITY;
    }
    let mut s = 0.0f64;
    for &d2 in &sorted2[..k] {
        s += d2.sqrt();
    }
    s / k as f64
}

/// The square roots of `d2` added in an order of our choosing (four
/// partial sums, so that independent additions pipeline).
#[inline]
pub fn unordered_sum(d2: impl Iterator<Item = f64>) -> f64 {
    let mut s = [0.0f64; 4];
    for (i, x) in d2.enumerate() {
        s[i & 3] += x.sqrt();
    }
    (s[0] + s[1]) + (s[2] + s[3])
}

/// The relative margin that separates an unordered sum of k non-negative
/// values from the canonical one: any two orders differ by at most
/// 2γ₍k−1₎ ≈ 2k·2⁻⁵³ of the sum; k·2⁻⁴⁰ covers that and the final division
/// for any k ≤ 2³⁰.
#[inline]
fn order_margin(k: usize) -> f64 {
    debug_assert!(k <= 1 << 30);
    k as f64 * f64::EPSILON * 4096.0
}

/// True when an [`unordered_sum`] of k distances proves that their
/// canonical σ is below 1.
#[inline]
pub fn sum_below_k(sum: f64, k: usize) -> bool {
    let kf = k as f64;
    sum < kf * (1.0 - order_margin(k))
}

/// True when an [`unordered_sum`] of k distances proves that their
/// canonical σ is at least 1.
#[inline]
pub fn sum_at_least_k(sum: f64, k: usize) -> bool {
    let kf = k as f64;
    sum >= kf * (1.0 + order_margin(k))
}

/// True when the square roots of `d2` (k values, any order) provably add
/// up to less than k in the canonical order, so that their canonical σ is
/// below 1.
#[inline]
pub fn surely_below_k(d2: impl Iterator<Item = f64>, k: usize) -> bool {
    sum_below_k(unordered_sum(d2), k)
}

/// A lower bound on σ when every point not yet seen lies at distance ≥
/// `bound`: the i-th true distance is at least min(found_i, bound). It is
/// computed with the same arithmetic as [`sigma`], and f64 addition is
/// monotone, so `lower_bound(..) ≥ 1` proves the exact σ ≥ 1.
#[inline]
pub fn lower_bound(sorted2: &[f64], k: usize, bound: f64) -> f64 {
    let mut s = 0.0f64;
    for i in 0..k {
        let d = sorted2.get(i).map_or(f64::INFINITY, |d2| d2.sqrt());
        s += d.min(bound);
    }
    s / k as f64
}

/// What a neighbour search needs to establish.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Goal {
    /// Only whether σ < 1 (the filter's decision).
    Decide,
    /// The exact σ (for the σ map).
    Exact,
}

/// The outcome of a search.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Verdict {
    /// σ < 1 is proven; the exact value was not needed.
    Accept,
    /// σ ≥ 1 is proven; the exact value was not needed.
    Reject,
    /// The exact σ.
    Sigma(f64),
}

impl Verdict {
    pub fn accepted(self) -> bool {
        match self {
            Verdict::Accept => true,
            Verdict::Reject => false,
            Verdict::Sigma(s) => s < 1.0,
        }
    }
    pub fn sigma(self) -> Option<f64> {
        match self {
            Verdict::Sigma(s) => Some(s),
            _ => None,
        }
    }
}

/// Decides from the neighbours found so far, when every unseen point lies
/// at distance ≥ `bound` (+∞ once the search is complete). `None` means the
/// search must go on.
///
/// Early acceptance is exact: the i-th smallest of any k found distances
/// bounds the i-th true one from above, so their canonical mean bounds σ.
/// Unordered contents are first judged from their unordered sum, which
/// settles most searches without sorting.
#[inline]
pub fn judge(kb: &mut KBest, bound: f64, goal: Goal) -> Option<Verdict> {
    let k = kb.k();
    kb.settle();
    let complete = bound == f64::INFINITY || kb.worst() <= bound;
    if goal == Goal::Decide
        && !kb.is_sorted()
        && let Some(sum) = kb.unordered_sum()
    {
        if sum_below_k(sum, k) {
            return Some(Verdict::Accept);
        }
        if complete && sum_at_least_k(sum, k) {
            // The k found are the k nearest, and their σ ≥ 1.
            return Some(Verdict::Reject);
        }
    }
    kb.sort();
    if complete {
        return Some(Verdict::Sigma(kb.sigma()));
    }
    if goal == Goal::Decide {
        if kb.is_full() && kb.sigma() < 1.0 {
            return Some(Verdict::Accept);
        }
        if lower_bound(kb.as_slice(), k, bound) >= 1.0 {
            return Some(Verdict::Reject);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kbest_keeps_the_k_smallest_sorted() {
        let mut kb = KBest::new(3);
        for d in [25.0, 1.0, 16.0, 0.0, 9.0, 0.0] {
            kb.push(d, 0);
        }
        assert_eq!(kb.as_slice(), &[0.0, 0.0, 1.0]);
        assert_eq!(kb.ids(), &[0, 0, 0]);
    }

    /// The unordered tests never claim σ < 1 or σ ≥ 1 when the canonical σ
    /// says otherwise, on sums within a few ulps of k (where the orders can
    /// disagree), and they do claim it when σ is clearly below or above 1.
    #[test]
    fn unordered_sums_never_contradict_the_canonical_sigma() {
        let mut rng = 0x9e3779b97f4a7c15u64;
        let mut unit = || {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (rng >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut claimed = 0;
        for case in 0..20_000 {
            let k = 1 + case % 60;
            let mut d: Vec<f64> = (0..k).map(|_| unit() * 2.0).collect();
            let total: f64 = d.iter().sum();
            // Scale so the distances add up to k within a few ulps.
            let nudge = 1.0 + (unit() - 0.5) * 64.0 * f64::EPSILON;
            for x in d.iter_mut() {
                *x *= k as f64 / total * nudge;
            }
            let mut d2: Vec<f64> = d.iter().map(|x| x * x).collect();
            let sum = unordered_sum(d2.iter().copied());
            let (below, at_least) = (sum_below_k(sum, k), sum_at_least_k(sum, k));
            d2.sort_by(f64::total_cmp);
            let canonical = sigma(&d2, k);
            assert!(!below || canonical < 1.0, "k = {k}: σ = {canonical}");
            assert!(!at_least || canonical >= 1.0, "k = {k}: σ = {canonical}");
            claimed += below as usize + at_least as usize;
            let half: Vec<f64> = d2.iter().map(|x| x * 0.25).collect();
            assert!(
                surely_below_k(half.into_iter(), k),
                "σ ≈ 0.5 must be claimed"
            );
            let double = unordered_sum(d2.iter().map(|x| x * 4.0));
            assert!(sum_at_least_k(double, k), "σ ≈ 2 must be claimed");
        }
        // Sums this close to k are left to the canonical order.
        assert_eq!(claimed, 0);
    }

    /// Offering candidates to unordered contents keeps the k smallest,
    /// whenever they are settled, and sorting them gives what sorted
    /// pushes give, ids included.
    #[test]
    fn unordered_kbest_keeps_the_same_k_smallest() {
        let ds = [25.0, 1.0, 16.0, 0.0, 9.0, 4.0, 36.0, 0.25, 2.0];
        for settle_every in [1, 2, 100] {
            let mut sorted = KBest::new(4);
            let mut unordered = KBest::new(4);
            unordered.set_unordered(&[(49.0, 100), (64.0, 101)]);
            assert_eq!(unordered.worst2(), f64::INFINITY);
            for (i, &d) in ds.iter().enumerate() {
                sorted.push(d, i as u32);
                unordered.offer(d, i as u32);
                if i % settle_every == 0 {
                    unordered.settle();
                    if unordered.is_full() {
                        let max = unordered.as_slice().iter().copied().fold(0.0, f64::max);
                        assert_eq!(unordered.worst2(), max);
                    }
                }
            }
            unordered.settle();
            assert!(!unordered.is_sorted());
            assert_eq!(sorted.worst2(), unordered.worst2());
            unordered.sort();
            assert_eq!(unordered.as_slice(), sorted.as_slice());
            assert_eq!(unordered.ids(), sorted.ids());
            assert_eq!(unordered.sigma(), sorted.sigma());
        }
    }

    /// `judge` on unordered contents reaches the verdict sorting would.
    #[test]
    fn judge_decides_unordered_contents_like_sorted_ones() {
        for scale in [0.1, 0.5, 0.99, 1.0, 1.01, 2.0] {
            let d2: Vec<f64> = (1..=10).map(|i| (scale * i as f64 / 5.5).powi(2)).collect();
            for bound in [0.5, 3.0, f64::INFINITY] {
                let mut sorted = KBest::new(10);
                sorted.load(&d2, true);
                let mut rev: Vec<(f64, u32)> = d2.iter().rev().map(|&d| (d, 0)).collect();
                rev.rotate_left(3);
                let mut unordered = KBest::new(10);
                unordered.set_unordered(&rev);
                let a = judge(&mut sorted, bound, Goal::Decide).map(Verdict::accepted);
                let b = judge(&mut unordered, bound, Goal::Decide).map(Verdict::accepted);
                assert_eq!(a, b, "scale {scale}, bound {bound}");
            }
        }
    }

    #[test]
    fn lower_bound_never_exceeds_sigma_of_a_completion() {
        let found = [0.04, 0.16];
        // Completing with points at the bound gives exactly the lower bound.
        let lb = lower_bound(&found, 4, 0.5);
        assert_eq!(lb, sigma(&[0.04, 0.16, 0.25, 0.25], 4));
    }
}
