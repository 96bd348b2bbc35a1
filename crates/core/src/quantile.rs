//! Exact nearest-rank quantiles of f32 values in two parallel passes with
//! fixed-size histograms (the high 16 bits of an order-preserving key, then
//! the low 16 bits inside the bins that hold the wanted ranks), so dumps
//! larger than memory work.

/// Maps an f32 to a u32 whose unsigned order is the float order.
pub fn key(v: f32) -> u32 {
    let b = v.to_bits();
    if b & 0x8000_0000 != 0 {
        !b
    } else {
        b | 0x8000_0000
    }
}

fn from_key(k: u32) -> f32 {
    f32::from_bits(if k & 0x8000_0000 != 0 {
        k & 0x7fff_ffff
    } else {
        !k
    })
}

/// Nearest-rank index (0-based) of quantile q among n > 0 values: the value
/// at 1-based rank ⌈q·n⌉.
pub fn rank(q: f64, n: u64) -> u64 {
    ((q * n as f64).ceil() as u64).clamp(1, n) - 1
}

/// Items a histogram pass takes at a time: each chunk counts into its own
/// histograms, which are then added, so the counts (and the quantiles)
/// are the same for any thread count.
const CHUNK: usize = 1 << 20;

/// The values at the 0-based `ranks` of the sorted sequence of the values
/// `value` gives the `items` (`None` skips an item; no NaN), in two
/// passes over the items, each in parallel. None when there is no value.
///
/// ```
/// use pathdensity_core::quantile::{exact, rank};
/// let v = [5.0f32, -1.0, 3.0, 3.0, 100.0];
/// let got = exact(&v, |&x| Some(x), |n| vec![0, rank(0.5, n), n - 1]);
/// assert_eq!(got, Some(vec![-1.0, 3.0, 100.0]));
/// ```
pub fn exact<T: Sync>(
    items: &[T],
    value: impl Fn(&T) -> Option<f32> + Sync,
    ranks: impl FnOnce(u64) -> Vec<u64>,
) -> Option<Vec<f32>> {
    let hi = histograms(
        items,
        |chunk, h: &mut [Vec<u64>]| {
            for k in chunk.iter().filter_map(&value).map(key) {
                h[0][(k >> 16) as usize] += 1;
            }
        },
        1,
    )
    .pop()?;
    let n: u64 = hi.iter().sum();
    if n == 0 {
        return None;
    }
    let ranks = ranks(n);
    let targets: Vec<(u32, u64)> = ranks
        .iter()
        .map(|&rk| {
            let mut seen = 0u64;
            for (bin, &c) in hi.iter().enumerate() {
                if seen + c > rk {
                    return (bin as u32, rk - seen);
                }
                seen += c;
            }
            unreachable!("rank {rk} not below the count {n}")
        })
        .collect();
    let lo = histograms(
        items,
        |chunk, h: &mut [Vec<u64>]| {
            for k in chunk.iter().filter_map(&value).map(key) {
                for (t, &(bin, _)) in targets.iter().enumerate() {
                    if k >> 16 == bin {
                        h[t][(k & 0xffff) as usize] += 1;
                    }
                }
            }
        },
        targets.len(),
    );
    Some(
        targets
            .iter()
            .zip(&lo)
            .map(|(&(bin, mut within), counts)| {
                for (low, &c) in counts.iter().enumerate() {
                    if within < c {
                        return from_key(bin << 16 | low as u32);
                    }
                    within -= c;
                }
                unreachable!("rank below the bin count")
            })
            .collect(),
    )
}

/// `count` histograms of 2¹⁶ bins over `items`: `fill` counts one chunk
/// into its own set, and the sets are added.
fn histograms<T: Sync>(
    items: &[T],
    fill: impl Fn(&[T], &mut [Vec<u64>]) + Sync,
    count: usize,
) -> Vec<Vec<u64>> {
    use crate::par::prelude::*;
    let empty = || vec![vec![0u64; 1 << 16]; count];
    let sets: Vec<Vec<Vec<u64>>> = items
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut h = empty();
            fill(chunk, &mut h);
            h
        })
        .collect();
    let mut total = empty();
    for set in sets {
        for (t, h) in total.iter_mut().zip(set) {
            for (a, b) in t.iter_mut().zip(h) {
                *a += b;
            }
        }
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn key_preserves_float_order() {
        let v = [
            f32::NEG_INFINITY,
            -3e38,
            -1.0,
            -1e-40,
            -0.0,
            0.0,
            1e-45,
            1.0,
            f32::MAX,
        ];
        for w in v.windows(2) {
            assert!(key(w[0]) <= key(w[1]));
            assert_eq!(from_key(key(w[0])).to_bits(), w[0].to_bits());
        }
    }

    #[test]
    fn matches_sorting() {
        let v: Vec<f32> = (0..10_000u32)
            .map(|i| ((i.wrapping_mul(2_654_435_761) % 1000) as f32 - 500.0) * 0.37)
            .collect();
        let mut s = v.clone();
        s.sort_by(f32::total_cmp);
        for q in [0.0, 0.01, 0.5, 0.99, 0.999, 1.0] {
            let got = exact(&v, |&x| Some(x), |n| vec![rank(q, n)]).unwrap();
            assert_eq!(got[0], s[rank(q, 10_000) as usize], "q {q}");
        }
        assert_eq!(exact(&[] as &[f32], |&x| Some(x), |_| vec![0]), None);
    }
}
