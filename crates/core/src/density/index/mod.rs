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

    /// Completes an earlier search `prev` (whose distances are in `kb`) with
    /// the points inserted since, those with id ≥ `first_new`.
    fn recheck(
        &self,
        q: &[f32; D],
        first_new: u32,
        prev: Found,
        goal: Goal,
        kb: &mut KBest,
        scratch: &mut Self::Scratch,
    ) -> Found;
}

/// Which index the filter runs on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum IndexKind {
    /// Uniform grid over the image (and time) axes with an exact ring search.
    Grid,
    /// kiddo's mutable k-d tree, searched exactly in f64.
    Kdtree,
}

impl std::fmt::Display for IndexKind {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str(match self {
            IndexKind::Grid => "grid",
            IndexKind::Kdtree => "kdtree",
        })
    }
}

impl std::str::FromStr for IndexKind {
    type Err = String;
    fn from_str(s: &str) -> Result<IndexKind, String> {
        match s {
            "grid" => Ok(IndexKind::Grid),
            "kdtree" => Ok(IndexKind::Kdtree),
            _ => Err(format!("unknown index {s:?} (grid or kdtree)")),
        }
    }
}

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
