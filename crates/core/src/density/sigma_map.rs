//! The σ map (the paper's Figure 6): where the joint density is sparse.

use super::Sigmas;
use crate::dump::{Header, Record, Validity};
use crate::image::Image;

/// The σ map (the paper's Figure 6): per pixel, the mean of the finite σ of
/// the valid samples it contains, summed in file order; 0 where none is finite.
pub fn sigma_map(records: &[Record], h: &Header, sigma: &Sigmas) -> Image {
    let mut sum = vec![(0.0f64, 0u32); h.pixels() * h.frames as usize];
    sigma.for_each_kept(|i, s| {
        let r = &records[i];
        if s.is_finite() && r.validity(h) == Validity::Valid {
            let e = &mut sum[r.pixel_index(h)];
            e.0 += s;
            e.1 += 1;
        }
    });
    let mut img = Image::for_header(h);
    for (out, (s, n)) in img.data.iter_mut().zip(sum) {
        if n > 0 {
            let m = s / n as f64;
            *out = [m, m, m];
        }
    }
    img
}
