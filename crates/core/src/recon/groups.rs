//! Samples grouped by pixel, for the per-pixel order statistics (median,
//! trimmed mean) that need all of a pixel's samples at once.
//!
//! A dump whose valid records already come pixel by pixel (pixel-major, or
//! any order that happens to be) is used in place: only the first record
//! index of each pixel is kept. So is a complete pass-major dump whose
//! passes visit the pixels in raster order: a pixel's samples lie one pass
//! apart. Any other order is grouped with a counting
//! sort of record indices (4 bytes per valid record). Either way the dump is
//! never copied, and per-pixel work runs in parallel with the same result
//! for any thread count.

use crate::par::prelude::*;

use crate::dump::{Header, Record, Validity};

/// Record indices, as narrow as the dump allows.
enum Indices {
    U32(Vec<u32>),
    U64(Vec<u64>),
}

impl Indices {
    fn get(&self, i: usize) -> usize {
        match self {
            Indices::U32(v) => v[i] as usize,
            Indices::U64(v) => v[i] as usize,
        }
    }
}

enum Layout {
    /// `starts[p]..starts[p + 1]` holds pixel p's valid records (and
    /// possibly invalid ones, which are skipped).
    Runs { starts: Vec<usize> },
    /// Record i is sample s of pixel f·P + p when i = (f·spp + s)·P + p,
    /// with P the pixels of a frame (or is invalid).
    Strided { pixels: usize, spp: usize },
    /// `order[offsets[p]..offsets[p + 1]]` are pixel p's valid records.
    Sorted { offsets: Vec<usize>, order: Indices },
}

/// The valid samples of every pixel (frames × height × width bins).
pub struct PixelGroups<'a> {
    records: &'a [Record],
    header: &'a Header,
    layout: Layout,
}

/// One pixel's samples, per channel, in file order.
pub type Channels = [Vec<f64>; 3];

impl<'a> PixelGroups<'a> {
    pub fn new(records: &'a [Record], header: &'a Header) -> PixelGroups<'a> {
        let pixels = header.pixels() * header.frames as usize;
        let layout = match runs(records, header, pixels) {
            Some(starts) => Layout::Runs { starts },
            None => {
                strided(records, header).unwrap_or_else(|| counting_sort(records, header, pixels))
            }
        };
        PixelGroups {
            records,
            header,
            layout,
        }
    }

    /// True when the dump was grouped in place (no index array).
    pub fn in_place(&self) -> bool {
        !matches!(self.layout, Layout::Sorted { .. })
    }

    fn pixels(&self) -> usize {
        self.header.pixels() * self.header.frames as usize
    }

    fn gather(&self, px: usize, out: &mut Channels) {
        for c in out.iter_mut() {
            c.clear();
        }
        let mut push = |r: &Record| {
            for (c, v) in out.iter_mut().zip(r.rgb()) {
                c.push(v as f64);
            }
        };
        match &self.layout {
            Layout::Runs { starts } => {
                for r in &self.records[starts[px]..starts[px + 1]] {
                    if r.validity(self.header) == Validity::Valid {
                        push(r);
                    }
                }
            }
            &Layout::Strided { pixels, spp } => {
                let (frame, p) = (px / pixels, px % pixels);
                for s in 0..spp {
                    let r = &self.records[(frame * spp + s) * pixels + p];
                    if r.validity(self.header) == Validity::Valid {
                        push(r);
                    }
                }
            }
            Layout::Sorted { offsets, order } => {
                for i in offsets[px]..offsets[px + 1] {
                    push(&self.records[order.get(i)]);
                }
            }
        }
    }

    /// `f(samples)` for every pixel, in pixel order, computed in parallel.
    /// Pixels without samples get `f` of empty channels.
    pub fn map<T: Send>(&self, f: impl Fn(&mut Channels) -> T + Sync) -> Vec<T> {
        (0..self.pixels())
            .into_par_iter()
            .map_init(Channels::default, |scratch, px| {
                self.gather(px, scratch);
                f(scratch)
            })
            .collect()
    }
}

/// Per-pixel starts if the valid records come pixel by pixel, else None.
fn runs(records: &[Record], h: &Header, pixels: usize) -> Option<Vec<usize>> {
    let mut starts = vec![usize::MAX; pixels + 1];
    let mut current: Option<usize> = None;
    for (i, r) in records.iter().enumerate() {
        if r.validity(h) != Validity::Valid {
            continue;
        }
        let px = r.pixel_index(h);
        match current {
            Some(c) if c == px => {}
            Some(c) if c > px => return None,
            _ => {
                starts[px] = i;
                current = Some(px);
            }
        }
    }
    starts[pixels] = records.len();
    for p in (0..pixels).rev() {
        if starts[p] == usize::MAX {
            starts[p] = starts[p + 1];
        }
    }
    Some(starts)
}

/// The strided layout if every valid record lies where a complete
/// pass-major dump in raster order puts it, else None.
fn strided(records: &[Record], h: &Header) -> Option<Layout> {
    let (pixels, spp) = (h.pixels(), h.spp as usize);
    let complete = pixels
        .checked_mul(spp)
        .and_then(|n| n.checked_mul(h.frames as usize));
    if complete != Some(records.len()) || records.is_empty() {
        return None;
    }
    let pass = pixels * spp;
    let placed = records.iter().enumerate().all(|(i, r)| {
        r.validity(h) != Validity::Valid || r.pixel_index(h) == i / pass * pixels + i % pixels
    });
    placed.then_some(Layout::Strided { pixels, spp })
}

fn counting_sort(records: &[Record], h: &Header, pixels: usize) -> Layout {
    let mut offsets = vec![0usize; pixels + 1];
    for r in records {
        if r.validity(h) == Validity::Valid {
            offsets[r.pixel_index(h) + 1] += 1;
        }
    }
    for p in 0..pixels {
        offsets[p + 1] += offsets[p];
    }
    let mut next = offsets.clone();
    let valid = offsets[pixels];
    let mut place = |set: &mut dyn FnMut(usize, usize)| {
        for (i, r) in records.iter().enumerate() {
            if r.validity(h) == Validity::Valid {
                let slot = &mut next[r.pixel_index(h)];
                set(*slot, i);
                *slot += 1;
            }
        }
    };
    let order = if records.len() <= u32::MAX as usize {
        let mut v = vec![0u32; valid];
        place(&mut |s, i| v[s] = i as u32);
        Indices::U32(v)
    } else {
        let mut v = vec![0u64; valid];
        place(&mut |s, i| v[s] = i as u64);
        Indices::U64(v)
    };
    Layout::Sorted { offsets, order }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::recon::test_header as header;

    fn rec(x: f32, y: f32, v: f32) -> Record {
        Record::new(x, y, 0.0, [v, 2.0 * v, -v])
    }

    /// Both layouts give every pixel its valid samples in file order.
    #[test]
    fn runs_and_counting_sort_group_the_same_samples() {
        let h = header(2, 2);
        let sorted = [
            rec(0.5, 0.5, 1.0),
            rec(0.1, 0.9, 2.0),
            rec(f32::NAN, 0.5, 9.0),
            rec(1.5, 1.5, 3.0),
            rec(5.0, 0.5, 9.0),
            rec(1.2, 1.2, 4.0),
        ];
        let g = PixelGroups::new(&sorted, &h);
        assert!(g.in_place());
        let got = g.map(|c| c.clone());
        assert_eq!(got[0][0], vec![1.0, 2.0]);
        assert_eq!(got[0][1], vec![2.0, 4.0]);
        assert!(got[1][0].is_empty() && got[2][0].is_empty());
        assert_eq!(got[3][0], vec![3.0, 4.0]);

        let mut shuffled = sorted;
        shuffled.swap(0, 3);
        let g = PixelGroups::new(&shuffled, &h);
        assert!(!g.in_place());
        let got = g.map(|c| c[0].clone());
        assert_eq!(got[0], vec![2.0, 1.0]);
        assert_eq!(got[3], vec![3.0, 4.0]);
    }

    /// A complete pass-major dump (two frames, invalid records) is grouped
    /// in place, with the samples the counting sort gives; one record out
    /// of place, or one missing, and it is sorted instead.
    #[test]
    fn a_pass_major_dump_is_grouped_in_place() {
        let (w, hh, spp, frames) = (3usize, 2usize, 4usize, 2usize);
        let h = Header {
            spp: spp as u32,
            frames: frames as u32,
            ..header(w as u32, hh as u32)
        };
        let mut records = Vec::new();
        for f in 0..frames {
            for s in 0..spp {
                for p in 0..w * hh {
                    let (x, y) = ((p % w) as f32 + 0.25, (p / w) as f32 + 0.5);
                    let v = (f * 100 + s * 10 + p) as f32;
                    let t = if (s + p) % 5 == 3 {
                        f32::NAN
                    } else {
                        f as f32 + 0.5
                    };
                    records.push(Record::new(x, y, t, [v, 0.0, 0.0]));
                }
            }
        }
        let pixels = w * hh * frames;
        let g = PixelGroups::new(&records, &h);
        assert!(g.in_place());
        let want = PixelGroups {
            records: &records,
            header: &h,
            layout: counting_sort(&records, &h, pixels),
        };
        let got = g.map(|c| c[0].clone());
        assert_eq!(got, want.map(|c| c[0].clone()));
        assert_eq!(got[7], vec![101.0, 111.0, 131.0]);
        assert_eq!(
            got[2],
            vec![2.0, 22.0, 32.0],
            "sample 1 of pixel 2 is invalid"
        );

        let mut moved = records.clone();
        moved.swap(0, 1);
        assert!(!PixelGroups::new(&moved, &h).in_place());
        assert!(!PixelGroups::new(&records[1..], &h).in_place());
    }
}
