//! Per-pixel folds of a dump's samples in file order, pixel bands apart.

use crate::dump::{Header, Record, Validity};
use crate::par::prelude::*;

/// Per pixel (all frames), `add` folded over its valid samples that
/// `keep(i)` picks (record i), in file order. The pixels are split into
/// `bands` bands of rows, one job each, and each job scans every record
/// for its own: each pixel's fold is the serial one for any number of
/// bands, at the cost of one scan of the dump a band.
pub fn fold<A: Default + Clone + Send>(
    records: &[Record],
    h: &Header,
    bands: usize,
    keep: impl Fn(usize) -> bool + Sync,
    add: impl Fn(&mut A, [f64; 3]) + Sync,
) -> Vec<A> {
    let width = (h.width as usize).max(1);
    let pixels = h.pixels() * h.frames as usize;
    let mut acc = vec![A::default(); pixels];
    let band = (pixels / width).div_ceil(bands.max(1)).max(1) * width;
    acc.par_chunks_mut(band).enumerate().for_each(|(b, acc)| {
        let first = b * band;
        for (i, r) in records.iter().enumerate() {
            if r.validity(h) != Validity::Valid {
                continue;
            }
            let Some(a) = r
                .pixel_index(h)
                .checked_sub(first)
                .and_then(|p| acc.get_mut(p))
            else {
                continue;
            };
            if keep(i) {
                add(a, [r.r as f64, r.g as f64, r.b as f64]);
            }
        }
    });
    acc
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::SynthParams;

    /// Any number of bands folds each pixel's samples in file order: the
    /// list of each pixel's picked records is the serial scan's.
    #[test]
    fn bands_fold_each_pixel_in_file_order() {
        let synth = SynthParams {
            width: 7,
            height: 5,
            frames: 2,
            spp: 6,
            ..SynthParams::default()
        };
        let (h, mut records): (Header, Vec<Record>) = (synth.header(), synth.records().collect());
        records[3].x = f32::NAN;
        records[10].y = -1.0;
        let keep = |i: usize| i % 5 != 2;
        let serial: Vec<Vec<usize>> = {
            let mut v = vec![Vec::new(); h.pixels() * 2];
            for (i, r) in records.iter().enumerate() {
                if r.validity(&h) == Validity::Valid && keep(i) {
                    v[r.pixel_index(&h)].push(i);
                }
            }
            v
        };
        for bands in [1, 2, 3, 4, 10, 100] {
            // The record's red value names it: the fold sees which, in order.
            let named: Vec<Record> = records
                .iter()
                .enumerate()
                .map(|(i, r)| Record { r: i as f32, ..*r })
                .collect();
            let got: Vec<Vec<usize>> = fold(&named, &h, bands, keep, |a: &mut Vec<usize>, c| {
                a.push(c[0] as usize)
            });
            assert_eq!(got, serial, "{bands} bands");
        }
    }
}
