//! What statmc's window reads of every pixel, made once from the pixels'
//! statistics, and which pairs of pixels average each other.

use super::features::Features;
use super::welch::{Kernel, agree};
use super::{Guide, NOISIER, Stats};
use crate::par::prelude::*;

/// What the window reads of every pixel, one array per field: a run of a
/// row's pixels is one slice of each, so the window's loop along the run
/// runs in vector registers.
pub(super) struct Fields {
    pub(super) n: Vec<u32>,
    /// Mean of the samples.
    pub(super) mean: [Vec<f64>; 3],
    /// Mean of the transformed samples.
    pub(super) y_mean: [Vec<f64>; 3],
    /// [`Stats::se2`].
    pub(super) se2: [Vec<f64>; 3],
    /// Σ over the channels of `se2`: how noisy the pixel's mean is.
    pub(super) spread: Vec<f64>,
    /// [`spread_limits`].
    pub(super) limit: Vec<f64>,
    /// [`patch_spreads`]: each pixel's 3 × 3 patch's spread where the whole
    /// patch is on the film with two samples or more a pixel, else NaN.
    pub(super) patch_spread: Vec<f64>,
    /// The renderer's features, where given.
    pub(super) features: Option<Features>,
}

impl Fields {
    /// What the test reads of each pixel, made once: s²/n would otherwise
    /// be divided out again for each of the (2R + 1)² pixels around it.
    pub(super) fn new<S: AsRef<Stats> + Sync>(
        stats: &[S],
        w: usize,
        ht: usize,
        guide: Option<Guide>,
    ) -> Fields {
        let stats: Vec<&Stats> = stats.iter().map(AsRef::as_ref).collect();
        let channel = |f: &(dyn Fn(&Stats) -> [f64; 3] + Sync)| -> [Vec<f64>; 3] {
            std::array::from_fn(|c| stats.par_iter().map(|s| f(s)[c]).collect())
        };
        let se2 = channel(&|s| s.se2());
        let spread: Vec<f64> = (0..stats.len())
            .into_par_iter()
            .map(|px| se2.iter().map(|c| c[px]).sum())
            .collect();
        let n: Vec<u32> = stats.par_iter().map(|s| s.x.n).collect();
        let limit = spread_limits(&n, &spread, w, ht);
        let patch_spread = patch_spreads(&n, &spread, w, ht);
        Fields {
            mean: channel(&|s| s.x.mean),
            y_mean: channel(&|s| s.y_mean),
            n,
            se2,
            spread,
            limit,
            patch_spread,
            features: guide.map(Features::new),
        }
    }

    /// Whether pixels p and q (p with two samples or more) average each
    /// other: q has two samples or more, neither is far noisier
    /// ([`NOISIER`]), and the test passes on every channel, as [`agree`]
    /// decides it.
    pub(super) fn compatible(&self, p: usize, q: usize, k: &Kernel) -> bool {
        let (spread, limit) = (&self.spread, &self.limit);
        if self.n[q] < 2 || spread[q] > limit[p] || spread[p] > limit[q] {
            return false;
        }
        let df = (self.n[p] + self.n[q] - 2) as usize;
        (0..3).fold(true, |all, c| {
            let (y, se2) = (&self.y_mean[c], &self.se2[c]);
            all & agree(y[p], y[q], se2[p] + se2[q], k.t[df], k.t2[df])
        })
    }
}

impl Fields {
    /// The patch test's terms of the pair (p, q) (F11): Σ_c (ȳ_p,c − ȳ_q,c)²
    /// and the two spreads S_p, S_q, where both have two samples or more;
    /// none otherwise.
    #[cfg(test)]
    pub(super) fn patch_term(&self, p: usize, q: usize) -> Option<(f64, f64, f64)> {
        if self.n[p] < 2 || self.n[q] < 2 {
            return None;
        }
        let d = |c: usize| self.y_mean[c][p] - self.y_mean[c][q];
        let (d0, d1, d2) = (d(0), d(1), d(2));
        Some((
            (d0 * d0 + d1 * d1) + d2 * d2,
            self.spread[p],
            self.spread[q],
        ))
    }
}

/// Per pixel, the sum of the spreads of its 3 × 3 patch, along each row's
/// three, then over the rows, in order (the patch test's Σ_u S_{p+u}
/// where every pair of the patch counts), or NaN where some pixel of the
/// patch is off the film (its frame) or has fewer than two samples.
pub(super) fn patch_spreads(n: &[u32], spread: &[f64], w: usize, ht: usize) -> Vec<f64> {
    let mut out = vec![f64::NAN; n.len()];
    out.par_iter_mut().enumerate().for_each(|(px, out)| {
        let (frame, i) = (px / (w * ht), px % (w * ht));
        let (x, y) = (i % w, i / w);
        if x == 0 || y == 0 || x + 1 >= w || y + 1 >= ht {
            return;
        }
        let at = |dy: usize, dx: usize| frame * w * ht + (y + dy - 1) * w + x + dx - 1;
        if (0..3).any(|dy| (0..3).any(|dx| n[at(dy, dx)] < 2)) {
            return;
        }
        let row = |dy: usize| (spread[at(dy, 0)] + spread[at(dy, 1)]) + spread[at(dy, 2)];
        *out = (row(0) + row(1)) + row(2);
    });
    out
}

/// Whether a patch whose `m` pairs (of two samples or more each) sum to
/// `a` (their squared differences) and `b` (their spreads) passes: the
/// transformed means differ by no more than the χ² bound at
/// [`PATCH_ALPHA`](super::PATCH_ALPHA) allows, pooled over the patch.
#[inline(always)]
pub(super) fn patch_passes(k: &Kernel, a: f64, b: f64, m: f64) -> bool {
    m > 0.0 && a <= k.patch[m as usize] * b
}

/// Per pixel, the largest spread a pixel it averages with may have:
/// [`NOISIER`] × the larger of the pixel's spread and the upper quartile
/// (nearest rank: the ⌈¾·c⌉-th smallest of c) of the spreads of its
/// 3 × 3 neighbourhood (same frame, pixels with two samples or more), so
/// that noise three of the nine share (two at the film's edge) is the
/// region's noise and a lone outlier is not.
pub(super) fn spread_limits(n: &[u32], spread: &[f64], w: usize, ht: usize) -> Vec<f64> {
    let mut limit = vec![0.0; n.len()];
    limit.par_iter_mut().enumerate().for_each(|(px, l)| {
        let (frame, i) = (px / (w * ht), px % (w * ht));
        let (x, y) = (i % w, i / w);
        let base = frame * w * ht;
        let mut around = [0.0f64; 9];
        let mut count = 0;
        for ny in y.saturating_sub(1)..(y + 2).min(ht) {
            for nx in x.saturating_sub(1)..(x + 2).min(w) {
                let q = base + ny * w + nx;
                if n[q] >= 2 {
                    around[count] = spread[q];
                    count += 1;
                }
            }
        }
        let around = &mut around[..count];
        around.sort_by(f64::total_cmp);
        let quartile = around
            .get((3 * count).div_ceil(4).saturating_sub(1))
            .copied()
            .unwrap_or(0.0);
        *l = NOISIER * spread[px].max(quartile);
    });
    limit
}
