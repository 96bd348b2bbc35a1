//! A grid built whole: every cell's points in one array, placed by chunks
//! of the items in parallel, with the ids and cells inserting them one by
//! one would give (F6a's grid over every sample).

use std::mem::MaybeUninit;

use super::{Cells, Grid};
use crate::density::index::tile::Entry;
use crate::par::prelude::*;

impl<const D: usize> Grid<D> {
    /// A grid built whole over `items`, searched and never inserted into,
    /// with every cell's points in one array and no second copy of them
    /// (4·D + 4 bytes a point). The points are `point(item)` for the items
    /// that have one, their ids in item order; `cell_point(item)` must give
    /// the same image (and time) coordinates, which fix the cell, and may
    /// skip the colour. The items are counted and placed in chunks, in
    /// parallel, each cell's points in id order: the grid inserting them
    /// one by one would make, for any number of threads. Also returns the
    /// (item, id) of the items `keep` picks, in item order.
    pub fn packed<T: Sync>(
        extent: [f64; 3],
        log2_side: i32,
        items: &[T],
        cell_point: impl Fn(&T) -> Option<[f32; D]> + Sync,
        point: impl Fn(&T) -> Option<[f32; D]> + Sync,
        keep: impl Fn(usize) -> bool + Sync,
    ) -> (Grid<D>, Vec<(usize, u32)>) {
        let chunks = crate::par::current_num_threads().max(1);
        Grid::packed_in(extent, log2_side, items, chunks, cell_point, point, keep)
    }

    /// [`Grid::packed`] with the items cut into `chunks` chunks.
    fn packed_in<T: Sync>(
        extent: [f64; 3],
        log2_side: i32,
        items: &[T],
        chunks: usize,
        cell_point: impl Fn(&T) -> Option<[f32; D]> + Sync,
        point: impl Fn(&T) -> Option<[f32; D]> + Sync,
        keep: impl Fn(usize) -> bool + Sync,
    ) -> (Grid<D>, Vec<(usize, u32)>) {
        let mut grid = Grid::empty(extent, log2_side);
        let cells = grid.cell_count();
        let chunk_len = items.len().div_ceil(chunks).max(1);
        let parts: Vec<&[T]> = items.chunks(chunk_len).collect();
        // How many points each chunk puts in each cell.
        let counts: Vec<Vec<u32>> = parts
            .par_iter()
            .map(|part| {
                let mut n = vec![0u32; cells];
                for p in part.iter().filter_map(&cell_point) {
                    n[grid.cell(&p)] += 1;
                }
                n
            })
            .collect();
        let per_part: Vec<usize> = counts
            .iter()
            .map(|n| n.iter().map(|&c| c as usize).sum())
            .collect();
        let total: usize = per_part.iter().sum();
        assert!(
            total <= u32::MAX as usize,
            "more than 2^32 samples in one grid"
        );
        // Cell by cell, each chunk's share of the array, in chunk order.
        let mut entries: Vec<Entry<D>> = Vec::with_capacity(total);
        let mut starts = Vec::with_capacity(cells + 1);
        let mut slots: Vec<Vec<&mut [MaybeUninit<Entry<D>>]>> =
            parts.iter().map(|_| Vec::with_capacity(cells)).collect();
        let mut rest = &mut entries.spare_capacity_mut()[..total];
        let mut at = 0;
        for c in 0..cells {
            starts.push(at);
            for (part, n) in slots.iter_mut().zip(&counts) {
                let (mine, tail) = std::mem::take(&mut rest).split_at_mut(n[c] as usize);
                part.push(mine);
                rest = tail;
                at += n[c] as usize;
            }
        }
        starts.push(at);
        drop(counts);
        let first_ids = per_part.iter().scan(0usize, |id, &n| {
            let first = *id;
            *id += n;
            Some(first as u32)
        });
        let jobs: Vec<_> = slots.into_iter().zip(first_ids).enumerate().collect();
        let kept: Vec<Vec<(usize, u32)>> = jobs
            .into_par_iter()
            .map(|(j, (mut slots, mut id))| {
                let mut kept = Vec::new();
                for (i, item) in (j * chunk_len..).zip(parts[j]) {
                    let Some(p) = point(item) else { continue };
                    let cell = grid.cell(&p);
                    let (slot, tail) = std::mem::take(&mut slots[cell])
                        .split_first_mut()
                        .expect("point and cell_point put an item in the same cell");
                    slot.write(Entry { p, id });
                    slots[cell] = tail;
                    if keep(i) {
                        kept.push((i, id));
                    }
                    id += 1;
                }
                assert!(
                    slots.iter().all(|s| s.is_empty()),
                    "point and cell_point give points to the same items"
                );
                kept
            })
            .collect();
        // SAFETY: the first `total` slots were cut into disjoint pieces that
        // cover them all, and every piece was written to its end (the
        // assertion above, in every job).
        unsafe { entries.set_len(total) };
        grid.cells = Cells::Packed { entries, starts };
        grid.len = total;
        (grid, kept.into_iter().flatten().collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::density::index::NeighbourIndex;
    use crate::density::index::tile::Tile;
    use crate::density::sigma::{Goal, KBest};

    /// Clusters and lone points far apart (so that some searches fall back
    /// to scanning every point), and items without a point: a packed
    /// grid, however many chunks build it, holds in each cell the points
    /// and ids inserting them one by one gives, keeps the items asked for
    /// with their ids, and gives every verdict and σ the growing grid
    /// gives, for both goals.
    #[test]
    fn a_packed_grid_is_the_grid_of_inserting_one_by_one() {
        let mut unit = crate::synth::test_units(1);
        let mut next = || unit() as f32;
        let mut items: Vec<Option<[f32; 5]>> = Vec::new();
        for c in 0..6 {
            let (cx, cy) = (40.0 * c as f32, 7.0 * c as f32);
            for i in 0..40 {
                let p = [cx + next(), cy + next(), next(), next(), next()];
                items.push((i % 7 != 3).then_some(p));
            }
        }
        for i in 0..5 {
            items.push(Some([
                250.0 * next(),
                250.0 * next(),
                9.0 * i as f32,
                0.0,
                0.0,
            ]));
        }
        let extent = [256.0, 256.0, 1.0];
        let mut growing = Grid::<5>::with_side(extent, -1);
        let mut want_kept = Vec::new();
        for (i, p) in items.iter().enumerate() {
            if let Some(p) = p {
                let id = growing.insert(*p);
                if i % 5 == 0 {
                    want_kept.push((i, id));
                }
            }
        }
        let image = |p: &Option<[f32; 5]>| p.map(|p| [p[0], p[1], 0.0, 0.0, 0.0]);
        for chunks in [1, 2, 3, 8, 1000] {
            let (packed, kept) =
                Grid::packed_in(extent, -1, &items, chunks, image, |p| *p, |i| i % 5 == 0);
            assert_eq!(kept, want_kept, "{chunks} chunks");
            assert_eq!(packed.len(), growing.len());
            for c in 0..growing.cell_count() {
                let ids = |g: &Grid<5>| g.points(c).iter().map(|e| (e.id, e.p)).collect::<Vec<_>>();
                assert_eq!(ids(&packed), ids(&growing), "cell {c}, {chunks} chunks");
            }
        }
        let (packed, _) = Grid::packed(extent, -1, &items, image, |p| *p, |_| false);
        let points: Vec<[f32; 5]> = items.iter().flatten().copied().collect();
        for k in [1, 4, 12] {
            for goal in [Goal::Decide, Goal::Exact] {
                for (id, p) in points.iter().enumerate() {
                    let id = Some(id as u32);
                    let (mut a, mut b) = (KBest::new(k), KBest::new(k));
                    let (mut ta, mut tb) = (Tile::default(), Tile::default());
                    let va = growing.search(p, id, goal, &mut a, &mut ta).verdict;
                    let vb = packed.search(p, id, goal, &mut b, &mut tb).verdict;
                    assert_eq!(va, vb, "point {id:?}, k {k}, {goal:?}");
                }
            }
        }
    }
}
