//! Per-pixel robust estimators (docs/filter.md §3): the median and the α-trimmed
//! mean, per channel, over the valid samples a pixel contains.

use std::sync::Arc;

use super::Image;
use super::groups::PixelGroups;
use super::median::{median_of_sorted, sort_total};
use crate::dump::Header;

/// The α-trimmed mean of `v` (reordered in place): sort, drop ⌊α n⌋ values
/// at each end, average the rest in ascending order in f64. α = 0 gives the
/// mean; `alpha` must lie in [0, 0.5). 0 for an empty slice.
///
/// ```
/// use pathdensity_core::recon::robust::trimmed_mean;
/// // n = 10, α = 0.1: drop one value at each end.
/// let mut v = [9.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 100.0];
/// assert_eq!(trimmed_mean(&mut v, 0.1), 5.5);
/// ```
pub fn trimmed_mean(v: &mut [f64], alpha: f64) -> f64 {
    sort_total(v);
    trimmed_mean_of_sorted(v, alpha)
}

/// [`trimmed_mean`] of `v` sorted by [`sort_total`].
fn trimmed_mean_of_sorted(v: &[f64], alpha: f64) -> f64 {
    let n = v.len();
    if n == 0 {
        return 0.0;
    }
    let cut = (alpha * n as f64).floor() as usize;
    let kept = &v[cut..n - cut];
    kept.iter().sum::<f64>() / kept.len() as f64
}

/// The per-pixel median and trimmed-mean images, computed in one grouped
/// pass over the dump.
pub struct RobustImages {
    pub median: Arc<Image>,
    pub trimmed: Arc<Image>,
}

pub fn robust_images(groups: &PixelGroups, h: &Header, alpha: f64) -> RobustImages {
    let per_pixel = groups.map(|ch| {
        let mut med = [0.0; 3];
        let mut trim = [0.0; 3];
        for c in 0..3 {
            // One sort for both.
            sort_total(&mut ch[c]);
            trim[c] = trimmed_mean_of_sorted(&ch[c], alpha);
            med[c] = median_of_sorted(&ch[c]);
        }
        (med, trim)
    });
    let mut median_img = Image::for_header(h);
    let mut trimmed_img = Image::for_header(h);
    for (px, (m, t)) in per_pixel.into_iter().enumerate() {
        median_img.data[px] = m;
        trimmed_img.data[px] = t;
    }
    RobustImages {
        median: Arc::new(median_img),
        trimmed: Arc::new(trimmed_img),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recon::median::median;

    #[test]
    fn trimmed_mean_by_hand() {
        // n = 5, α = 0.2: ⌊1⌋ = 1 dropped at each end → mean of 2, 3, 50.
        let mut v = [50.0, 2.0, -7.0, 3.0, 1000.0];
        assert_eq!(trimmed_mean(&mut v, 0.2), 55.0 / 3.0);
        // n = 9, α = 0.1: ⌊0.9⌋ = 0, nothing dropped: the mean.
        let mut v = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 900.0];
        assert_eq!(trimmed_mean(&mut v, 0.1), 936.0 / 9.0);
        // α = 0 is the mean.
        let mut v = [4.0, 1.0, 1.0];
        assert_eq!(trimmed_mean(&mut v, 0.0), 2.0);
        assert_eq!(trimmed_mean(&mut [], 0.1), 0.0);
    }

    #[test]
    fn median_by_hand() {
        assert_eq!(median(&mut [5.0, 1.0, 3.0]), 3.0);
        assert_eq!(median(&mut [5.0, 1.0, 3.0, 100.0]), 4.0);
        assert_eq!(median(&mut [7.0]), 7.0);
        assert_eq!(median(&mut [-1.0, -3.0]), -2.0);
    }
}
