//! `pathdensity info`: what a dump holds, in bounded memory.
//!
//! Percentiles are exact with two passes and two 65536-bin histograms per
//! channel over the order-preserving bit pattern of the f32 values: the
//! first pass finds the bin of the high 16 bits holding each rank, the
//! second resolves the low 16 bits within that bin.

use std::path::Path;

use anyhow::Result;

use crate::dump::{DumpReader, Header, InvalidCounts, Record, Validity};
use crate::quantile::{exact, rank};

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

pub fn info(path: &Path) -> Result<Info> {
    let dump = DumpReader::open(path)?;
    let h = dump.header().clone();
    let recs = dump.records();
    let mut invalid = InvalidCounts::default();
    let mut valid = 0u64;
    for r in recs {
        match r.validity(&h) {
            Validity::Valid => valid += 1,
            v => invalid.add(v),
        }
    }
    // Ranks: min, the quantiles, max.
    let ranks = |n: u64| {
        std::iter::once(0)
            .chain(QUANTILES.iter().map(|&(_, q)| rank(q, n)))
            .chain(std::iter::once(n - 1))
            .collect()
    };
    let channel = |c: usize| {
        let value = |r: &Record| (r.validity(&h) == Validity::Valid).then(|| r.rgb()[c]);
        let v = exact(recs, value, ranks)?;
        Some(ChannelStats {
            min: v[0],
            p50: v[1],
            p99: v[2],
            p99_9: v[3],
            max: v[4],
        })
    };
    let channels = (valid > 0).then(|| [0, 1, 2].map(|c| channel(c).expect("valid values")));
    dump.intact()?;
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
        "{}\n  film        {} × {} px, {} frame(s), {} spp, order {}\n  scene       {:?} (seed {}, producer {:?})\n  records     {} ({} valid; invalid: {} non-finite, {} outside film, {} outside time)\n",
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
