//! Per-pixel folds of a dump's samples in file order.

use std::ops::Range;
use std::sync::atomic::{AtomicBool, Ordering::Relaxed};

use crate::dump::{Header, Order, Record, Validity};
use crate::par::prelude::*;

/// Bytes of accumulators a job keeps in the core's cache while it reads
/// its pixels' samples ([`in_place`]).
const TILE_BYTES: usize = 1 << 18;

/// At most this many bands scan the dump where its order is not known:
/// each reads every record.
const MAX_BANDS: usize = 8;

/// Per pixel (all frames), `add` folded over its valid samples that
/// `keep(i)` picks (record i), in file order, by up to `jobs` jobs at a
/// time (1: on this thread alone). Each pixel's fold is the serial one
/// whatever the number of jobs.
///
/// A pixel- or pass-major dump is read in place, tile by tile of pixels
/// ([`in_place`]); any other in bands of rows, each band's job scanning
/// every record for its own.
pub fn fold<A: Default + Clone + Send>(
    records: &[Record],
    h: &Header,
    jobs: usize,
    keep: impl Fn(usize) -> bool + Sync,
    add: impl Fn(&mut A, [f64; 3]) + Sync,
) -> Vec<A> {
    let colour = |i: usize, r: &Record| keep(i).then_some([r.r as f64, r.g as f64, r.b as f64]);
    fold_colours(records, h, jobs, colour, add)
}

/// [`fold`] of the items `colour(i, r)` gives the valid samples it picks
/// (record i, called for valid records only): their colours, or anything
/// `add` takes.
pub fn fold_colours<A: Default + Clone + Send, T>(
    records: &[Record],
    h: &Header,
    jobs: usize,
    colour: impl Fn(usize, &Record) -> Option<T> + Sync,
    add: impl Fn(&mut A, T) + Sync,
) -> Vec<A> {
    let film = 0..h.pixels() * h.frames as usize;
    let tile = (TILE_BYTES / size_of::<A>().max(1)).max(1);
    if let Some(acc) = in_place(records, h, film.clone(), jobs > 1, tile, &colour, &add) {
        return acc;
    }
    let width = (h.width as usize).max(1);
    let mut acc = vec![A::default(); film.len()];
    let jobs = jobs.clamp(1, MAX_BANDS);
    let rows = (film.len() / width).div_ceil(jobs).max(1) * width;
    acc.par_chunks_mut(rows).enumerate().for_each(|(b, acc)| {
        let first = b * rows;
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
            if let Some(c) = colour(i, r) {
                add(a, c);
            }
        }
    });
    acc
}

/// A band of one frame's rows, with up to `halo` rows of the frame either
/// side: [`fold_in_bands`] folds one at a time, so that what is made from
/// a pixel's neighbourhood (within `halo` rows) is the whole film's, with
/// the folds of a band of the film in memory rather than all of them.
pub struct RowBand {
    /// The folded rows' geometry as a film of their own: the film's width,
    /// the band's rows with their halo, one frame (the whole film's header
    /// where the band is the film). Its sample count and order are the
    /// film's: never a header to fold a dump with.
    pub header: Header,
    /// The film's pixels folded (indices over all frames).
    pub pixels: Range<usize>,
    /// The band's own pixels among them, counted from `pixels.start`.
    pub own: Range<usize>,
}

impl RowBand {
    /// The whole film as one band.
    pub fn film(h: &Header) -> RowBand {
        let all = 0..h.pixels() * h.frames as usize;
        RowBand {
            header: h.clone(),
            own: all.clone(),
            pixels: all,
        }
    }

    /// The band's own pixels of `src` (one per folded pixel) written to
    /// `dst` (one per film pixel).
    pub fn put<T: Copy>(&self, dst: &mut [T], src: &[T]) {
        self.own_of(dst).copy_from_slice(&src[self.own.clone()]);
    }

    /// The band's own pixels of `film` (one per film pixel).
    pub fn own_of<'a, T>(&self, film: &'a mut [T]) -> &'a mut [T] {
        let at = self.pixels.start + self.own.start;
        &mut film[at..at + self.own.len()]
    }
}

/// The film in bands of whole rows whose own rows keep about `budget`
/// bytes of `pixel_bytes` a pixel (one row at least; the halo's come on
/// top), each frame apart, with `halo` rows either side within the frame;
/// one band, the film, where that is all of it.
pub fn row_bands(h: &Header, pixel_bytes: usize, budget: usize, halo: usize) -> Vec<RowBand> {
    let (w, ht, frames) = (h.width as usize, h.height as usize, h.frames as usize);
    let rows = (budget / (w * pixel_bytes).max(1)).max(1);
    if rows >= ht && frames == 1 {
        return vec![RowBand::film(h)];
    }
    let mut bands = Vec::new();
    for frame in 0..frames {
        for y0 in (0..ht).step_by(rows) {
            let y1 = (y0 + rows).min(ht);
            let (from, to) = (y0.saturating_sub(halo), (y1 + halo).min(ht));
            let first = (frame * ht + from) * w;
            bands.push(RowBand {
                header: Header {
                    height: (to - from) as u32,
                    frames: 1,
                    ..h.clone()
                },
                pixels: first..first + (to - from) * w,
                own: (y0 - from) * w..(y1 - from) * w,
            });
        }
    }
    bands
}

/// [`fold_colours`] band by band: `each(band, folds)` for each of `bands`
/// in turn with the folds of its pixels. Bands are read in place, which
/// needs a dump whose declared order holds ([`in_place`]): where one
/// cannot be, a band before it may have missed a sample lying in its
/// rows, so the film is folded whole and given as one last band
/// ([`RowBand::film`]), its every pixel's fold [`fold_colours`]'s.
pub fn fold_in_bands<A: Default + Clone + Send, T>(
    records: &[Record],
    h: &Header,
    bands: &[RowBand],
    jobs: usize,
    colour: impl Fn(usize, &Record) -> Option<T> + Sync,
    add: impl Fn(&mut A, T) + Sync,
    mut each: impl FnMut(&RowBand, &[A]),
) {
    let tile = (TILE_BYTES / size_of::<A>().max(1)).max(1);
    if bands.len() > 1 {
        let placed = bands.iter().all(|band| {
            let folds = in_place(
                records,
                h,
                band.pixels.clone(),
                jobs > 1,
                tile,
                &colour,
                &add,
            );
            folds.map(|folds| each(band, &folds)).is_some()
        });
        if placed {
            return;
        }
    }
    each(
        &RowBand::film(h),
        &fold_colours(records, h, jobs, colour, add),
    );
}

/// [`fold`] of the pixels `film` (indices over all frames, one
/// accumulator each) of a dump that declares pixel- or pass-major order
/// and holds exactly its film's samples, so that a record's place says its pixel
/// and sample: pixel-major, record p·spp + s is sample s of pixel p
/// (frames in turn); pass-major, record (f·spp + s)·P + p is
/// sample s of pixel p of frame f (P pixels a frame). Each job takes
/// `tile` pixels of one frame and reads their samples in file order: a
/// pixel's run of records at a time (pixel-major), or the tile's run of
/// each pass (pass-major), so its accumulators stay in cache. None when
/// the dump declares neither order, or when a valid record lies outside
/// the pixel its place says (then the order does not hold, and [`fold`]
/// scans).
fn in_place<A: Default + Clone + Send, T>(
    records: &[Record],
    h: &Header,
    film: Range<usize>,
    parallel: bool,
    tile: usize,
    colour: &(impl Fn(usize, &Record) -> Option<T> + Sync),
    add: &(impl Fn(&mut A, T) + Sync),
) -> Option<Vec<A>> {
    let pass_major = match h.order {
        Order::PassMajor => true,
        Order::PixelMajor => false,
        Order::Unspecified => return None,
    };
    let (pixels, frames, spp) = (h.pixels(), h.frames as usize, h.spp as usize);
    let complete = (pixels * frames).checked_mul(spp) == Some(records.len());
    if !complete || records.is_empty() {
        return None;
    }
    let misplaced = AtomicBool::new(false);
    let mut acc = vec![A::default(); film.len()];
    let fill = |(first, acc): (usize, &mut [A])| {
        let (frame, p0, n) = (first / pixels, first % pixels, acc.len());
        // Pixel `first + j`'s sample at record `rec`; false if it is not
        // that pixel's.
        let mut visit = |j: usize, rec: usize| {
            let r = &records[rec];
            if r.validity(h) != Validity::Valid {
                return true;
            }
            if r.pixel_index(h) != first + j {
                return false;
            }
            if let Some(c) = colour(rec, r) {
                add(&mut acc[j], c);
            }
            true
        };
        let placed = if pass_major {
            (0..spp).all(|s| {
                let base = (frame * spp + s) * pixels + p0;
                (0..n).all(|j| visit(j, base + j))
            })
        } else {
            (0..n).all(|j| (0..spp).all(|s| visit(j, (first + j) * spp + s)))
        };
        if !placed {
            misplaced.store(true, Relaxed);
        }
    };
    // Tiles within a frame, so that each is one run a pass.
    let mut tiles: Vec<(usize, &mut [A])> = Vec::new();
    let (mut first, mut rest) = (film.start, &mut acc[..]);
    while !rest.is_empty() {
        let len = rest.len().min(tile).min(pixels - first % pixels);
        let (t, tail) = rest.split_at_mut(len);
        tiles.push((first, t));
        (first, rest) = (first + len, tail);
    }
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
            (Order::PixelMajor, true),
            (Order::PassMajor, false),
            (Order::PassMajor, true),
            (Order::Unspecified, false),
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
            // Read in place in tiles of any size (a frame has 35 pixels),
            // where the order is declared and holds.
            let push = |a: &mut Vec<usize>, c: [f64; 3]| a.push(c[0] as usize);
            let colour = |i: usize, r: &Record| keep(i).then_some([r.r as f64, 0.0, 0.0]);
            for tile in [1, 3, 8, 35, 1000] {
                let film = 0..h.pixels() * 2;
                let got = in_place(&named, &h, film, bands > 1, tile, &colour, &push);
                let holds = order != Order::Unspecified && !misplace;
                assert_eq!(
                    got.is_some(),
                    holds,
                    "{order} misplaced {misplace}: tile {tile}"
                );
                if let Some(got) = got {
                    assert_eq!(got, serial, "{order}: {bands} jobs, tile {tile}");
                }
                // A range of pixels across the frames' edge, in tiles.
                let part = 10..45;
                let got = in_place(&named, &h, part.clone(), bands > 1, tile, &colour, &push);
                if holds {
                    assert_eq!(got.as_deref(), Some(&serial[part]), "{order}: tile {tile}");
                }
            }
        }
        check_row_bands(
            &h,
            &records,
            &serial,
            keep,
            order == Order::Unspecified || misplace,
        );
    }

    /// In bands of rows of any size, with any halo, each pixel's fold is
    /// the serial one: where a band cannot be read in place (`whole`), the
    /// film is folded whole and given as the last band.
    fn check_row_bands(
        h: &Header,
        records: &[Record],
        serial: &[Vec<usize>],
        keep: impl Fn(usize) -> bool + Sync,
        whole: bool,
    ) {
        let named: Vec<Record> = records
            .iter()
            .enumerate()
            .map(|(i, r)| Record { r: i as f32, ..*r })
            .collect();
        let push = |a: &mut Vec<usize>, c: [f64; 3]| a.push(c[0] as usize);
        let colour = |i: usize, r: &Record| keep(i).then_some([r.r as f64, 0.0, 0.0]);
        // (rows a band, halo, bands): five rows are a frame, one band each.
        for (rows, halo, count) in [(1, 0, 10), (1, 1, 10), (2, 1, 6), (5, 2, 2)] {
            let bands = row_bands(h, 1, 7 * rows, halo);
            assert_eq!(bands.len(), count);
            let mut got = vec![Vec::new(); serial.len()];
            let mut last_whole = false;
            fold_in_bands(&named, h, &bands, 2, colour, push, |band, folds| {
                let at = band.pixels.start + band.own.start;
                for (j, f) in folds[band.own.clone()].iter().enumerate() {
                    got[at + j] = f.clone();
                }
                last_whole = band.own.len() == serial.len();
            });
            assert_eq!(got, serial, "{rows} rows a band, halo {halo}");
            assert_eq!(last_whole, whole, "{rows} rows a band, halo {halo}");
        }
    }
}
