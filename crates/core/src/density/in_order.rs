//! The in-order pass: each record of a batch, in file order, completed
//! with the points stored since its parallel search ran, then decided and,
//! if rejected, stored. This is where the replay is sequential, as the
//! paper's algorithm is.

use super::Decision;
use super::FilterCounts;
use super::batch::{ACCEPTED, Batch, Worker};
use super::index::NeighbourIndex;
use super::sigma::Goal;
use crate::dump::Validity;

/// The streaming pass's results, filled in file order.
pub(super) struct Streaming<'a> {
    pub(super) decisions: &'a mut [u8],
    pub(super) counts: &'a mut FilterCounts,
    /// Record index of every stored point, by id.
    pub(super) stored_at: &'a mut Vec<u64>,
}

/// Sequential, in file order: completes each search of `batch` (records from
/// `start`) with the points stored since it ran, then decides and stores.
/// Before a search or a recheck it tries the k nearest of its last search,
/// as the parallel workers do: consecutive samples mostly share neighbours.
/// Returns how many deferred searches it ran.
#[allow(clippy::too_many_arguments)]
pub(super) fn decide_in_order<const D: usize, I: NeighbourIndex<D>>(
    batch: &Batch<D>,
    start: usize,
    m: usize,
    index: &mut I,
    worker: &mut Worker<I::Scratch>,
    out: &mut Streaming,
) -> usize {
    let Worker {
        kb, scratch, seeds, ..
    } = worker;
    let k = kb.k();
    let mut deferred = 0;
    for (i, &validity) in batch.validity[..m].iter().enumerate() {
        let rec = start + i;
        if validity != Validity::Valid {
            out.counts.invalid.add(validity);
            continue;
        }
        out.counts.valid += 1;
        let j = batch.pos[i] as usize;
        if batch.accepted[j] {
            out.decisions[rec] = Decision::AcceptedStreaming as u8;
            out.counts.accepted_streaming += 1;
            continue;
        }
        // Not accepted by the search: its verdict stands only if nothing
        // was stored since.
        let (slot, hit) = (&batch.slots[i], &batch.hits[j]);
        let settled = !hit.deferred && index.len() == batch.base as usize;
        if !settled {
            // Only the samples that need them visit the seeds: in a
            // pass-major dump every sample is a new pixel, and filing and
            // fetching seeds for the many the parallel search settled
            // took a third of the in-order pass (k = 10).
            seeds.visit(slot.key, slot.seed_key);
        }
        let found = if settled {
            hit.found
        } else if seeds.accept(&*index, &slot.p, k) {
            ACCEPTED
        } else if hit.deferred {
            deferred += 1;
            let found = index.search(&slot.p, None, Goal::Decide, kb, scratch);
            seeds.remember(kb, slot.key, slot.seed_key, &found);
            found
        } else {
            kb.load(&batch.kbuf[j * k..j * k + hit.klen], hit.sorted);
            index.recheck(&slot.p, batch.base, hit.found, kb, scratch)
        };
        if found.verdict.accepted() {
            out.decisions[rec] = Decision::AcceptedStreaming as u8;
            out.counts.accepted_streaming += 1;
        } else {
            index.insert(slot.p);
            out.stored_at.push(rec as u64);
            out.decisions[rec] = Decision::Rejected as u8;
        }
    }
    deferred
}
