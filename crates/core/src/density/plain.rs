//! The replay exactly as the paper states it (docs/filter.md, "The
//! replay"), one sample at a time, T scanned in full for every query. It is
//! the specification [`super::run`] must reproduce bit for bit (decisions
//! and σ), and the oracle the tests hold it to. Quadratic in |T|: for small
//! dumps only.

use std::time::Instant;

use super::sigma::sigma;
use super::{Decision, FilterCounts, FilterResult, FinalPass};
use crate::dump::{Header, Record, Validity};
use crate::joint::{JointSpace, dist2};

/// Replays `records` with k neighbours in `space`; every σ is kept.
pub fn replay(records: &[Record], header: &Header, space: &JointSpace, k: usize) -> FilterResult {
    replay_with(records, header, space, k, FinalPass::Stored)
}

/// [`replay`] with the final pass of `final_pass`.
pub fn replay_with(
    records: &[Record],
    header: &Header,
    space: &JointSpace,
    k: usize,
    final_pass: FinalPass,
) -> FilterResult {
    if header.animated() {
        replay_in::<6>(records, header, space, k, final_pass)
    } else {
        replay_in::<5>(records, header, space, k, final_pass)
    }
}

fn replay_in<const D: usize>(
    records: &[Record],
    header: &Header,
    space: &JointSpace,
    k: usize,
    final_pass: FinalPass,
) -> FilterResult {
    let n = records.len();
    let mut decisions = vec![Decision::Invalid as u8; n];
    let mut sigmas = vec![f64::NAN; n];
    let mut counts = FilterCounts {
        records: n as u64,
        ..FilterCounts::default()
    };
    // T: the stored samples' joint points, and which record each is.
    let mut stored: Vec<[f32; D]> = Vec::new();
    let mut stored_at: Vec<usize> = Vec::new();
    // Every valid sample's point (F6a's final pass needs them all), and
    // each stored sample's place among them.
    let mut all: Vec<[f32; D]> = Vec::new();
    let mut stored_in_all: Vec<usize> = Vec::new();

    // Step 1, streaming: a sample whose k nearest stored samples are on
    // average closer than 1 is accepted; any other joins T.
    let t0 = Instant::now();
    for (i, r) in records.iter().enumerate() {
        let v = r.validity(header);
        if v != Validity::Valid {
            counts.invalid.add(v);
            continue;
        }
        counts.valid += 1;
        let p = space.point::<D>(r);
        all.push(p);
        sigmas[i] = sigma_against(&p, &stored, None, k);
        if sigmas[i] < 1.0 {
            decisions[i] = Decision::AcceptedStreaming as u8;
            counts.accepted_streaming += 1;
        } else {
            decisions[i] = Decision::Rejected as u8;
            stored.push(p);
            stored_at.push(i);
            stored_in_all.push(all.len() - 1);
        }
    }
    let streaming_seconds = t0.elapsed().as_secs_f64();

    // Step 2, the final pass: each stored sample against all of T but
    // itself, with T fixed (F6a: against every valid sample but itself).
    let t1 = Instant::now();
    for (id, &i) in stored_at.iter().enumerate() {
        sigmas[i] = match final_pass {
            FinalPass::Stored => sigma_against(&stored[id], &stored, Some(id), k),
            FinalPass::All => sigma_against(&stored[id], &all, Some(stored_in_all[id]), k),
        };
        if sigmas[i] < 1.0 {
            decisions[i] = Decision::AcceptedFinal as u8;
            counts.accepted_final += 1;
        } else {
            counts.rejected += 1;
        }
    }
    counts.stored = stored.len() as u64;
    FilterResult {
        decisions,
        sigma: Some(super::Sigmas::Dense(sigmas)),
        counts,
        streaming_seconds,
        final_seconds: t1.elapsed().as_secs_f64(),
    }
}

/// σ(q, T): the mean distance from `q` to its k nearest points of `set`
/// (leaving out `skip`), +∞ when there are fewer than k.
fn sigma_against<const D: usize>(
    q: &[f32; D],
    set: &[[f32; D]],
    skip: Option<usize>,
    k: usize,
) -> f64 {
    let mut d2: Vec<f64> = set
        .iter()
        .enumerate()
        .filter(|&(id, _)| Some(id) != skip)
        .map(|(_, p)| dist2(p, q))
        .collect();
    d2.sort_by(f64::total_cmp);
    d2.truncate(k);
    sigma(&d2, k)
}
