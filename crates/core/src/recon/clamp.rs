//! Per-sample clamping, what most renderers offer against fireflies
//! (pbrt-v4's `maxcomponentvalue`, Cycles' and Arnold's clamps): a sample
//! whose largest RGB component exceeds C is scaled down so that component
//! is C, keeping its hue; any other sample is unchanged. Then the mean,
//! under the same reconstruction filter. Biased (energy is lost wherever a
//! genuine feature is brighter than C), and blind to where a sample is.

use super::{Film, Image, ReconFilter};
use crate::dump::{Header, Record};

/// `rgb` with its largest component at most `c` (pbrt-v4's rule: scale
/// all three by c / max). Negative components do not count towards the
/// maximum and are scaled with the others.
///
/// ```
/// use pathdensity_core::recon::clamp::clamp_rgb;
/// assert_eq!(clamp_rgb([20.0, 5.0, 1.0], 10.0), [10.0, 2.5, 0.5]);
/// assert_eq!(clamp_rgb([3.0, 2.0, 1.0], 10.0), [3.0, 2.0, 1.0]);
/// ```
#[inline]
pub fn clamp_rgb(rgb: [f64; 3], c: f64) -> [f64; 3] {
    let m = rgb[0].max(rgb[1]).max(rgb[2]);
    if m > c { rgb.map(|v| v * (c / m)) } else { rgb }
}

/// The mean of the valid samples, each clamped to `c` first.
pub fn clamped_mean(
    records: &[Record],
    h: &Header,
    filter: ReconFilter,
    c: f64,
    occupancy: &[u32],
) -> Image {
    let film = Film::of_records(h, filter, records, |_, r| {
        Some(clamp_rgb([r.r as f64, r.g as f64, r.b as f64], c))
    });
    film.resolve(occupancy)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Hand-computed: one channel over C, all over, none over, a negative
    /// channel.
    #[test]
    fn clamps_by_the_largest_component() {
        assert_eq!(clamp_rgb([12.0, 3.0, 6.0], 4.0), [4.0, 1.0, 2.0]);
        assert_eq!(clamp_rgb([8.0, 16.0, 32.0], 4.0), [1.0, 2.0, 4.0]);
        assert_eq!(clamp_rgb([4.0, 1.0, 0.0], 4.0), [4.0, 1.0, 0.0]);
        assert_eq!(clamp_rgb([8.0, -2.0, 1.0], 4.0), [4.0, -1.0, 0.5]);
        assert_eq!(clamp_rgb([-8.0, -2.0, -1.0], 4.0), [-8.0, -2.0, -1.0]);
    }

    #[test]
    fn the_clamped_mean_of_a_pixel() {
        use crate::dump::Order;
        let h = Header::still(1, 1, 3, Order::PixelMajor);
        let recs = [
            Record::new(0.5, 0.5, 0.0, [1.0, 1.0, 1.0]),
            Record::new(0.5, 0.5, 0.0, [100.0, 50.0, 0.0]),
            Record::new(0.5, 0.5, 0.0, [2.0, 0.0, 0.0]),
        ];
        let img = clamped_mean(&recs, &h, ReconFilter::Box, 10.0, &[3]);
        // (1 + 10 + 2) / 3, (1 + 5 + 0) / 3, (1 + 0 + 0) / 3
        assert_eq!(img.data[0], [13.0 / 3.0, 2.0, 1.0 / 3.0]);
    }
}
