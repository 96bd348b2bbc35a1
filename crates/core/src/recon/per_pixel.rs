//! Per-pixel folds of a dump's samples in file order.

use std::sync::atomic::{AtomicBool, Ordering::Relaxed};

use crate::dump::{Header, Order, Record, Validity};
use crate::par::prelude::*;

/// Bytes of accumulators a job of a pass-major fold keeps in the core's
/// cache while it reads its pixels' samples pass by pass.
const TILE_BYTES: usize = 1 << 18;

/// Per pixel (all frames), `add` folded over its valid samples that
/// `keep(i)` picks (record i), in file order, by `bands` jobs (1: on
/// this thread alone). Each pixel's fold is the serial one whatever the
/// number of jobs.
///
/// A pass-major dump is read tile by tile of pixels, each tile's samples
/// pass by pass, so that its accumulators stay in cache ([`by_tiles`]);
/// any other dump in bands of rows, each band's job scanning every record
/// for its own.
pub fn fold<A: Default + Clone + Send>(
    records: &[Record],
    h: &Header,
    bands: usize,
    keep: impl Fn(usize) -> bool + Sync,
    add: impl Fn(&mut A, [f64; 3]) + Sync,
) -> Vec<A> {
    if let Some(acc) = by_tiles(records, h, bands > 1, &keep, &add) {
        return acc;
    }
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

/// [`fold`] of a dump that declares pass-major order and holds exactly its
/// film's samples: record (f·spp + s)·P + p is sample s of pixel p of
/// frame f (P pixels a frame), so a tile of a frame's pixels finds its
/// samples as one run of records a pass, in file order. None when the
/// dump does not declare that order, or when a valid record lies outside
/// the pixel its place says (then the order does not hold, and [`fold`]
/// scans).
fn by_tiles<A: Default + Clone + Send>(
    records: &[Record],
    h: &Header,
    parallel: bool,
    keep: &(impl Fn(usize) -> bool + Sync),
    add: &(impl Fn(&mut A, [f64; 3]) + Sync),
) -> Option<Vec<A>> {
    let (pixels, frames, spp) = (h.pixels(), h.frames as usize, h.spp as usize);
    let complete = (pixels * frames).checked_mul(spp) == Some(records.len());
    if h.order != Order::PassMajor || !complete || records.is_empty() {
        return None;
    }
    let misplaced = AtomicBool::new(false);
    let tile = (TILE_BYTES / size_of::<A>().max(1)).max(1);
    let mut acc = vec![A::default(); pixels * frames];
    let fill = |(first, acc): (usize, &mut [A])| {
        let (frame, p0) = (first / pixels, first % pixels);
        let n = acc.len();
        for s in 0..spp {
            let base = (frame * spp + s) * pixels + p0;
            for (j, (a, r)) in acc.iter_mut().zip(&records[base..base + n]).enumerate() {
                if r.validity(h) != Validity::Valid {
                    continue;
                }
                if r.pixel_index(h) != first + j {
                    misplaced.store(true, Relaxed);
                    return;
                }
                if keep(base + j) {
                    add(a, [r.r as f64, r.g as f64, r.b as f64]);
                }
            }
        }
    };
    // Tiles within a frame, so that each is one run a pass.
    let tiles = acc
        .chunks_mut(pixels)
        .flat_map(|frame| frame.chunks_mut(tile));
    let tiles: Vec<(usize, &mut [A])> = tiles
        .scan(0, |start, t| {
            let first = *start;
            *start += t.len();
            Some((first, t))
        })
        .collect();
    if parallel {
        tiles.into_par_iter().for_each(fill);
    } else {
        tiles.into_iter().for_each(fill);
    }
    (!misplaced.into_inner()).then_some(acc)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::SynthParams;

    /// Any number of bands, or tiles of a pass-major dump, folds each
    /// pixel's samples in file order: the list of each pixel's picked
    /// records is the serial scan's, in either order, and with a record
    /// that is not where a pass-major order puts it.
    #[test]
    fn bands_fold_each_pixel_in_file_order() {
        for (order, misplace) in [
            (Order::PixelMajor, false),
            (Order::PassMajor, false),
            (Order::PassMajor, true),
        ] {
            check_bands(order, misplace);
        }
    }

    fn check_bands(order: Order, misplace: bool) {
        let synth = SynthParams {
            width: 7,
            height: 5,
            frames: 2,
            spp: 6,
            order,
            ..SynthParams::default()
        };
        let (h, mut records): (Header, Vec<Record>) = (synth.header(), synth.records().collect());
        records[3].x = f32::NAN;
        records[10].y = -1.0;
        if misplace {
            // A sample of pixel (0, 0) where the order has another pixel's.
            records[200].x = 0.5;
            records[200].y = 0.5;
        }
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
            assert_eq!(got, serial, "{order} misplaced {misplace}: {bands} bands");
        }
    }
}
