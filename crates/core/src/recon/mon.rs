//! Median of means (MoN) and its Gini-adaptive variant (G-MoN), after
//! Buisine, Delepoulle and Renaud, "Firefly Removal in Monte Carlo
//! Rendering with Adaptive Median of meaNs", EGSR 2021.
//!
//! A pixel's valid samples are dealt, in file order, to `m` groups
//! round-robin (sample j to group j mod m, so in a pass-major dump each
//! group is a set of passes); each group is averaged. Means are ordered by
//! luminance and whole colours are kept, so neither estimator shifts hue
//! the way a per-channel median does (the paper's Figure 4 problem).

use std::sync::Arc;

use super::Image;
use super::groups::{Channels, PixelGroups};
use crate::dump::Header;
use crate::joint::lab::luminance;

/// The group means of one pixel's samples, sorted by luminance (ties keep
/// group order). Groups that received no sample (fewer samples than
/// groups) are left out.
pub fn sorted_group_means(ch: &Channels, groups: usize) -> Vec<[f64; 3]> {
    let n = ch[0].len();
    let m = groups.min(n);
    let mut sums = vec![([0.0f64; 3], 0u32); m];
    for j in 0..n {
        let (s, count) = &mut sums[j % m];
        for c in 0..3 {
            s[c] += ch[c][j];
        }
        *count += 1;
    }
    let mut means: Vec<(f64, [f64; 3])> = sums
        .into_iter()
        .map(|(s, count)| {
            let mean = s.map(|v| v / count as f64);
            (luminance(mean), mean)
        })
        .collect();
    means.sort_by(|a, b| a.0.total_cmp(&b.0));
    means.into_iter().map(|(_, mean)| mean).collect()
}

/// MoN: the median-luminance group mean; for an even count, the average
/// of the two middle ones. 0 for no samples.
///
/// ```
/// use pathdensity_core::recon::mon::median_of_means;
/// // Six samples in three groups: means 1, 1 and 149.5 (the firefly's group).
/// let v = vec![1.0, 1.0, 298.0, 1.0, 1.0, 1.0];
/// let ch = [v.clone(), v.clone(), v];
/// assert_eq!(median_of_means(&ch, 3), [1.0; 3]);
/// ```
pub fn median_of_means(ch: &Channels, groups: usize) -> [f64; 3] {
    median_of_sorted(&sorted_group_means(ch, groups))
}

/// MoN of group means sorted by [`sorted_group_means`].
fn median_of_sorted(means: &[[f64; 3]]) -> [f64; 3] {
    let m = means.len();
    match m {
        0 => [0.0; 3],
        _ if m % 2 == 1 => means[m / 2],
        _ => [0, 1, 2].map(|c| (means[m / 2 - 1][c] + means[m / 2][c]) / 2.0),
    }
}

/// Gini coefficient of non-negative values sorted ascending:
/// G = Σᵢ (2i − m − 1) xᵢ / (m Σ xᵢ), i = 1…m; 0 for an all-zero set.
/// Negative values (a renderer's negative radiance) are shifted up by the
/// minimum first, as the authors' code does.
pub fn gini(sorted: &[f64]) -> f64 {
    let m = sorted.len();
    let shift = sorted.first().map_or(0.0, |&v| v.min(0.0));
    let total: f64 = sorted.iter().map(|v| v - shift).sum();
    if m == 0 || total <= 0.0 {
        return 0.0;
    }
    let weighted: f64 = sorted
        .iter()
        .enumerate()
        .map(|(i, v)| (2.0 * (i + 1) as f64 - m as f64 - 1.0) * (v - shift))
        .sum();
    (weighted / (m as f64 * total)).clamp(0.0, 1.0)
}

/// G-MoN (the paper's Eq. 6): with G the Gini coefficient of the group
/// means' luminances, drop c = ⌊G · ⌊m/2⌋⌋ means at each end and average
/// the rest. G = 0 (equal means) gives the mean of all groups; G near 1 (one
/// group holds everything) gives the median group.
///
/// ```
/// use pathdensity_core::recon::mon::gini_median_of_means;
/// // Equal groups: nothing to trim, the mean of the means.
/// let ch = std::array::from_fn(|_| vec![2.0, 2.0, 2.0, 2.0]);
/// assert_eq!(gini_median_of_means(&ch, 4), [2.0; 3]);
/// ```
pub fn gini_median_of_means(ch: &Channels, groups: usize) -> [f64; 3] {
    gini_median_of_sorted(&sorted_group_means(ch, groups))
}

/// G-MoN of group means sorted by [`sorted_group_means`].
fn gini_median_of_sorted(means: &[[f64; 3]]) -> [f64; 3] {
    let m = means.len();
    if m == 0 {
        return [0.0; 3];
    }
    let lum: Vec<f64> = means.iter().map(|&c| luminance(c)).collect();
    let cut = (gini(&lum) * (m / 2) as f64).floor() as usize;
    let kept = &means[cut..m - cut];
    [0, 1, 2].map(|c| kept.iter().map(|v| v[c]).sum::<f64>() / kept.len() as f64)
}

/// The MoN and G-MoN images, in one grouped pass.
pub struct MonImages {
    pub mon: Arc<Image>,
    pub gmon: Arc<Image>,
}

pub fn mon_images(groups: &PixelGroups, h: &Header, m: usize) -> MonImages {
    let per_pixel = groups.map(|ch| {
        let means = sorted_group_means(ch, m);
        (median_of_sorted(&means), gini_median_of_sorted(&means))
    });
    let mut mon = Image::for_header(h);
    let mut gmon = Image::for_header(h);
    for (px, (a, b)) in per_pixel.into_iter().enumerate() {
        mon.data[px] = a;
        gmon.data[px] = b;
    }
    MonImages {
        mon: Arc::new(mon),
        gmon: Arc::new(gmon),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grey(v: &[f64]) -> Channels {
        [v.to_vec(), v.to_vec(), v.to_vec()]
    }

    #[test]
    fn samples_are_dealt_round_robin_in_file_order() {
        // Groups of 3: {1, 4}, {2, 5}, {3, 600} → means 2.5, 3.5, 301.5.
        let means = sorted_group_means(&grey(&[1.0, 2.0, 3.0, 4.0, 5.0, 600.0]), 3);
        assert_eq!(means, [[2.5; 3], [3.5; 3], [301.5; 3]]);
        // Fewer samples than groups: one group per sample.
        assert_eq!(sorted_group_means(&grey(&[7.0, 1.0]), 11).len(), 2);
    }

    #[test]
    fn median_of_means_by_hand() {
        let ch = grey(&[1.0, 2.0, 3.0, 4.0, 5.0, 600.0]);
        assert_eq!(median_of_means(&ch, 3), [3.5; 3]);
        // Even group count: the two middle means averaged, (2.5 + 3.5) / 2
        // with groups {1, 5}, {2, 600}, {3}, {4}: means 3, 301, 3, 4.
        assert_eq!(median_of_means(&ch, 4), [3.5; 3]);
        // One group is the mean.
        assert_eq!(median_of_means(&ch, 1), [615.0 / 6.0; 3]);
        assert_eq!(median_of_means(&grey(&[]), 11), [0.0; 3]);
    }

    #[test]
    fn whole_colours_are_kept_not_mixed_per_channel() {
        // Group means (1, 0, 0), (0, 0, 1) and (0, 1, 0): luminances 0.21,
        // 0.07, 0.72; the median by luminance is the red one, whole.
        let ch = [
            vec![1.0, 0.0, 0.0],
            vec![0.0, 0.0, 1.0],
            vec![0.0, 1.0, 0.0],
        ];
        assert_eq!(median_of_means(&ch, 3), [1.0, 0.0, 0.0]);
    }

    #[test]
    fn gini_by_hand() {
        assert_eq!(gini(&[3.0, 3.0, 3.0]), 0.0);
        // All in one of four: G = (2·4 − 5)·1 / (4·1) = 3/4.
        assert_eq!(gini(&[0.0, 0.0, 0.0, 1.0]), 0.75);
        assert_eq!(gini(&[0.0, 0.0]), 0.0);
        // {1, 2, 3}: (−2·1 + 0·2 + 2·3) / (3·6) = 4/18.
        assert!((gini(&[1.0, 2.0, 3.0]) - 4.0 / 18.0).abs() < 1e-15);
    }

    #[test]
    fn gmon_trims_by_the_gini_coefficient() {
        // Five groups, means 1, 1, 1, 1, 96 (luminance = value for grey):
        // G = (−4 − 2 + 0 + 2 + 4·96) / (5 · 100) = 0.76, c = ⌊0.76 · 2⌋ = 1.
        let ch = grey(&[1.0, 1.0, 1.0, 1.0, 96.0]);
        assert!((gini(&[1.0, 1.0, 1.0, 1.0, 96.0]) - 0.76).abs() < 1e-12);
        // c = 1: drop one mean at each end, average 1, 1, 1.
        assert_eq!(gini_median_of_means(&ch, 5), [1.0; 3]);
        // Means 2 and 4: G = 1/6, c = 0, the plain mean.
        assert_eq!(
            gini_median_of_means(&grey(&[2.0, 4.0, 2.0, 4.0]), 2),
            [3.0; 3]
        );
    }
}
