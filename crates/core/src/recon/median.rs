//! Per-pixel medians (docs/filter.md §3): per channel, the middle value of the valid
//! samples a pixel contains, the mean of the two middle ones for an even count.

use std::collections::HashMap;

use crate::dump::{Header, Record, Validity};

/// The median of `v` (reordered in place); 0 for an empty slice.
///
/// ```
/// let mut v = [3.0, 1.0, 4.0, 1.5];
/// assert_eq!(pathdensity_core::recon::median::median(&mut v), 2.25);
/// ```
pub fn median(v: &mut [f64]) -> f64 {
    let n = v.len();
    if n == 0 {
        return 0.0;
    }
    v.sort_unstable_by(f64::total_cmp);
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

/// Per-channel medians of the pixels listed in `pixels` (flat indices),
/// gathering only those pixels' samples in one pass over the dump.
pub fn pixel_medians(records: &[Record], h: &Header, pixels: &[usize]) -> Vec<[f64; 3]> {
    if pixels.is_empty() {
        return Vec::new();
    }
    let slot: HashMap<usize, usize> = pixels.iter().enumerate().map(|(i, &p)| (p, i)).collect();
    let mut samples: Vec<[Vec<f64>; 3]> = vec![Default::default(); pixels.len()];
    for r in records {
        if r.validity(h) != Validity::Valid {
            continue;
        }
        if let Some(&s) = slot.get(&r.pixel_index(h)) {
            for (c, v) in r.rgb().into_iter().enumerate() {
                samples[s][c].push(v as f64);
            }
        }
    }
    samples
        .into_iter()
        .map(|mut ch| [median(&mut ch[0]), median(&mut ch[1]), median(&mut ch[2])])
        .collect()
}
