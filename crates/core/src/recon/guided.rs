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
//!   the denoiser kept and the pixel is raised to A's lower edge m − h: a
//!   feature the samples agree on is never dimmed below what they vouch
//!   for, and a pixel lifted by noise moves as little as the samples
//!   require;
//! - last, where the display shows both the result and the samples' mean
//!   x̄ as white on every channel, the result is held within √2 of the
//!   pixel's *own* standard errors of x̄ (no pooling): the display cannot
//!   tell the two apart, so only the linear error counts there (the MSE
//!   break-even of an unbiased mean against an independent estimate; a
//!   heuristic, as D is made from x̄). A small light whose samples all
//!   agree is not brightened by a neighbour's spread energy; a pixel
//!   whose own samples are noisy keeps D.
//!
//! The upper bound is C's, not A's: the filter's accepted samples miss
//! the real but rare bright paths it rejects (a caustic's), so their mean
//! is low exactly where the truth is bright, and A's edge would clip it
//! (docs/RESULTS.md, "The guided image"). A pixel whose samples were all
//! rejected, or whose one accepted sample has no compatible neighbour
//! (h = ∞), is not lifted.

use super::Image;
use super::confidence::Interval;
use crate::par::prelude::*;

/// The shipped z of the accepted samples' interval.
pub const Z: f64 = 2.5;

/// Where the display shows a pixel as white, D is held within this many
/// of the pixel's own standard errors of its mean: beyond √2 SE the mean's
/// expected squared error, SE², is below the denoiser's, (D − x̄)² − SE².
pub const SATURATED_Z: f64 = std::f64::consts::SQRT_2;

/// `denoised` steered by `accepted`, the interval of each pixel's accepted
/// samples, and held inside `all`, the interval of all its samples;
/// `white` is the linear value the display shows as white (1/exposure).
/// Pixels with no valid sample stay 0.
pub fn guide(denoised: &Image, accepted: &Interval, all: &Interval, white: f64) -> Image {
    guide_from(denoised, |px| floor(accepted, px), all, white)
}

/// The least value pixel `px`'s accepted samples vouch for, per channel:
/// the lower edge m − h of their interval `accepted`, or −∞ where none
/// was accepted.
pub fn floor(accepted: &Interval, px: usize) -> [f64; 3] {
    let (m, h) = (accepted.centre.data[px], accepted.half_width.data[px]);
    match accepted.count[px] {
        0 => [f64::NEG_INFINITY; 3],
        _ => std::array::from_fn(|c| m[c] - h[c]),
    }
}

/// [`guide`] with the accepted samples' interval read as its [`floor`]s
/// alone: `least(px)`, which a caller may keep instead of the interval.
pub fn guide_from(
    denoised: &Image,
    least: impl Fn(usize) -> [f64; 3] + Sync,
    all: &Interval,
    white: f64,
) -> Image {
    let mut out = all.bound(denoised);
    out.data.par_iter_mut().enumerate().for_each(|(px, v)| {
        let least = least(px);
        for c in 0..3 {
            // Not `max`: a value that is not a number stays so.
            if v[c] < least[c] {
                v[c] = least[c];
            }
        }
        let (x, se) = (all.centre.data[px], all.own_se.data[px]);
        if shown_white(all, px, v, white) {
            *v = std::array::from_fn(|c| {
                v[c].clamp(x[c] - SATURATED_Z * se[c], x[c] + SATURATED_Z * se[c])
            });
        }
    });
    out
}

/// Whether the display shows both `v` and pixel `px`'s mean as white on
/// every channel, the mean made from two samples or more.
pub(crate) fn shown_white(all: &Interval, px: usize, v: &[f64; 3], white: f64) -> bool {
    let over = |a: &[f64; 3]| a.iter().all(|&c| c >= white);
    all.count[px] >= 2 && over(v) && over(&all.centre.data[px])
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::recon::test_pixel as one;

    /// A display that shows nothing as white.
    fn guide_(d: &Image, accepted: &Interval, all: &Interval) -> Image {
        guide(d, accepted, all, f64::INFINITY)
    }

    fn interval(m: f64, h: f64, n: u32) -> Interval {
        Interval {
            centre: one(m),
            half_width: one(h),
            count: vec![n],
            own_se: one(h / 3.0),
            z: 3.0,
        }
    }

    #[test]
    fn a_vouched_feature_and_a_spread_one_go_to_the_intervals_edges() {
        let all = interval(120.0, 90.0, 16);
        let accepted = interval(100.0, 30.0, 15);
        // A highlight the denoiser dimmed to 28: the accepted samples say
        // 100 ± 30, so at least 70.
        assert_eq!(guide_(&one(28.0), &accepted, &all).data[0], [70.0; 3]);
        // Energy spread into the pixel beyond what all its samples allow.
        assert_eq!(guide_(&one(500.0), &accepted, &all).data[0], [210.0; 3]);
        // Inside both: the denoiser's.
        assert_eq!(guide_(&one(90.0), &accepted, &all).data[0], [90.0; 3]);
        // Above A but inside C: kept (the filter may have rejected real
        // bright samples).
        assert_eq!(guide_(&one(180.0), &accepted, &all).data[0], [180.0; 3]);
    }

    #[test]
    fn nothing_accepted_or_nothing_known_is_not_lifted() {
        let all = interval(5.0, 4.0, 4);
        assert_eq!(
            guide_(&one(2.0), &interval(0.0, 0.0, 0), &all).data[0],
            [2.0; 3]
        );
        // Nothing accepted says nothing, not "at least m − h = 0".
        let wide = interval(5.0, 40.0, 4);
        assert_eq!(
            guide_(&one(-3.0), &interval(0.0, 0.0, 0), &wide).data[0],
            [-3.0; 3]
        );
        let unbounded = interval(8.0, f64::INFINITY, 1);
        assert_eq!(guide_(&one(2.0), &unbounded, &all).data[0], [2.0; 3]);
        // An empty pixel stays empty.
        let empty = interval(0.0, 0.0, 0);
        assert_eq!(guide_(&one(7.0), &empty, &empty).data[0], [0.0; 3]);
    }

    /// Where the display shows both as white, the own samples decide: a
    /// light's 16 equal samples (own SE 0, pooled interval wide) pull a
    /// spread 885 back to 700; a pixel whose own samples are noisy keeps D;
    /// below white nothing changes.
    #[test]
    fn saturated_pixels_are_held_by_their_own_samples() {
        let light = Interval {
            own_se: one(0.0),
            ..interval(700.0, 300.0, 16)
        };
        let none = interval(0.0, 0.0, 0);
        assert_eq!(guide(&one(885.0), &none, &light, 1.0).data[0], [700.0; 3]);
        assert_eq!(
            guide(&one(885.0), &none, &light, 1000.0).data[0],
            [885.0; 3]
        );
        let noisy = Interval {
            own_se: one(100.0),
            ..interval(262.0, 300.0, 16)
        };
        assert_eq!(guide(&one(149.0), &none, &noisy, 1.0).data[0], [149.0; 3]);
        let far = 262.0 - SATURATED_Z * 100.0;
        assert_eq!(guide(&one(50.0), &none, &noisy, 1.0).data[0], [far; 3]);
        // Both must be white on every channel, with two samples or more.
        let dim = Interval {
            centre: Image {
                data: vec![[700.0, 700.0, 0.5]],
                ..one(0.0)
            },
            ..light
        };
        let d = Image {
            data: vec![[885.0, 885.0, 0.8]],
            ..one(0.0)
        };
        assert_eq!(guide(&d, &none, &dim, 1.0).data[0], [885.0, 885.0, 0.8]);
        let below = interval(0.5, 300.0, 16);
        assert_eq!(guide(&one(885.0), &none, &below, 1.0).data[0], [300.5; 3]);
        let single = Interval {
            own_se: one(0.0),
            ..interval(700.0, 300.0, 1)
        };
        assert_eq!(guide(&one(885.0), &none, &single, 1.0).data[0], [885.0; 3]);
    }
}
