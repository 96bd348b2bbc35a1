//! kiddo's mutable k-d tree as an exact, independent index.
//!
//! Candidates come from kiddo's `nearest_n` with an f64 squared-Euclidean
//! metric over the f32 points; their distances are then recomputed with the
//! canonical [`crate::joint::dist2`], so σ is bit-identical to the grid's.
//!
//! kiddo's `add` fails when a leaf cannot split (it picks the split axis by
//! level, so more than a bucket of points sharing x and y is enough). Such
//! points go to an overflow list that every search scans.

use std::num::NonZeroUsize;

use kiddo::{MutableKdTree, SquaredEuclidean};

use super::{Found, NeighbourIndex, offer_suffix};
use crate::density::sigma::{Goal, KBest, judge};
use crate::joint::dist2;

pub struct KdTree<const D: usize> {
    tree: MutableKdTree<f32, D>,
    overflow: Vec<u32>,
    arena: Vec<[f32; D]>,
}

impl<const D: usize> Default for KdTree<D> {
    fn default() -> Self {
        KdTree {
            tree: MutableKdTree::default(),
            overflow: Vec::new(),
            arena: Vec::new(),
        }
    }
}

impl<const D: usize> KdTree<D> {
    /// Points the tree refused and the searches scan linearly.
    pub fn overflow_len(&self) -> usize {
        self.overflow.len()
    }

    /// The ids of kiddo's `want` (≥ 1) nearest points of the tree to `q`.
    fn nearest_in_tree(&self, q: &[f32; D], want: usize) -> Vec<u32> {
        let n = NonZeroUsize::new(want).expect("want ≥ 1");
        let hits = self
            .tree
            .query(q)
            .nearest_n::<SquaredEuclidean<f64>>(n)
            .execute();
        hits.into_iter().map(|h| h.item).collect()
    }
}

/// The verdict of a search that looked at every candidate.
fn complete(kb: &mut KBest, goal: Goal) -> Found {
    let verdict = judge(kb, f64::INFINITY, goal).expect("a complete search always decides");
    Found {
        verdict,
        bound: f64::INFINITY,
        reach: 0,
    }
}

impl<const D: usize> NeighbourIndex<D> for KdTree<D> {
    type Scratch = ();

    fn insert(&mut self, p: [f32; D]) -> u32 {
        let id = u32::try_from(self.arena.len()).expect("more than 2^32 stored samples");
        if self.tree.add(&p, id).is_err() {
            self.overflow.push(id);
        }
        self.arena.push(p);
        id
    }

    fn len(&self) -> usize {
        self.arena.len()
    }

    fn point(&self, id: u32) -> &[f32; D] {
        &self.arena[id as usize]
    }

    fn search(
        &self,
        q: &[f32; D],
        exclude: Option<u32>,
        goal: Goal,
        kb: &mut KBest,
        _: &mut (),
    ) -> Found {
        kb.clear();
        let in_tree = self.arena.len() - self.overflow.len();
        if in_tree > 0 {
            let want = (kb.k() + exclude.is_some() as usize).min(in_tree);
            for id in self.nearest_in_tree(q, want) {
                if Some(id) != exclude {
                    kb.push(dist2(&self.arena[id as usize], q), id);
                }
            }
        }
        for &id in &self.overflow {
            if Some(id) != exclude {
                kb.push(dist2(&self.arena[id as usize], q), id);
            }
        }
        complete(kb, goal)
    }

    fn search_before(&self, q: &[f32; D], before: u32, kb: &mut KBest, _: &mut ()) -> Found {
        kb.clear();
        let earlier = (before as usize).min(self.arena.len());
        let in_tree = self.arena.len() - self.overflow.len();
        // The n nearest of the tree hold the k nearest of the points stored
        // before `before` once k of them are such points: ask for more
        // until they are, or scan those points when there are few.
        let mut want = kb.k().min(in_tree);
        loop {
            if want == 0 || earlier <= 4 * want {
                for (p, id) in self.arena[..earlier].iter().zip(0u32..) {
                    kb.push(dist2(p, q), id);
                }
                break;
            }
            let mut ids = self.nearest_in_tree(q, want);
            ids.retain(|&id| id < before);
            if ids.len() >= kb.k() || want == in_tree {
                for id in ids {
                    kb.push(dist2(&self.arena[id as usize], q), id);
                }
                for &id in self.overflow.iter().filter(|&&id| id < before) {
                    kb.push(dist2(&self.arena[id as usize], q), id);
                }
                break;
            }
            want = (want * 4).min(in_tree);
        }
        complete(kb, Goal::Exact)
    }

    fn recheck(
        &self,
        q: &[f32; D],
        first_new: u32,
        prev: Found,
        kb: &mut KBest,
        scratch: &mut (),
    ) -> Found {
        // The previous search was complete, so only the new points can matter.
        let new = self.arena.len() - first_new as usize;
        if new <= 4096 {
            offer_suffix(&self.arena, first_new, q, kb);
            let verdict =
                judge(kb, prev.bound, Goal::Decide).expect("a complete search always decides");
            Found { verdict, ..prev }
        } else {
            self.search(q, None, Goal::Decide, kb, scratch)
        }
    }
}
