//! Rendering a scene into a dump, or into an in-memory reference image.
//!
//! Every sample is a pure function of (seed, frame, pixel, sample index),
//! so the bytes do not depend on the thread count, and pixel- and
//! pass-major dumps hold the same multiset of records.

use std::path::Path;

use anyhow::{Result, bail};
use pathdensity_core::progress::Progress;
use pathdensity_core::recon::{Film, Image, ReconFilter};
use pathdensity_format::dump::{Header, Order, PresizedDump, Record};
use rayon::prelude::*;

use crate::sampler::Sampler;
use crate::scene::Scene;
use crate::vec3::{Ray, Vec3};

/// What to render: film size, samples and their order.
#[derive(Clone, Debug)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    pub spp: u32,
    pub order: Order,
    pub seed: u64,
}

impl RenderSettings {
    pub fn sample_count(&self) -> u64 {
        self.width as u64 * self.height as u64 * self.frames as u64 * self.spp as u64
    }

    pub fn header(&self, scene: &Scene) -> Header {
        Header {
            width: self.width,
            height: self.height,
            frames: self.frames,
            spp: self.spp,
            sample_count: self.sample_count(),
            order: self.order,
            scene: scene.name.clone(),
            seed: self.seed,
            producer: format!("pathdensity-render {}", env!("CARGO_PKG_VERSION")),
        }
    }

    fn check(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 || self.frames == 0 || self.spp == 0 {
            bail!("width, height, frames and spp must all be at least 1");
        }
        if self.order == Order::Unspecified {
            bail!("the renderer writes pixel- or pass-major dumps");
        }
        Ok(())
    }
}

/// `n + u`, u ∈ [0, 1), kept inside [n, n + 1) after rounding to f32.
fn inside(n: u32, u: f64) -> f32 {
    let v = (n as f64 + u) as f32;
    if v >= (n + 1) as f32 {
        ((n + 1) as f32).next_down()
    } else {
        v
    }
}

/// Sample `s` of pixel `(i, j)` in frame `f`: a film position jittered in
/// the pixel, a time jittered in the frame (animations only), radiance.
pub fn sample(scene: &Scene, st: &RenderSettings, f: u32, i: u32, j: u32, s: u32) -> Record {
    let (mut rng, [x, y, t], ray) = primary(scene, st, f, i, j, s);
    let l = crate::integrator::radiance(scene, ray, &mut rng);
    let c = [l.x as f32, l.y as f32, l.z as f32];
    Record::new(x, y, t, c)
}

/// Sample `s`'s camera ray and its (x, y, t), and the sampler that goes
/// on from there.
fn primary(
    scene: &Scene,
    st: &RenderSettings,
    f: u32,
    i: u32,
    j: u32,
    s: u32,
) -> (Sampler, [f32; 3], Ray) {
    let mut rng = Sampler::new(st.seed, f, i, j, s);
    let (x, y) = (inside(i, rng.uniform()), inside(j, rng.uniform()));
    let t = if st.frames > 1 {
        inside(f, rng.uniform())
    } else {
        0.0
    };
    // The camera uses the stored f32 coordinates, so the record says
    // exactly where the sample was taken.
    let ray = scene
        .camera
        .ray(x as f64, y as f64, st.width, st.height, t as f64);
    (rng, [x, y, t], ray)
}

/// Camera rays a pixel of the albedo and normal images, unless asked
/// otherwise (`render --aux-spp`).
pub const AUX_SPP: u32 = 16;

/// The first-hit albedo and normal images a denoiser takes beside the
/// colour (OIDN's auxiliary images, statmc's guide): each pixel's mean
/// over `st.spp` camera rays jittered as the dump's samples are, in a
/// fixed order (the same bits for any thread count).
pub fn render_aux(
    scene: &Scene,
    st: &RenderSettings,
    progress: &dyn Progress,
) -> Result<[Image; 2]> {
    st.check()?;
    let (w, h, frames) = (st.width as usize, st.height as usize, st.frames as usize);
    progress.set_length((frames * h) as u64);
    let rows: Vec<Vec<[[f64; 3]; 2]>> = (0..frames * h)
        .into_par_iter()
        .map(|row| {
            let (f, j) = ((row / h) as u32, (row % h) as u32);
            let pixels = (0..w as u32)
                .map(|i| {
                    let mut sum = [Vec3::ZERO; 2];
                    for s in 0..st.spp {
                        let (_, _, ray) = primary(scene, st, f, i, j, s);
                        let (a, n) = crate::integrator::first_hit(scene, &ray);
                        sum = [sum[0] + a, sum[1] + n];
                    }
                    sum.map(|v| {
                        let v = v / st.spp as f64;
                        [v.x, v.y, v.z]
                    })
                })
                .collect();
            progress.inc(1);
            pixels
        })
        .collect();
    progress.finish();
    let image = |k: usize| Image {
        width: w,
        height: h,
        frames,
        data: rows.iter().flatten().map(|p| p[k]).collect(),
    };
    Ok([image(0), image(1)])
}

/// Renders every sample straight into a memory-mapped dump at `path`,
/// written under a temporary name and renamed when complete.
pub fn render_dump(
    scene: &Scene,
    st: &RenderSettings,
    path: &Path,
    progress: &dyn Progress,
) -> Result<Header> {
    st.check()?;
    let header = st.header(scene);
    let mut dump = PresizedDump::create(path, &header)?;
    let (w, h, spp) = (st.width as usize, st.height as usize, st.spp as usize);
    // A chunk is one row of records: in pixel-major order a film row with
    // all its samples, in pass-major order one sample of every pixel of a
    // film row. Chunk index → (frame, sample pass, row).
    let (chunk, rows_per_frame) = match st.order {
        Order::PassMajor => (w, h * spp),
        _ => (w * spp, h),
    };
    progress.set_length((st.frames as usize * rows_per_frame) as u64);
    dump.records_mut()
        .par_chunks_mut(chunk)
        .enumerate()
        .for_each(|(c, out)| {
            let f = (c / rows_per_frame) as u32;
            let r = c % rows_per_frame;
            for (n, rec) in out.iter_mut().enumerate() {
                *rec = match st.order {
                    Order::PassMajor => {
                        sample(scene, st, f, n as u32, (r % h) as u32, (r / h) as u32)
                    }
                    _ => sample(scene, st, f, (n / spp) as u32, r as u32, (n % spp) as u32),
                };
            }
            progress.inc(1);
        });
    progress.finish();
    dump.finish()?;
    Ok(header)
}

/// A reference image: `st.spp` samples per pixel accumulated in memory
/// with the reconstruction filter `filter` (the one the filter stage uses
/// for its images), splatted in a fixed order so any thread count gives
/// the same bits.
pub fn render_reference(
    scene: &Scene,
    st: &RenderSettings,
    filter: ReconFilter,
    progress: &dyn Progress,
) -> Result<Image> {
    st.check()?;
    let header = st.header(scene);
    let mut film = Film::new(&header, filter);
    let (w, h) = (st.width as usize, st.height as usize);
    // Rows per batch: about 4M records in flight, whatever the spp.
    let per_row = w * st.spp as usize;
    let band = (4_000_000 / per_row.max(1)).clamp(1, h);
    progress.set_length(st.frames as u64 * h as u64);
    let mut occupancy = vec![0u32; w * h * st.frames as usize];
    for f in 0..st.frames {
        for r0 in (0..h).step_by(band) {
            let rows = r0..(r0 + band).min(h);
            let records: Vec<Vec<Record>> = rows
                .into_par_iter()
                .map(|j| {
                    let mut v = Vec::with_capacity(per_row);
                    for i in 0..w {
                        for s in 0..st.spp {
                            v.push(sample(scene, st, f, i as u32, j as u32, s));
                        }
                    }
                    progress.inc(1);
                    v
                })
                .collect();
            for r in records.iter().flatten() {
                film.splat(r);
                let px = (f as usize * h + r.y as usize) * w + r.x as usize;
                occupancy[px] += 1;
            }
        }
    }
    progress.finish();
    Ok(film.resolve(&occupancy))
}
