//! The parallel schedule of the replay (docs/filter.md, "The replay"):
//! exact, and the same bytes for any thread count.
//!
//! Parallelism that cannot change results: T only grows, and a larger T can
//! only lower σ. A batch of consecutive samples is searched in parallel
//! against an earlier state of T; then, in file order, a sample found
//! accepted stays accepted, and any other is completed with the points
//! stored since that state (see [`NeighbourIndex::recheck`]) before it is
//! decided. The in-order pass over batch b overlaps the search of batch
//! b + 1, which therefore reads a copy of T one batch behind, and the
//! preparation of batch b + 2 (classification and joint-space points,
//! which need no T; a batch is sorted into its search order when its
//! search starts). Searches
//! likely to fail against that copy may be left to the in-order pass
//! ([`super::deferral::Deferral`]), which searches the current T instead. The final pass
//! searches a fixed T, so it is parallel as is.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::sync::atomic::Ordering::Release;
use std::time::Instant;

use crate::par::prelude::*;

use super::Sigmas;
use super::accepted_sigma::Accepted;
use super::batch::{Batch, SUB_BLOCK, Worker};
use super::deferral::Deferral;
use super::in_order::{Streaming, decide_in_order};
use super::index::NeighbourIndex;
use super::seeds::{SeedCache, SeedKeys};
use super::sigma::{KBest, Verdict};
use super::{Decision, FilterCounts, FilterResult, Params};
use crate::dump::{Header, Record};
use crate::progress::Progress;

pub(super) fn replay<const D: usize, I: NeighbourIndex<D>>(
    records: &[Record],
    header: &Header,
    params: &Params,
    make_index: impl Fn() -> I,
    progress: &dyn Progress,
) -> FilterResult {
    let k = params.k;
    let exact = params.exact_sigma;
    let n = records.len();
    let mut decisions = vec![Decision::Invalid as u8; n];
    let mut sigma = exact.any().then(|| Sigmas::new(exact, n));
    let mut counts = FilterCounts {
        records: n as u64,
        ..Default::default()
    };
    let mut stored_at: Vec<u64> = Vec::new();

    let t0 = Instant::now();
    let batch = params.batch.max(SUB_BLOCK);
    // Two copies of T: `index` is current; `lagging` trails it by one batch.
    // While one worker decides batch b in order (inserting into `index`)
    // and then prepares batch b + 2, the others search batch b + 1 against
    // `lagging` (each side helps the other when done); the rechecks then
    // offer everything stored since, so the lag changes no result. The
    // serial steps (the in-order pass, the sort of a batch's search order)
    // thus overlap parallel work.
    let mut index = make_index();
    let mut lagging = make_index();
    // This batch (decided in order), the next (searched), the one after
    // (prepared); rotated after each batch.
    let mut batches: [Batch<D>; 3] = std::array::from_fn(|_| Batch::new(batch, k));
    let seed_keys = SeedKeys::new(header, k);
    let mut in_order_worker = Worker::new(k, Arc::new(SeedCache::new(k, seed_keys.slots)));
    let range = |start: usize| start..(start + batch).min(n);
    let mut deferral = Deferral::new(params.deferral);
    let workers = Worker::<I::Scratch>::per_thread(k, seed_keys.slots);
    for (j, start) in (0..n).step_by(batch).take(2).enumerate() {
        batches[j].prepare(
            &records[range(start)],
            &lagging,
            header,
            params.space,
            seed_keys,
        );
    }
    if n > 0 {
        // Nothing is stored yet: the first batch is decided in order
        // whatever its search finds.
        batches[0].search(&lagging, k, 0.0, &workers);
    }
    for start in (0..n).step_by(batch) {
        let m = range(start).len();
        let [cur, next, after] = &mut batches;
        let mut out = Streaming {
            decisions: &mut decisions,
            counts: &mut counts,
            stored_at: &mut stored_at,
        };
        let (lagging_ref, workers) = (&lagging, &workers);
        let share = deferral.share;
        // Set when this batch's in-order pass and the preparation after it
        // are done, and when the next batch's search is.
        let (decided, searched) = (&AtomicBool::new(false), &AtomicBool::new(false));
        // The search job is pushed first, so it is the one an idle thread
        // steals; the preparation waits on this thread's own queue, taken
        // by whichever thread runs out of work first. The thread that owns
        // the join thus mostly finishes last, and nobody sleeps on a latch.
        // Each side then waits for the other ([`wait_for`]), helping with
        // what is left, so the searching thread is awake for the next batch.
        let ((in_order, deferred), search) = crate::par::join(
            || {
                let in_order = crate::par::join(
                    || {
                        let t = Instant::now();
                        let deferred = decide_in_order(
                            cur,
                            start,
                            m,
                            &mut index,
                            &mut in_order_worker,
                            &mut out,
                        );
                        (t.elapsed().as_secs_f64(), deferred)
                    },
                    || {
                        if start + 2 * batch < n {
                            let recs = &records[range(start + 2 * batch)];
                            after.prepare(recs, lagging_ref, header, params.space, seed_keys);
                        }
                    },
                )
                .0;
                decided.store(true, Release);
                crate::par::wait_for(searched);
                in_order
            },
            || {
                let t = Instant::now();
                if start + batch < n {
                    next.search(lagging_ref, k, share, workers);
                }
                let search = t.elapsed().as_secs_f64();
                searched.store(true, Release);
                crate::par::wait_for(decided);
                search
            },
        );
        deferral.update(in_order, search, deferred);
        for id in lagging.len()..index.len() {
            lagging.insert(*index.point(id as u32));
        }
        batches.rotate_left(1);
        progress.inc(m as u64);
    }
    drop(lagging);
    if let Some(sigma) = sigma.as_mut() {
        let accepted = Accepted {
            records,
            space: params.space,
            k,
            stored_at: &stored_at,
            decisions: &decisions,
            exact,
        };
        let pixels = header.pixels() * header.frames as usize;
        accepted.find_sigma(&index, sigma, pixels);
    }
    let streaming_seconds = t0.elapsed().as_secs_f64();

    // Final pass: every stored point against T without itself.
    let t1 = Instant::now();
    let finals: Vec<Verdict> = (0..index.len() as u32)
        .into_par_iter()
        .map_init(
            || (KBest::new(k), I::Scratch::default()),
            |(kb, scratch), id| {
                let goal = exact.goal(stored_at[id as usize] as usize);
                index
                    .search(index.point(id), Some(id), goal, kb, scratch)
                    .verdict
            },
        )
        .collect();
    for (&rec, v) in stored_at.iter().zip(&finals) {
        if let (Some(sig), Some(s), true) = (sigma.as_mut(), v.sigma(), exact.wants(rec as usize)) {
            sig.set(rec as usize, s);
        }
        if v.accepted() {
            decisions[rec as usize] = Decision::AcceptedFinal as u8;
            counts.accepted_final += 1;
        } else {
            counts.rejected += 1;
        }
    }
    counts.stored = index.len() as u64;
    if let Some(s) = sigma.as_mut() {
        s.finish();
    }
    FilterResult {
        decisions,
        sigma,
        counts,
        streaming_seconds,
        final_seconds: t1.elapsed().as_secs_f64(),
    }
}
