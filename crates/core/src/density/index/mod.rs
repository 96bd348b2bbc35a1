//! Exact k-nearest searches over the growing stored set T.
//!
//! Every index returns the same verdicts: they differ only in how they find
//! candidates, never in how σ is computed (see [`super::sigma::sigma`]).

pub mod grid;
pub mod kdtree;
pub mod tile;

use super::sigma::{Goal, KBest, Verdict};

/// The result of one search.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Found {
    pub verdict: Verdict,
    /// Every stored point the search did not look at lies at distance ≥
    /// `bound` (+∞ when it looked at all of them).
    pub bound: f64,
    /// How far the search went, in index-specific units (grid rings).
    pub reach: u32,
}

/// An incremental, exact k-nearest index over joint-space points of
/// dimension `D`. Points get ids 0, 1, 2, … in insertion order.
pub trait NeighbourIndex<const D: usize>: Sync + Send {
    /// Per-worker working memory of the searches (caches, buffers). It
    /// never changes a result, only how fast it is found.
    type Scratch: Default + Send;

    /// Adds a point and returns its id. Never fails: identical points are
    /// distinct neighbours at distance 0.
    fn insert(&mut self, p: [f32; D]) -> u32;

    fn len(&self) -> usize;

    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn point(&self, id: u32) -> &[f32; D];

    /// A key shared by nearby queries; the filter searches a batch in key
    /// order so that consecutive searches share a worker's caches. Only
    /// speed depends on it.
    fn locality(&self, _q: &[f32; D]) -> u32 {
        0
    }

    /// Searches the k = `kb.k()` nearest stored points to `q`, skipping the
    /// point `exclude`. On return `kb` holds the nearest distances found.
    fn search(
        &self,
        q: &[f32; D],
        exclude: Option<u32>,
        goal: Goal,
        kb: &mut KBest,
        scratch: &mut Self::Scratch,
    ) -> Found;

    /// The k nearest to `q` among the points with ids below `before` (the
    /// T a sample met when the replay decided it), found exactly, as
    /// [`Goal::Exact`]: the σ map's searches, run once T is complete.
    fn search_before(
        &self,
        q: &[f32; D],
        before: u32,
        kb: &mut KBest,
        scratch: &mut Self::Scratch,
    ) -> Found;

    /// Completes an earlier search `prev` that only had to decide (whose
    /// distances are in `kb`) with the points inserted since, those with
    /// id ≥ `first_new`, and decides.
    fn recheck(
        &self,
        q: &[f32; D],
        first_new: u32,
        prev: Found,
        kb: &mut KBest,
        scratch: &mut Self::Scratch,
    ) -> Found;
}

/// Which index the filter runs on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IndexKind {
    /// Uniform grid over the image (and time) axes with an exact ring search.
    Grid,
    /// kiddo's mutable k-d tree, searched exactly in f64.
    Kdtree,
}

crate::names::named!(IndexKind, "index", { Grid => "grid", Kdtree => "kdtree" });

/// Offers `arena[first_new..]` to `kb`: the brute-force completion.
pub(crate) fn offer_suffix<const D: usize>(
    arena: &[[f32; D]],
    first_new: u32,
    q: &[f32; D],
    kb: &mut KBest,
) {
    for (p, id) in arena[first_new as usize..].iter().zip(first_new..) {
        kb.offer(crate::joint::dist2(p, q), id);
    }
}

#[cfg(test)]
mod tests {
    use super::grid::Grid;
    use super::kdtree::KdTree;
    use super::*;
    use crate::joint::dist2;

    /// Clustered points (so that grid searches go past their block and
    /// k-d tree searches past their first ask), with exact duplicates.
    fn points(n: usize) -> Vec<[f32; 5]> {
        let mut unit = crate::synth::test_units(99);
        let mut pts: Vec<[f32; 5]> = Vec::new();
        for i in 0..n {
            if i % 17 == 16 {
                pts.push(pts[i / 2]);
                continue;
            }
            let (cx, cy) = ((i % 5) as f64 * 9.0, (i % 3) as f64 * 7.0);
            let spread = if i % 4 == 0 { 12.0 } else { 1.5 };
            pts.push(std::array::from_fn(|j| match j {
                0 => (cx + unit() * spread) as f32,
                1 => (cy + unit() * spread) as f32,
                _ => (unit() * 2.0) as f32,
            }));
        }
        pts
    }

    /// `search_before` finds the k nearest of the points stored before a
    /// given id, as a sort of those points' distances does, on both
    /// indices, for any number of earlier points (fewer than k included).
    fn finds_the_k_nearest_stored_before<I: NeighbourIndex<5>>(mut index: I) {
        let pts = points(3000);
        for &p in &pts {
            index.insert(p);
        }
        let mut unit = crate::synth::test_units(5);
        let mut scratch = I::Scratch::default();
        for k in [1, 5, 50] {
            let mut kb = KBest::new(k);
            for before in [0, 1, k as u32 - 1, k as u32, 40, 301, 1777, 2999, 3000] {
                for _ in 0..20 {
                    let q: [f32; 5] =
                        std::array::from_fn(|j| (unit() * if j < 2 { 40.0 } else { 2.0 }) as f32);
                    let found = index.search_before(&q, before, &mut kb, &mut scratch);
                    let mut want: Vec<f64> = pts[..before as usize]
                        .iter()
                        .map(|p| dist2(p, &q))
                        .collect();
                    want.sort_by(f64::total_cmp);
                    want.truncate(k);
                    assert_eq!(kb.as_slice(), &want[..], "k {k}, before {before}");
                    assert_eq!(
                        found.verdict,
                        Verdict::Sigma(super::super::sigma::sigma(&want, k)),
                        "k {k}, before {before}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_grid_finds_the_k_nearest_stored_before() {
        finds_the_k_nearest_stored_before(Grid::<5>::new([60.0, 40.0, 1.0]));
    }

    #[test]
    fn a_kdtree_finds_the_k_nearest_stored_before() {
        finds_the_k_nearest_stored_before(KdTree::<5>::default());
    }
}
