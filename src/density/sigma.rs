//! σ(s, T): the mean distance from a sample to its k nearest stored points
//! (SPEC §3), and the bounds that let a search stop early without changing
//! any decision.

/// The k smallest distances seen so far, kept sorted ascending.
///
/// Candidates arrive as squared distances and are screened against the
/// square of the current k-th distance (with a margin that can only let
/// extra candidates through), so most never pay a square root.
///
/// Invariant: `len ≤ k` and `d[..len]` is sorted ascending.
#[derive(Clone, Debug)]
pub struct KBest {
    k: usize,
    len: usize,
    d: Vec<f64>,
    /// Squared distances above this cannot enter.
    screen2: f64,
    /// Bumped on every change, so callers can skip re-judging.
    version: u64,
}

impl KBest {
    pub fn new(k: usize) -> KBest {
        assert!(k >= 1, "k must be at least 1");
        KBest {
            k,
            len: 0,
            d: vec![0.0; k],
            screen2: f64::INFINITY,
            version: 0,
        }
    }

    pub fn k(&self) -> usize {
        self.k
    }

    pub fn clear(&mut self) {
        self.len = 0;
        self.screen2 = f64::INFINITY;
    }

    /// Replaces the contents with `sorted` distances (ascending, ≤ k values).
    pub fn load(&mut self, sorted: &[f64]) {
        self.len = sorted.len();
        self.d[..self.len].copy_from_slice(sorted);
        self.update_screen();
    }

    /// The distances, ascending.
    pub fn as_slice(&self) -> &[f64] {
        &self.d[..self.len]
    }

    /// Changes whenever the contents change.
    pub fn version(&self) -> u64 {
        self.version
    }

    pub fn is_full(&self) -> bool {
        self.len == self.k
    }

    fn update_screen(&mut self) {
        self.screen2 = if self.is_full() {
            // sqrt is correctly rounded, so a square above w² (1 + 2^-40)
            // has a root ≥ w and could not enter anyway.
            let w = self.d[self.k - 1];
            w * w * (1.0 + f64::EPSILON * 4096.0)
        } else {
            f64::INFINITY
        };
    }

    /// Offers one squared distance (from [`crate::joint::dist2`]).
    #[inline]
    pub fn push(&mut self, dist2: f64) {
        if dist2 > self.screen2 {
            return;
        }
        let dist = dist2.sqrt();
        let mut i = self.len;
        if i == self.k {
            if dist >= self.d[i - 1] {
                return;
            }
            i -= 1;
        } else {
            self.len += 1;
        }
        while i > 0 && self.d[i - 1] > dist {
            self.d[i] = self.d[i - 1];
            i -= 1;
        }
        self.d[i] = dist;
        self.version += 1;
        if self.len == self.k {
            self.update_screen();
        }
    }

    /// The k-th smallest distance so far, +∞ while fewer than k are known.
    #[inline]
    pub fn worst(&self) -> f64 {
        if self.is_full() {
            self.d[self.k - 1]
        } else {
            f64::INFINITY
        }
    }
}

/// The canonical σ (SPEC §3): the k smallest distances, sorted ascending,
/// added one at a time from the smallest in f64 and divided by k; +∞ when
/// fewer than k are given. Every σ in this crate comes from this function,
/// so the search path that found the neighbours cannot change the bits.
///
/// ```
/// use pathdensity::density::sigma::sigma;
/// assert_eq!(sigma(&[0.5, 1.0, 1.5], 3), 1.0);
/// assert_eq!(sigma(&[0.5], 3), f64::INFINITY);
/// ```
#[inline]
pub fn sigma(sorted: &[f64], k: usize) -> f64 {
    if sorted.len() < k {
        return f64::INFINITY;
    }
    let mut s = 0.0f64;
    for &d in &sorted[..k] {
        s += d;
    }
    s / k as f64
}

/// A lower bound on σ when every point not yet seen lies at distance ≥
/// `bound`: the i-th true distance is at least min(found_i, bound). It is
/// computed with the same arithmetic as [`sigma`], and f64 addition is
/// monotone, so `lower_bound(..) ≥ 1` proves the exact σ ≥ 1.
#[inline]
pub fn lower_bound(sorted: &[f64], k: usize, bound: f64) -> f64 {
    let mut s = 0.0f64;
    for i in 0..k {
        let d = sorted.get(i).copied().unwrap_or(f64::INFINITY);
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
        return Some(Verdict::Sigma(sigma(kb.as_slice(), k)));
    }
    if goal == Goal::Decide {
        if kb.is_full() && sigma(kb.as_slice(), k) < 1.0 {
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
            kb.push(d);
        }
        assert_eq!(kb.as_slice(), &[0.0, 0.0, 1.0]);
    }

    #[test]
    fn lower_bound_never_exceeds_sigma_of_a_completion() {
        let found = [0.2, 0.4];
        // Completing with points at the bound gives exactly the lower bound.
        let lb = lower_bound(&found, 4, 0.7);
        assert_eq!(lb, sigma(&[0.2, 0.4, 0.7, 0.7], 4));
    }
}
