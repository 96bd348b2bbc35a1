//! `pathdensity info`: what a dump holds, in bounded memory.
//!
//! Percentiles are exact with two passes and two 65536-bin histograms per
//! channel over the order-preserving bit pattern of the f32 values: the
//! first pass finds the bin of the high 16 bits holding each rank, the
//! second resolves the low 16 bits within that bin.

use std::path::Path;

use anyhow::Result;

use crate::dump::{DumpReader, Header, InvalidCounts, Record, Validity};

/// The percentiles reported, as fractions.
pub const QUANTILES: [(&str, f64); 3] = [("p50", 0.5), ("p99", 0.99), ("p99_9", 0.999)];

#[derive(Clone, Debug, serde::Serialize)]
pub struct ChannelStats {
    pub min: f32,
    pub p50: f32,
    pub p99: f32,
    pub p99_9: f32,
    pub max: f32,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Info {
    pub path: String,
    pub header: Header,
    pub header_len: usize,
    pub valid: u64,
    pub invalid: InvalidCounts,
    /// Radiance statistics of the valid records, for r, g and b; absent
    /// when there is no valid record.
    pub channels: Option<[ChannelStats; 3]>,
}

/// Maps an f32 to a u32 whose unsigned order is the float order.
fn key(v: f32) -> u32 {
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

/// Nearest-rank index (0-based) of quantile q among n values.
fn rank(q: f64, n: u64) -> u64 {
    ((q * n as f64).ceil() as u64).clamp(1, n) - 1
}

fn valid_records<'a>(recs: &'a [Record], h: &'a Header) -> impl Iterator<Item = &'a Record> + 'a {
    recs.iter()
        .filter(move |r| r.validity(h) == Validity::Valid)
}

pub fn info(path: &Path) -> Result<Info> {
    let dump = DumpReader::open(path)?;
    let h = dump.header().clone();
    let recs = dump.records();
    let mut invalid = InvalidCounts::default();
    let mut hi = vec![[0u64; 3]; 1 << 16];
    let mut valid = 0u64;
    for r in recs {
        match r.validity(&h) {
            Validity::Valid => {
                valid += 1;
                for (c, v) in r.rgb().into_iter().enumerate() {
                    hi[(key(v) >> 16) as usize][c] += 1;
                }
            }
            v => invalid.add(v),
        }
    }
    let channels = (valid > 0).then(|| {
        // Ranks: min, the quantiles, max.
        let ranks: Vec<u64> = std::iter::once(0)
            .chain(QUANTILES.iter().map(|&(_, q)| rank(q, valid)))
            .chain(std::iter::once(valid - 1))
            .collect();
        // For each channel and rank: its high bin and the rank within it.
        let locate = |c: usize, rk: u64| {
            let mut seen = 0u64;
            for (bin, n) in hi.iter().enumerate() {
                if seen + n[c] > rk {
                    return (bin as u32, rk - seen);
                }
                seen += n[c];
            }
            unreachable!("rank below the count")
        };
        let targets: Vec<Vec<(u32, u64)>> = (0..3)
            .map(|c| ranks.iter().map(|&rk| locate(c, rk)).collect())
            .collect();
        let mut lo = vec![vec![vec![0u64; 1 << 16]; ranks.len()]; 3];
        for r in valid_records(recs, &h) {
            for (c, v) in r.rgb().into_iter().enumerate() {
                let k = key(v);
                for (t, &(bin, _)) in targets[c].iter().enumerate() {
                    if k >> 16 == bin {
                        lo[c][t][(k & 0xffff) as usize] += 1;
                    }
                }
            }
        }
        let value = |c: usize, t: usize| {
            let (bin, mut within) = targets[c][t];
            for (low, &n) in lo[c][t].iter().enumerate() {
                if within < n {
                    return from_key(bin << 16 | low as u32);
                }
                within -= n;
            }
            unreachable!("rank below the bin count")
        };
        [0, 1, 2].map(|c| ChannelStats {
            min: value(c, 0),
            p50: value(c, 1),
            p99: value(c, 2),
            p99_9: value(c, 3),
            max: value(c, 4),
        })
    });
    Ok(Info {
        path: path.display().to_string(),
        header: h,
        header_len: dump.header_len(),
        valid,
        invalid,
        channels,
    })
}

/// A human-readable rendering of [`Info`].
pub fn render(i: &Info) -> String {
    let h = &i.header;
    let mut s = format!(
        "{}\n  film        {} × {} px, {} frame(s), {} spp, order {:?}\n  scene       {:?} (seed {}, producer {:?})\n  records     {} ({} valid; invalid: {} non-finite, {} outside film, {} outside time)\n",
        i.path,
        h.width,
        h.height,
        h.frames,
        h.spp,
        h.order,
        h.scene,
        h.seed,
        h.producer,
        h.sample_count,
        i.valid,
        i.invalid.non_finite,
        i.invalid.outside_film,
        i.invalid.outside_time
    );
    if let Some(ch) = &i.channels {
        s += &format!(
            "  {:<8}{:>13}{:>13}{:>13}{:>13}{:>13}\n",
            "channel", "min", "p50", "p99", "p99.9", "max"
        );
        for (name, c) in ["r", "g", "b"].iter().zip(ch) {
            s += &format!(
                "  {:<8}{:>13.6e}{:>13.6e}{:>13.6e}{:>13.6e}{:>13.6e}\n",
                name, c.min, c.p50, c.p99, c.p99_9, c.max
            );
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn key_preserves_float_order() {
        let v = [-3e38f32, -1.0, -1e-40, -0.0, 0.0, 1e-40, 1.0, 3e38];
        for w in v.windows(2) {
            assert!(key(w[0]) <= key(w[1]));
            assert_eq!(from_key(key(w[0])).to_bits(), w[0].to_bits());
        }
    }
}
