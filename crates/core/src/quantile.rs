//! Exact nearest-rank quantiles of f32 values in two streaming passes with
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

/// The values at the 0-based `ranks` of the sorted sequence that `values()`
/// yields (called twice; it must yield the same non-NaN values each time).
/// None when the sequence is empty.
///
/// ```
/// use pathdensity_core::quantile::{exact, rank};
/// let v = [5.0f32, -1.0, 3.0, 3.0, 100.0];
/// let got = exact(|| v.iter().copied(), |n| vec![0, rank(0.5, n), n - 1]);
/// assert_eq!(got, Some(vec![-1.0, 3.0, 100.0]));
/// ```
pub fn exact<I: Iterator<Item = f32>>(
    values: impl Fn() -> I,
    ranks: impl FnOnce(u64) -> Vec<u64>,
) -> Option<Vec<f32>> {
    let mut hi = vec![0u64; 1 << 16];
    let mut n = 0u64;
    for v in values() {
        hi[(key(v) >> 16) as usize] += 1;
        n += 1;
    }
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
    let mut lo = vec![vec![0u64; 1 << 16]; targets.len()];
    for v in values() {
        let k = key(v);
        for (t, &(bin, _)) in targets.iter().enumerate() {
            if k >> 16 == bin {
                lo[t][(k & 0xffff) as usize] += 1;
            }
        }
    }
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
            let got = exact(|| v.iter().copied(), |n| vec![rank(q, n)]).unwrap();
            assert_eq!(got[0], s[rank(q, 10_000) as usize], "q {q}");
        }
        assert_eq!(exact(std::iter::empty, |_| vec![0]), None);
    }
}
