//! Energy accounting for the path-density filter: what it removed from
//! each pixel, and an energy-aware variant that gives that energy back
//! without giving back the spikes.
//!
//! Removed radiance is `mean − filtered` per pixel and channel: exactly
//! what the filter changed, including the renormalisation over the accepted
//! samples and median fallbacks (so it can be negative where a dark outlier
//! was rejected). Its sum over the film is the energy deficit the energy
//! ratio measures.
//!
//! The energy-aware variant spreads each pixel's removed radiance over its
//! image-space neighbourhood with a normalised Gaussian of σ_e pixels and
//! adds it to the filtered image. Why this design (docs/RESULTS.md measures
//! it): a rejected firefly is a sample of a real but rare light path
//! (a caustic seen through a diffuse bounce) whose expected contribution is
//! smooth over many pixels; the filter's fault is only that one pixel got
//! all of it. Spreading over 2πσ_e² pixels divides the spike's amplitude by
//! that area (σ_e = 8: about 400×) while the film's total radiance per
//! channel, and so the energy ratio, stays that of the mean. Only pixels
//! holding samples receive energy, and the weights are normalised over those
//! inside the frame, so nothing leaks off the film.

use super::Image;

/// Per pixel, `mean − filtered`.
pub fn removed(mean: &Image, filtered: &Image) -> Image {
    let mut out = mean.clone();
    for (o, f) in out.data.iter_mut().zip(&filtered.data) {
        for c in 0..3 {
            o[c] -= f[c];
        }
    }
    out
}

/// `filtered` plus `removed` spread over each source pixel's neighbourhood
/// (radius ⌈3σ_e⌉) with weights exp(−d²/2σ_e²) normalised over the
/// occupied pixels of its frame. Sources are visited in pixel order, so the
/// result does not depend on threads.
///
/// ```
/// use pathdensity_core::recon::{Image, energy};
/// let mut mean = Image::new(5, 5, 1);
/// mean.data[12] = [26.0; 3]; // a firefly at the centre, all else 0
/// let filtered = Image::new(5, 5, 1);
/// let occupancy = vec![1; 25];
/// let removed = energy::removed(&mean, &filtered);
/// let out = energy::energy_aware(&filtered, &removed, &occupancy, 100.0);
/// // σ_e far above the film: the 26 units are spread almost evenly.
/// let total: f64 = out.data.iter().map(|p| p[0]).sum();
/// assert!((total - 26.0).abs() < 1e-9);
/// assert!(out.data.iter().all(|p| (p[0] - 26.0 / 25.0).abs() < 0.01));
/// ```
pub fn energy_aware(filtered: &Image, removed: &Image, occupancy: &[u32], sigma: f64) -> Image {
    let (w, h) = (filtered.width, filtered.height);
    let r = (3.0 * sigma).ceil().max(0.0) as isize;
    let kernel: Vec<f64> = (-r..=r)
        .map(|d| (-((d * d) as f64) / (2.0 * sigma * sigma)).exp())
        .collect();
    let mut out = filtered.clone();
    let n = w * h;
    for (src, e) in removed.data.iter().enumerate() {
        if *e == [0.0; 3] || occupancy[src] == 0 {
            continue;
        }
        let frame = src / n * n;
        let (x, y) = (((src % n) % w) as isize, ((src % n) / w) as isize);
        let window = |visit: &mut dyn FnMut(usize, f64)| {
            for dy in -r..=r {
                let qy = y + dy;
                if qy < 0 || qy >= h as isize {
                    continue;
                }
                for dx in -r..=r {
                    let qx = x + dx;
                    if qx < 0 || qx >= w as isize {
                        continue;
                    }
                    let q = frame + qy as usize * w + qx as usize;
                    if occupancy[q] > 0 {
                        visit(q, kernel[(dy + r) as usize] * kernel[(dx + r) as usize]);
                    }
                }
            }
        };
        let mut total = 0.0;
        window(&mut |_, k| total += k);
        window(&mut |q, k| {
            for (o, v) in out.data[q].iter_mut().zip(e) {
                *o += v * k / total;
            }
        });
    }
    out
}

/// Σ over the film of each channel of `img`.
pub fn channel_sums(img: &Image) -> [f64; 3] {
    img.data
        .iter()
        .fold([0.0; 3], |a, p| [a[0] + p[0], a[1] + p[1], a[2] + p[2]])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spreading_conserves_each_channel_and_skips_empty_pixels() {
        let mut mean = Image::new(7, 4, 2);
        let mut filtered = Image::new(7, 4, 2);
        mean.data[3] = [10.0, 5.0, -1.0];
        mean.data[7 * 4 + 27] = [0.0, 0.0, 8.0]; // frame 1's last pixel
        filtered.data[9] = [1.0; 3];
        mean.data[9] = [1.0; 3];
        let mut occupancy = vec![1u32; 56];
        occupancy[4] = 0;
        let rem = removed(&mean, &filtered);
        let out = energy_aware(&filtered, &rem, &occupancy, 1.5);
        let before = channel_sums(&mean);
        let after = channel_sums(&out);
        for c in 0..3 {
            assert!((before[c] - after[c]).abs() < 1e-12, "{before:?} {after:?}");
        }
        assert_eq!(out.data[4], [0.0; 3], "an empty pixel receives nothing");
        // Frame 0's energy stays in frame 0.
        let f0: f64 = out.data[..28].iter().map(|p| p[0] + p[1] + p[2]).sum();
        assert!((f0 - (14.0 + 3.0)).abs() < 1e-12);
    }
}
