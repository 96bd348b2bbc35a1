//! The density-guided image (docs/filter.md §3, F10): a denoiser's image
//! steered per pixel and channel by the pixel's own samples. The denoiser
//! is right where a pixel is noise; the samples are right about a real
//! bright feature, which a denoiser dims as if it were noise, and about an
//! outlier, whose energy a denoiser of the mean spreads into its
//! neighbours. With D the denoiser's value, C = c ± w the confidence
//! interval of all the pixel's samples and A = m ± h that of the samples
//! the filter accepted (both [`super::confidence`], z standard errors,
//! variance pooled over compatible neighbours):
//!
//! - D is first held inside C, as the `_ci` images are: a neighbour's
//!   spread energy that the pixel's samples refute goes back to C's edge;
//! - then, where it lies below A, the accepted samples vouch for more than
//!   the denoiser kept and the pixel takes their mean m: a feature the
//!   samples agree on is never dimmed.
//!
//! The upper bound is C's, not A's: the filter's accepted samples miss
//! the real but rare bright paths it rejects (a caustic's), so their mean
//! is low exactly where the truth is bright, and A's edge would clip it
//! (docs/RESULTS.md, "The guided image"). A pixel whose samples were all
//! rejected, or whose one accepted sample has no compatible neighbour
//! (h = ∞), is not lifted.

use super::Image;
use super::confidence::Interval;

/// The shipped z of the accepted samples' interval.
pub const Z: f64 = 2.5;

/// `denoised` steered by `accepted`, the interval of each pixel's accepted
/// samples, and held inside `all`, the interval of all its samples.
/// Pixels with no valid sample stay 0.
pub fn guide(denoised: &Image, accepted: &Interval, all: &Interval) -> Image {
    let mut out = all.bound(denoised);
    for (px, v) in out.data.iter_mut().enumerate() {
        if accepted.count[px] == 0 {
            continue;
        }
        let (m, h) = (accepted.centre.data[px], accepted.half_width.data[px]);
        for c in 0..3 {
            if v[c] < m[c] - h[c] {
                v[c] = m[c];
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn one(v: f64) -> Image {
        Image {
            width: 1,
            height: 1,
            frames: 1,
            data: vec![[v; 3]],
        }
    }

    fn interval(m: f64, h: f64, n: u32) -> Interval {
        Interval {
            centre: one(m),
            half_width: one(h),
            count: vec![n],
        }
    }

    #[test]
    fn a_vouched_feature_takes_the_accepted_mean_a_spread_one_the_edge() {
        let all = interval(120.0, 90.0, 16);
        let accepted = interval(100.0, 30.0, 15);
        // A highlight the denoiser dimmed to 28: the accepted samples say
        // 100 ± 30.
        assert_eq!(guide(&one(28.0), &accepted, &all).data[0], [100.0; 3]);
        // Energy spread into the pixel beyond what all its samples allow.
        assert_eq!(guide(&one(500.0), &accepted, &all).data[0], [210.0; 3]);
        // Inside both: the denoiser's.
        assert_eq!(guide(&one(90.0), &accepted, &all).data[0], [90.0; 3]);
        // Above A but inside C: kept (the filter may have rejected real
        // bright samples).
        assert_eq!(guide(&one(180.0), &accepted, &all).data[0], [180.0; 3]);
    }

    #[test]
    fn nothing_accepted_or_nothing_known_is_not_lifted() {
        let all = interval(5.0, 4.0, 4);
        assert_eq!(
            guide(&one(2.0), &interval(0.0, 0.0, 0), &all).data[0],
            [2.0; 3]
        );
        let unbounded = interval(8.0, f64::INFINITY, 1);
        assert_eq!(guide(&one(2.0), &unbounded, &all).data[0], [2.0; 3]);
        // An empty pixel stays empty.
        let empty = interval(0.0, 0.0, 0);
        assert_eq!(guide(&one(7.0), &empty, &empty).data[0], [0.0; 3]);
    }
}
