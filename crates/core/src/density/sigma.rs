//! σ(s, T): the mean distance from a sample to its k nearest stored points
//! (docs/filter.md, F5), and the bounds that let a search stop early
//! without changing any decision.

pub use super::kbest::KBest;

/// The canonical σ (docs/filter.md §2) from the k smallest squared distances, sorted
/// ascending: their square roots added one at a time from the smallest in
/// f64 and divided by k; +∞ when fewer than k are given. Every σ in this
/// crate comes from this function, so the search path that found the
/// neighbours cannot change the bits.
///
/// ```
/// use pathdensity_core::density::sigma::sigma;
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

/// The square roots of `d2` added in an order of our choosing: four
/// partial sums over consecutive lanes, which the compiler turns into
/// packed square roots and additions.
#[inline]
pub fn unordered_sum(d2: &[f64]) -> f64 {
    let mut s = [0.0f64; 4];
    let chunks = d2.chunks_exact(4);
    let rest = chunks.remainder();
    for c in chunks {
        for j in 0..4 {
            s[j] += c[j].sqrt();
        }
    }
    for (j, &x) in rest.iter().enumerate() {
        s[j] += x.sqrt();
    }
    (s[0] + s[1]) + (s[2] + s[3])
}

/// The relative margin that separates a sum of k non-negative values added
/// in any order from the exact and the canonical ones: any two orders
/// differ by at most 2γ₍k−1₎ ≈ 2k·2⁻⁵³ of the sum; k·2⁻⁴⁰ covers that and
/// the final division for any k ≤ 2³⁰.
#[inline]
fn order_margin(k: usize) -> f64 {
    debug_assert!(k <= 1 << 30);
    k as f64 * f64::EPSILON * 4096.0
}

/// What k squared distances, in any order, prove about their canonical σ
/// ([`sigma`]) on their own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sum {
    /// σ < 1: any k stored points this close accept the sample.
    BelowK,
    /// σ ≥ 1: rejected, if they are the k nearest.
    AtLeastK,
    /// Too close to 1 to tell without the canonical order.
    Unknown,
}

/// Classifies k squared distances given in any order (see [`Sum`]) from
/// their [`unordered_sum`], with a margin of `order_margin` on either
/// side of k, so no order of additions can flip it.
///
/// Cheaper tests without square roots (Σd² < k proves σ < 1 since the mean
/// is at most the root mean square; Σd² ≥ k·√d²_max proves σ ≥ 1) were
/// measured on the benchmark dump and rarely decide: the k nearest spread
/// too widely. They cost more than they saved.
///
/// ```
/// use pathdensity_core::density::sigma::{Sum, classify};
/// assert_eq!(classify(&[0.25, 0.25], 2), Sum::BelowK);
/// assert_eq!(classify(&[4.0, 1.0], 2), Sum::AtLeastK);
/// assert_eq!(classify(&[1.0, 1.0], 2), Sum::Unknown);
/// ```
#[inline]
pub fn classify(d2: &[f64], k: usize) -> Sum {
    debug_assert_eq!(d2.len(), k);
    let m = order_margin(k);
    let kf = k as f64;
    let sum = unordered_sum(d2);
    if sum < kf * (1.0 - m) {
        Sum::BelowK
    } else if sum >= kf * (1.0 + m) {
        Sum::AtLeastK
    } else {
        Sum::Unknown
    }
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
    if goal == Goal::Decide && !kb.is_sorted() {
        match kb.classify() {
            Sum::BelowK => return Some(Verdict::Accept),
            // The k found are the k nearest, and their σ ≥ 1.
            Sum::AtLeastK if complete => return Some(Verdict::Reject),
            _ => {}
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

    /// `classify` never claims σ < 1 or σ ≥ 1 when the canonical σ says
    /// otherwise, on sums within a few ulps of k (where the orders can
    /// disagree), and it does claim it when σ is clearly below or above 1.
    #[test]
    fn unordered_sums_never_contradict_the_canonical_sigma() {
        let mut unit = crate::synth::test_units(1);
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
            let sum = classify(&d2, k);
            d2.sort_by(f64::total_cmp);
            let canonical = sigma(&d2, k);
            match sum {
                Sum::BelowK => assert!(canonical < 1.0, "k = {k}: σ = {canonical}"),
                Sum::AtLeastK => assert!(canonical >= 1.0, "k = {k}: σ = {canonical}"),
                Sum::Unknown => {}
            }
            claimed += (sum != Sum::Unknown) as usize;
            let half: Vec<f64> = d2.iter().map(|x| x * 0.25).collect();
            assert_eq!(classify(&half, k), Sum::BelowK, "σ ≈ 0.5");
            let double: Vec<f64> = d2.iter().map(|x| x * 4.0).collect();
            assert_eq!(classify(&double, k), Sum::AtLeastK, "σ ≈ 2");
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
            unordered.set_unordered(&[(64.0, 101), (49.0, 100)], false);
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

    /// For any k, the unordered contents keep their largest last and hold
    /// the k smallest of everything offered or pushed; sorting them gives
    /// them ascending.
    #[test]
    fn unordered_kbest_holds_the_k_smallest_for_any_k() {
        let mut unit = crate::synth::test_units(7);
        // Coarse values, so that ties occur.
        let mut next = || (unit() * 1000.0).floor() / 64.0;
        for k in [1, 2, 3, 4, 5, 7, 13, 50, 100] {
            let mut kb = KBest::new(k);
            let first: Vec<(f64, u32)> = (0..k as u32).map(|i| (next(), i)).collect();
            kb.set_unordered(&first, false);
            let mut all: Vec<f64> = first.iter().map(|c| c.0).collect();
            for round in 0..40u32 {
                for j in 0..(round % 11) {
                    let d = next();
                    all.push(d);
                    if j % 2 == 0 {
                        kb.offer(d, 1000 + round);
                    } else {
                        kb.settle();
                        kb.push(d, 1000 + round);
                    }
                }
                kb.settle();
                let max = kb.as_slice().iter().copied().fold(0.0, f64::max);
                assert_eq!(kb.as_slice()[k - 1], max, "k = {k}");
                let mut want = all.clone();
                want.sort_by(f64::total_cmp);
                let mut got = kb.as_slice().to_vec();
                got.sort_by(f64::total_cmp);
                assert_eq!(got, want[..k], "k = {k}");
            }
            kb.sort();
            let mut want = all.clone();
            want.sort_by(f64::total_cmp);
            assert_eq!(kb.as_slice(), &want[..k], "sorted, k = {k}");
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
                unordered.set_unordered(&rev, false);
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
