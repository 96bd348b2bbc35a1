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
    sort_total(v);
    median_of_sorted(v)
}

/// The median of `v` sorted by [`sort_total`]; 0 for an empty slice.
pub fn median_of_sorted(v: &[f64]) -> f64 {
    let n = v.len();
    if n == 0 {
        return 0.0;
    }
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

/// Sorts `v` in [`f64::total_cmp`]'s order, comparing integers: each
/// value's bits are mapped in place to those of an i64 that orders the
/// same way, sorted by it, and mapped back. Equal keys are equal bits, so
/// the result is the one `sort_unstable_by(f64::total_cmp)` gives, which
/// maps both sides of every comparison.
pub fn sort_total(v: &mut [f64]) {
    // total_cmp's key: negative values' magnitude bits flipped. The map
    // is its own inverse.
    let flip = |x: &mut f64| {
        let b = x.to_bits() as i64;
        *x = f64::from_bits((b ^ (((b >> 63) as u64) >> 1) as i64) as u64);
    };
    v.iter_mut().for_each(flip);
    v.sort_unstable_by_key(|x| x.to_bits() as i64);
    v.iter_mut().for_each(flip);
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The same bits, in the same order, as sorting by `total_cmp`, on
    /// signed zeros, NaNs of either sign, infinities and subnormals.
    #[test]
    fn sort_total_is_total_cmps_order() {
        let mut unit = crate::synth::test_units(99);
        let specials = [
            0.0,
            -0.0,
            f64::NAN,
            -f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MIN_POSITIVE / 4.0,
            -f64::MIN_POSITIVE / 4.0,
            f64::MAX,
            f64::MIN,
        ];
        for n in [0, 1, 2, 7, 64, 300] {
            let mut v: Vec<f64> = (0..n)
                .map(|i| match i % 4 {
                    0 => specials[i % specials.len()],
                    1 => (unit() - 0.5) * 1e3,
                    _ => ((unit() * 8.0).floor() - 4.0) * 0.25,
                })
                .collect();
            let mut want = v.clone();
            want.sort_unstable_by(f64::total_cmp);
            sort_total(&mut v);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&v), bits(&want), "n {n}");
        }
    }
}
