//! Synthetic dumps with known structure, for tests, benchmarks and the
//! checked-in demo fixture: a smooth colour field, rare fireflies (isolated
//! samples far brighter than their neighbours) and optionally a small dense
//! bright light (many bright samples together, which must be kept).
//!
//! Every sample is a pure function of (seed, frame, pixel, sample index), so
//! pixel- and pass-major dumps hold the same multiset of records.

use std::path::Path;

use crate::dump::{DumpError, DumpWriter, Header, Order, Record};

#[derive(Clone, Debug)]
pub struct SynthParams {
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    pub spp: u32,
    pub order: Order,
    /// Probability that a sample is a firefly.
    pub firefly_fraction: f64,
    /// A firefly's radiance is its field value times this gain.
    pub firefly_gain: f32,
    /// Put every sample at its pixel centre (as some renderers do).
    pub pixel_centre: bool,
    /// A square light `(x0, y0, side, radiance)` in pixels, seen directly.
    pub light: Option<(u32, u32, u32, f32)>,
    pub seed: u64,
}

impl Default for SynthParams {
    /// The benchmark dump: 256 × 256 × 64 spp, 0.5% fireflies.
    fn default() -> Self {
        SynthParams {
            width: 256,
            height: 256,
            frames: 1,
            spp: 64,
            order: Order::PixelMajor,
            firefly_fraction: 0.005,
            firefly_gain: 200.0,
            pixel_centre: false,
            light: None,
            seed: 1,
        }
    }
}

/// SplitMix64: a counter-based generator, so any sample is addressable.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// `n + u` for u ∈ [0, 1), kept below n + 1: the f32 sum can round up to
/// n + 1, which would put the sample outside its pixel (or the film).
fn inside(n: u32, u: f32) -> f32 {
    let v = n as f32 + u;
    if v >= (n + 1) as f32 {
        ((n + 1) as f32).next_down()
    } else {
        v
    }
}

/// A stream of uniform f64 in [0, 1) for unit tests: SplitMix64 over a
/// counter, so each test names its seed and needs no generator of its own.
#[cfg(test)]
pub(crate) fn test_units(seed: u64) -> impl FnMut() -> f64 {
    let mut i = 0u64;
    move || {
        i += 1;
        (mix(seed ^ mix(i)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn uniform(h: u64) -> f32 {
    (h >> 40) as f32 / (1u64 << 24) as f32
}

impl SynthParams {
    pub fn sample_count(&self) -> u64 {
        self.width as u64 * self.height as u64 * self.frames as u64 * self.spp as u64
    }

    /// Sample `s` of pixel `(i, j)` in frame `f`.
    pub fn sample(&self, f: u32, i: u32, j: u32, s: u32) -> Record {
        // Chained mixing: distinct (seed, frame, pixel, sample) never share a
        // stream, and no arithmetic can overflow whatever the seed.
        let pixel = (j as u64) << 32 | i as u64;
        let mut h = mix(mix(mix(mix(self.seed) ^ f as u64) ^ pixel) ^ s as u64);
        let mut next = || {
            h = mix(h);
            uniform(h)
        };
        let (jx, jy, jt) = (next(), next(), next());
        let (x, y) = if self.pixel_centre {
            (i as f32 + 0.5, j as f32 + 0.5)
        } else {
            (inside(i, jx), inside(j, jy))
        };
        let t = if self.frames > 1 { inside(f, jt) } else { 0.0 };
        let (u, v) = (x / self.width as f32, y / self.height as f32);
        let tau = std::f32::consts::TAU;
        let base = [
            0.45 + 0.25 * (tau * (u + 0.1 * f as f32)).sin(),
            0.40 + 0.20 * (tau * v).cos(),
            0.30 + 0.15 * (tau * (u + v)).sin(),
        ];
        let noise = 1.0 + 0.2 * (next() - 0.5);
        let mut rgb = base.map(|c| c * noise);
        if let Some((x0, y0, side, radiance)) = self.light
            && (x0..x0 + side).contains(&i)
            && (y0..y0 + side).contains(&j)
        {
            rgb = [radiance * noise, radiance * noise, radiance * 0.8 * noise];
        }
        if (next() as f64) < self.firefly_fraction {
            let gain = self.firefly_gain * (0.5 + next());
            rgb = rgb.map(|c| c * gain);
        }
        Record::new(x, y, t, rgb)
    }

    /// Every sample, in the dump's order.
    pub fn records(&self) -> impl Iterator<Item = Record> + '_ {
        let (w, h, spp) = (self.width, self.height, self.spp);
        (0..self.frames).flat_map(move |f| {
            let per_frame = w as u64 * h as u64 * spp as u64;
            (0..per_frame).map(move |n| {
                let (pixel, s) = match self.order {
                    Order::PassMajor => (n % (w as u64 * h as u64), n / (w as u64 * h as u64)),
                    _ => (n / spp as u64, n % spp as u64),
                };
                self.sample(
                    f,
                    (pixel % w as u64) as u32,
                    (pixel / w as u64) as u32,
                    s as u32,
                )
            })
        })
    }

    pub fn header(&self) -> Header {
        Header {
            width: self.width,
            height: self.height,
            frames: self.frames,
            spp: self.spp,
            sample_count: self.sample_count(),
            order: self.order,
            scene: "synthetic".into(),
            seed: self.seed,
            producer: format!("pathdensity synth {}", env!("CARGO_PKG_VERSION")),
        }
    }

    /// Writes the dump to `path`.
    pub fn write(&self, path: &Path) -> Result<Header, DumpError> {
        let mut w = DumpWriter::create(path, self.header())?;
        let mut buf = Vec::with_capacity(4096);
        for r in self.records() {
            buf.push(r);
            if buf.len() == buf.capacity() {
                w.push_all(&buf)?;
                buf.clear();
            }
        }
        w.push_all(&buf)?;
        w.finish()
    }
}
