//! The shared pieces: made together as made apart, and each image makes
//! exactly the pieces its row lists.

use super::*;
use crate::recon::{self, test_header};

impl Estimators<'_, '_> {
    /// Which shared pieces have been made, in [`Piece::ALL`]'s order.
    fn made(&self) -> Vec<Piece> {
        // Sized by Piece::ALL: a new piece must be added here too.
        let set: [bool; Piece::ALL.len()] = [
            self.robust.get().is_some(),
            self.mon.get().is_some(),
            self.filtered_energy.get().is_some(),
            self.shared.interval.get().is_some(),
            self.shared.oidn_mean.get().is_some(),
            self.accepted_interval.get().is_some(),
            self.statmc.get().is_some(),
        ];
        Piece::ALL
            .into_iter()
            .zip(set)
            .filter(|p| p.1)
            .map(|p| p.0)
            .collect()
    }
}

/// The accepted samples' intervals and statmc made together by
/// `prepare` are those each makes on its own: guided and
/// guided_oidn's hold read the one, statmc and guided the other.
#[test]
fn the_pieces_made_together_are_those_made_apart() {
    let synth = crate::synth::SynthParams {
        width: 23,
        height: 9,
        spp: 12,
        firefly_fraction: 0.03,
        ..crate::synth::SynthParams::default()
    };
    let (h, records): (Header, Vec<Record>) = (synth.header(), synth.records().collect());
    let config = FilterConfig::DEFAULT;
    let decisions: Vec<u8> = (0..records.len())
        .map(|i| if i % 7 == 3 { Decision::Rejected } else { Decision::AcceptedStreaming } as u8)
        .collect();
    let rec = recon::reconstruct(&records, &h, config.recon.filter(), |i| i % 7 != 3);
    let core = Core::new(rec, 0.0, 0.0);
    let shared = Shared::new(&records, &h);
    let made = |prepared: bool| {
        let e = Estimators::new(&shared, &config, 1.0, &core).with_decisions(&decisions);
        if prepared {
            e.prepare(&[(Method::Guided, false), (Method::Statmc, false)]);
            assert_eq!(
                e.made(),
                [Piece::Interval, Piece::AcceptedInterval, Piece::Statmc]
            );
        }
        [Method::Guided, Method::Statmc].map(|m| e.image(m).unwrap().0.data.clone())
    };
    let bits = |v: [Vec<[f64; 3]>; 2]| {
        v.map(|i| i.iter().map(|p| p.map(f64::to_bits)).collect::<Vec<_>>())
    };
    assert_eq!(bits(made(true)), bits(made(false)));
}

/// `prepare` can only make what [`Piece::of`] lists: every method's
/// image, made on its own, makes exactly its listed pieces.
#[test]
fn each_image_makes_exactly_the_pieces_it_lists() {
    let h = test_header(6, 5);
    let records: Vec<Record> = (0..6 * 5 * 12)
        .map(|i| {
            let v = 0.1 + (i % 17) as f32 * if i % 53 == 0 { 40.0 } else { 0.02 };
            Record::new(
                (i % 6) as f32 + 0.5,
                ((i / 6) % 5) as f32 + 0.5,
                0.0,
                [v; 3],
            )
        })
        .collect();
    let config = FilterConfig::DEFAULT;
    let rec = recon::reconstruct(&records, &h, config.recon.filter(), |i| i % 53 != 0);
    let core = Core::new(rec, 0.0, 0.0);
    for method in Method::ALL {
        let shared = Shared::new(&records, &h);
        let decisions = vec![0u8; records.len()];
        let estimators = Estimators::new(&shared, &config, 1.0, &core).with_decisions(&decisions);
        let made = estimators.image(method);
        let mut want = Piece::of(method).to_vec();
        want.sort_by_key(|p| Piece::ALL.iter().position(|q| q == p));
        match made {
            Ok(_) => assert_eq!(estimators.made(), want, "{method:?}"),
            // OIDN's methods where no OIDN is found: they stop at
            // the piece that failed, which keeps the error.
            Err(_) => {
                let made = estimators.made();
                assert!(!made.is_empty(), "{method:?}");
                assert!(made.iter().all(|p| want.contains(p)), "{method:?}");
            }
        }
    }
}
