//! σ(s, T): the mean distance from a sample to its k nearest stored points
//! (SPEC §3), and the bounds that let a search stop early without changing
//! any decision.

/// The k smallest squared distances seen so far, kept sorted ascending,
/// with the ids of their points.
///
/// Squared distances order exactly as distances (sqrt is correctly rounded,
/// hence monotone), so candidates never pay a square root: only the k that
/// enter σ do, when it is evaluated.
///
/// Invariant: `len ≤ k` and `d2[..len]` is sorted ascending.
#[derive(Clone, Debug)]
pub struct KBest {
    k: usize,
    len: usize,
    d2: Vec<f64>,
    /// The stored-point id of each distance (`u32::MAX` when unknown).
    ids: Vec<u32>,
    /// Bumped on every change, so callers can skip re-judging.
    version: u64,
    /// False after [`KBest::set_unordered`]: then only the set is known.
    sorted: bool,
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
        }
    }

    pub fn k(&self) -> usize {
        self.k
    }

    pub fn clear(&mut self) {
        self.len = 0;
        self.sorted = true;
    }

    /// Replaces the contents with the k nearest `(squared distance, id)` of
    /// a search that has already decided, in no order: their ids stay
    /// available, but nothing may be judged from them until the next
    /// [`KBest::clear`] or [`KBest::load`].
    pub fn set_unordered(&mut self, nearest: &[(f64, u32)]) {
        self.len = nearest.len();
        for (i, &(d2, id)) in nearest.iter().enumerate() {
            self.d2[i] = d2;
            self.ids[i] = id;
        }
        self.sorted = false;
        self.version += 1;
    }

    /// Replaces the contents with `sorted` squared distances (ascending, ≤ k
    /// values) of unknown points.
    pub fn load(&mut self, sorted: &[f64]) {
        self.len = sorted.len();
        self.d2[..self.len].copy_from_slice(sorted);
        self.ids[..self.len].fill(u32::MAX);
        self.sorted = true;
        self.version += 1;
    }

    /// The squared distances, ascending (see [`KBest::set_unordered`]).
    pub fn as_slice(&self) -> &[f64] {
        &self.d2[..self.len]
    }

    /// The ids of the points behind [`KBest::as_slice`] (`u32::MAX` for
    /// distances given to [`KBest::load`]).
    pub fn ids(&self) -> &[u32] {
        &self.ids[..self.len]
    }

    /// Changes whenever the contents change.
    pub fn version(&self) -> u64 {
        self.version
    }

    pub fn is_full(&self) -> bool {
        self.len == self.k
    }

    /// Offers one squared distance (from [`crate::joint::dist2`]).
    #[inline]
    pub fn push(&mut self, dist2: f64, id: u32) {
        debug_assert!(self.sorted);
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

    /// The k-th smallest squared distance so far, +∞ while fewer than k are
    /// known.
    #[inline]
    pub fn worst2(&self) -> f64 {
        debug_assert!(self.sorted);
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

    /// The canonical σ of the contents (+∞ while fewer than k).
    #[inline]
    pub fn sigma(&self) -> f64 {
        debug_assert!(self.sorted);
        sigma(self.as_slice(), self.k)
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

/// True when the square roots of `d2` (k values, any order) provably add
/// up to less than k in the canonical order, so that their canonical σ is
/// below 1. Any two orders of summing k non-negative values differ by at
/// most 2γ₍k−1₎ ≈ 2k·2⁻⁵³ of the sum; the margin k·2⁻⁴⁰ covers that and
/// the final division for any k ≤ 2³⁰.
#[inline]
pub fn surely_below_k(d2: impl Iterator<Item = f64>, k: usize) -> bool {
    debug_assert!(k <= 1 << 30);
    // Four partial sums: independent additions pipeline.
    let mut s = [0.0f64; 4];
    for (i, x) in d2.enumerate() {
        s[i & 3] += x.sqrt();
    }
    let kf = k as f64;
    (s[0] + s[1]) + (s[2] + s[3]) < kf * (1.0 - kf * f64::EPSILON * 4096.0)
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
#[inline]
pub fn judge(kb: &KBest, bound: f64, goal: Goal) -> Option<Verdict> {
    let k = kb.k();
    if kb.worst() <= bound || bound == f64::INFINITY {
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

    /// The unordered test never claims σ < 1 when the canonical σ is not,
    /// on sums within a few ulps of k (where the orders can disagree), and
    /// it does claim it when σ is clearly below 1.
    #[test]
    fn surely_below_k_implies_the_canonical_sigma_is_below_one() {
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
            let surely = surely_below_k(d2.iter().copied(), k);
            d2.sort_by(f64::total_cmp);
            let canonical = sigma(&d2, k);
            assert!(!surely || canonical < 1.0, "k = {k}: σ = {canonical}");
            claimed += surely as usize;
            let half: Vec<f64> = d2.iter().map(|x| x * 0.25).collect();
            assert!(
                surely_below_k(half.into_iter(), k),
                "σ ≈ 0.5 must be claimed"
            );
        }
        // Sums this close to k are left to the canonical order.
        assert_eq!(claimed, 0);
    }

    #[test]
    fn lower_bound_never_exceeds_sigma_of_a_completion() {
        let found = [0.04, 0.16];
        // Completing with points at the bound gives exactly the lower bound.
        let lb = lower_bound(&found, 4, 0.5);
        assert_eq!(lb, sigma(&[0.04, 0.16, 0.25, 0.25], 4));
    }
}
