//! The σ a replay keeps ([`super::ExactSigma`]): every record's, as one
//! array, or only those of the records asked for — one slot each where
//! the dump's order tells which they are, else (record, σ) pairs — so
//! that the report's σ map (a share of each pixel's samples) costs memory in
//! proportion to its share of the dump rather than to the whole dump.

use super::{ExactSigma, Strata};

/// The σ that decided each record a replay was asked for.
///
/// Invariant once [`Sigmas::finish`] has run: `Sparse` pairs are sorted by
/// record, each record once.
///
/// ```
/// use pathdensity_core::density::{ExactSigma, Sigmas};
/// let mut s = Sigmas::new(ExactSigma::OneIn(2), 4);
/// s.set(3, 0.5);
/// s.set(1, 2.0);
/// s.set(3, 0.25); // a later σ of the same record (the final pass's) wins
/// s.finish();
/// assert_eq!(s.get(3), 0.25);
/// assert!(s.get(0).is_nan());
/// assert_eq!(s.kept().collect::<Vec<_>>(), [(1, 2.0), (3, 0.25)]);
/// ```
#[derive(Clone, Debug)]
pub enum Sigmas {
    /// One σ per record, in file order; NaN where none was kept.
    Dense(Vec<f64>),
    /// (record, σ) of the records asked for.
    Sparse(Vec<(u64, f64)>),
    /// One σ per record the strata pick, at [`Strata::slot`]; NaN where
    /// none was kept. Half the pairs' memory.
    Strata(Strata, Vec<f64>),
}

impl Sigmas {
    /// Room for `exact`'s σ over `records` records: an array when it asks
    /// for every one.
    pub fn new(exact: ExactSigma, records: usize) -> Sigmas {
        match exact {
            ExactSigma::All => Sigmas::Dense(vec![f64::NAN; records]),
            ExactSigma::Strata(s) => Sigmas::Strata(s, vec![f64::NAN; s.slots(records)]),
            ExactSigma::None | ExactSigma::OneIn(_) => Sigmas::Sparse(Vec::new()),
        }
    }

    /// Keeps `sigma` as record `rec`'s, replacing an earlier one.
    #[inline]
    pub fn set(&mut self, rec: usize, sigma: f64) {
        match self {
            Sigmas::Dense(v) => v[rec] = sigma,
            Sigmas::Sparse(v) => v.push((rec as u64, sigma)),
            Sigmas::Strata(s, v) => v[s.slot(rec as u64)] = sigma,
        }
    }

    /// Sorts the pairs by record, keeping each record's last σ. Call it
    /// once every σ is set, before reading.
    pub fn finish(&mut self) {
        if let Sigmas::Sparse(v) = self {
            // Stable: a record's pairs stay in the order they were set, and
            // the last one set replaces the one kept.
            v.sort_by_key(|&(rec, _)| rec);
            v.dedup_by(|later, kept| {
                let same = later.0 == kept.0;
                if same {
                    *kept = *later;
                }
                same
            });
        }
    }

    /// Record `rec`'s σ, NaN if none was kept.
    pub fn get(&self, rec: usize) -> f64 {
        match self {
            Sigmas::Dense(v) => v[rec],
            Sigmas::Sparse(v) => v
                .binary_search_by_key(&(rec as u64), |&(r, _)| r)
                .map_or(f64::NAN, |i| v[i].1),
            Sigmas::Strata(s, v) => match s.wants(rec as u64) {
                true => v[s.slot(rec as u64)],
                false => f64::NAN,
            },
        }
    }

    /// Calls `f` with (record, σ) in record order, as [`Sigmas::kept`]
    /// gives them, without testing every record where the strata tell
    /// which are kept.
    pub fn for_each_kept(&self, mut f: impl FnMut(usize, f64)) {
        match self {
            Sigmas::Strata(s, v) => {
                s.for_each_wanted(0..s.records(v.len()), |rec| f(rec as usize, v[s.slot(rec)]));
            }
            _ => self.kept().for_each(|(rec, s)| f(rec, s)),
        }
    }

    /// (record, σ) in record order; NaN where an array keeps none.
    pub fn kept(&self) -> Box<dyn Iterator<Item = (usize, f64)> + '_> {
        match self {
            Sigmas::Dense(v) => Box::new(v.iter().copied().enumerate()),
            Sigmas::Sparse(v) => Box::new(v.iter().map(|&(r, s)| (r as usize, s))),
            Sigmas::Strata(s, v) => {
                let s = *s;
                Box::new(
                    (0..s.records(v.len()))
                        .filter(move |&rec| s.wants(rec))
                        .map(move |rec| (rec as usize, v[s.slot(rec)])),
                )
            }
        }
    }

    /// One σ per record of `records`, NaN where none was kept.
    pub fn to_dense(&self, records: usize) -> Vec<f64> {
        let mut out = vec![f64::NAN; records];
        self.for_each_kept(|rec, s| out[rec] = s);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pairs give what an array overwritten in the same order gives.
    #[test]
    fn sparse_pairs_read_like_an_overwritten_array() {
        let writes = [(5, 1.0), (2, 3.0), (5, 4.0), (0, 0.5), (2, 6.0), (5, 7.0)];
        let mut dense = Sigmas::new(ExactSigma::All, 7);
        let mut sparse = Sigmas::new(ExactSigma::OneIn(2), 7);
        for (rec, s) in writes {
            dense.set(rec, s);
            sparse.set(rec, s);
        }
        dense.finish();
        sparse.finish();
        let bits = |v: Vec<f64>| v.iter().map(|s| s.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(sparse.to_dense(7)), bits(dense.to_dense(7)));
        for rec in 0..7 {
            assert_eq!(sparse.get(rec).to_bits(), dense.get(rec).to_bits());
        }
        assert_eq!(sparse.kept().count(), 3);
    }

    /// Slots give what pairs give, for both declared orders, frames and a
    /// share that does not divide spp: every picked record has its own
    /// slot, read back in record order, later writes winning.
    #[test]
    fn strata_slots_read_like_pairs() {
        use crate::dump::Order;
        use crate::synth::SynthParams;
        for order in [Order::PixelMajor, Order::PassMajor] {
            let h = SynthParams {
                width: 5,
                height: 3,
                frames: 2,
                spp: 11,
                order,
                ..SynthParams::default()
            }
            .header();
            let n = h.sample_count as usize;
            let exact = ExactSigma::Strata(Strata::new(&h, 4).unwrap());
            let mut slots = Sigmas::new(exact, n);
            let mut pairs = Sigmas::Sparse(Vec::new());
            for (k, rec) in (0..n).chain((0..n).step_by(3)).enumerate() {
                if exact.wants(rec) {
                    slots.set(rec, k as f64);
                    pairs.set(rec, k as f64);
                }
            }
            slots.finish();
            pairs.finish();
            let bits = |s: &Sigmas| s.kept().map(|(r, v)| (r, v.to_bits())).collect::<Vec<_>>();
            assert_eq!(bits(&slots), bits(&pairs), "{order}");
            let mut each = Vec::new();
            slots.for_each_kept(|r, v| each.push((r, v.to_bits())));
            assert_eq!(each, bits(&pairs));
            for rec in 0..n {
                assert_eq!(slots.get(rec).to_bits(), pairs.get(rec).to_bits());
            }
        }
    }
}
