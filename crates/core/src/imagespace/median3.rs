//! The 3 × 3 image-space median (the paper's Figure 3): per channel, the
//! median of the pixel and its 8 neighbours that hold samples, the window
//! clipped at the border (an even count takes the mean of the middle two).

use crate::par::prelude::*;

use crate::recon::Image;
use crate::recon::median::median;

pub fn median3(img: &Image, occupancy: &[u32]) -> Image {
    let (w, h) = (img.width, img.height);
    let mut out = Image::new(w, h, img.frames);
    out.data
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(row, line)| {
            let (frame, y) = (row / h, row % h);
            let base = frame * w * h;
            let mut window: [Vec<f64>; 3] = Default::default();
            for (x, out_px) in line.iter_mut().enumerate() {
                if occupancy[base + y * w + x] == 0 {
                    continue;
                }
                window.iter_mut().for_each(Vec::clear);
                for yy in y.saturating_sub(1)..(y + 2).min(h) {
                    for xx in x.saturating_sub(1)..(x + 2).min(w) {
                        let q = base + yy * w + xx;
                        if occupancy[q] > 0 {
                            for (ch, v) in window.iter_mut().zip(img.data[q]) {
                                ch.push(v);
                            }
                        }
                    }
                }
                *out_px = [0, 1, 2].map(|c| median(&mut window[c]));
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median3_by_hand() {
        // 3 × 3 values 1..9 in the red channel, one outlier of 100 at the
        // centre: the centre's median is the median of {1..4, 100, 6..9} = 6.
        let mut img = Image::new(3, 3, 1);
        for i in 0..9 {
            img.data[i] = [(i + 1) as f64, 0.0, 0.0];
        }
        img.data[4][0] = 100.0;
        let out = median3(&img, &[1; 9]);
        assert_eq!(out.data[4][0], 6.0);
        // Corner (0, 0): window {1, 2, 4, 100} → (2 + 4) / 2.
        assert_eq!(out.data[0][0], 3.0);
        // Without pixel 1 (empty), corner (0, 0): {1, 4, 100} → 4.
        let mut occ = [1u32; 9];
        occ[1] = 0;
        let out = median3(&img, &occ);
        assert_eq!(out.data[0][0], 4.0);
        assert_eq!(out.data[1], [0.0; 3]);
    }
}
