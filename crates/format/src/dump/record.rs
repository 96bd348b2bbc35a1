use super::Header;

/// One sample: continuous film position `(x, y)` in pixels, time `t` in
/// frames, and linear Rec.709 radiance `(r, g, b)`. 24 bytes, little-endian
/// on disk, so a mapped dump is a `&[Record]` on little-endian hosts.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Record {
    pub x: f32,
    pub y: f32,
    pub t: f32,
    pub r: f32,
    pub g: f32,
    pub b: f32,
}

/// Why a record is or is not usable (docs/format.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Validity {
    Valid,
    NonFinite,
    OutsideFilm,
    OutsideTime,
}

impl Record {
    pub fn new(x: f32, y: f32, t: f32, rgb: [f32; 3]) -> Record {
        Record {
            x,
            y,
            t,
            r: rgb[0],
            g: rgb[1],
            b: rgb[2],
        }
    }

    pub fn rgb(&self) -> [f32; 3] {
        [self.r, self.g, self.b]
    }

    /// Classifies the record against the film of `h`. Bounds are compared in
    /// f64, exactly: x ∈ [0, width), y ∈ [0, height), t ∈ [0, frames).
    #[inline]
    pub fn validity(&self, h: &Header) -> Validity {
        let f = [self.x, self.y, self.t, self.r, self.g, self.b];
        if !f.iter().all(|v| v.is_finite()) {
            return Validity::NonFinite;
        }
        let inside = |v: f32, n: u32| (v as f64) >= 0.0 && (v as f64) < n as f64;
        if !inside(self.x, h.width) || !inside(self.y, h.height) {
            return Validity::OutsideFilm;
        }
        if !inside(self.t, h.frames) {
            return Validity::OutsideTime;
        }
        Validity::Valid
    }

    /// The (frame, row, column) bin of a valid record, as a flat index into
    /// `frames × height × width`.
    #[inline]
    pub fn pixel_index(&self, h: &Header) -> usize {
        let frame = self.t as usize;
        let (i, j) = (self.x as usize, self.y as usize);
        (frame * h.height as usize + j) * h.width as usize + i
    }
}

/// Invalid records by reason.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct InvalidCounts {
    pub non_finite: u64,
    pub outside_film: u64,
    pub outside_time: u64,
}

impl InvalidCounts {
    pub fn add(&mut self, v: Validity) {
        match v {
            Validity::Valid => {}
            Validity::NonFinite => self.non_finite += 1,
            Validity::OutsideFilm => self.outside_film += 1,
            Validity::OutsideTime => self.outside_time += 1,
        }
    }
    pub fn total(&self) -> u64 {
        self.non_finite + self.outside_film + self.outside_time
    }
}
