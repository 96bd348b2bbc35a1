//! Intel Open Image Denoise (OIDN) on a reconstructed image: its `RT`
//! filter, HDR, on the CPU device, frame by frame; colour only, or with
//! the renderer's albedo (and normal) images as OIDN's auxiliary inputs
//! ([`Aux`]: a dump has none of its own, `filter --albedo --normal` reads
//! them), denoised first by OIDN itself or taken as they are
//! ([`AuxPrefilter`]).
//!
//! OIDN is loaded at run time, so every build can use an installed OIDN 2
//! and none needs it ([`library`] finds it; `library.rs`).
//!
//! When none is found the methods that need OIDN are refused by the
//! configuration and the default set leaves them out, so the recommended
//! image falls back to the statistical denoiser ([`crate::recon::statmc`]).
//!
//! Input treatment: OIDN's HDR mode expects finite, non-negative values. A
//! non-finite channel is replaced by 0 and a negative one clamped to 0
//! before denoising (the counts come back in [`Denoised`]); a mean image
//! has no non-finite pixel, and negative samples are rare. Pixels with no
//! sample (occupancy 0) go in as 0 and are written back as 0, as in every
//! image (docs/filter.md §3).

use std::ffi::{CStr, c_char, c_int};

mod library;

use self::library::{Api, DEVICE_TYPE_CPU, FORMAT_FLOAT3, Handle};
pub use self::library::{Library, available, library};
use super::aux::AuxImages;
pub use super::aux::{Aux, AuxPrefilter};
use crate::recon::Image;

/// A denoised image and what had to be changed in its input.
pub struct Denoised {
    pub image: Image,
    /// Channels that were NaN or ±∞, set to 0.
    pub non_finite: u64,
    /// Channels below 0, set to 0.
    pub negative: u64,
}

/// OIDN's scratch memory, in MB: beyond it OIDN denoises the image in
/// overlapping tiles. Unbounded, a 1080p frame's took 0.84 GB (the
/// `--no-html` run's peak anonymous memory 2.03 GB, against 1.19 GB at
/// this bound, docs/BENCHMARKS.md, "A production frame"). OIDN does not
/// promise tiles give the untiled bits; on that frame, and on every
/// 128² dump (which fit untiled), they did.
const MAX_MEMORY_MB: c_int = 256;

/// A committed CPU device and its RT filter, released on drop.
struct Session<'a> {
    api: &'a Api,
    device: Handle,
    filter: Handle,
}

impl Session<'_> {
    /// The device's pending error, as `what: MESSAGE`.
    fn check(&self, what: &'static str) -> Result<(), OidnError> {
        let mut msg: *const c_char = std::ptr::null();
        // SAFETY: a live device; OIDN sets msg to its own string or null.
        let code = unsafe { (self.api.device_error)(self.device, &mut msg) };
        if code == 0 {
            return Ok(());
        }
        let msg = if msg.is_null() {
            format!("error {code}")
        } else {
            unsafe { CStr::from_ptr(msg) }
                .to_string_lossy()
                .into_owned()
        };
        Err(OidnError::Device { what, message: msg })
    }
}

impl Drop for Session<'_> {
    fn drop(&mut self) {
        // SAFETY: handles made by this session, released once.
        unsafe {
            if !self.filter.is_null() {
                (self.api.release_filter)(self.filter);
            }
            (self.api.release_device)(self.device);
        }
    }
}

/// OIDN's documented prefiltering ([`AuxPrefilter::Accurate`]): the
/// albedo, then the normal, denoised each on its own by an `RT` filter,
/// frame by frame (`w` × `h` pixels a frame).
fn prefilter(
    s: &Session,
    albedo: &[f32],
    normal: Option<&[f32]>,
    w: usize,
    h: usize,
) -> Result<AuxImages, OidnError> {
    let api = s.api;
    let one = |name: &CStr, image: &[f32]| {
        // SAFETY: a live device; the filter is released when dropped.
        let handle = unsafe { (api.new_filter)(s.device, c"RT".as_ptr()) };
        if handle.is_null() {
            s.check("the auxiliary images' filter")?;
            return Err(OidnError::NoFilter);
        }
        let filter = Filter { api, handle };
        // SAFETY: a live filter and a NUL-terminated parameter name.
        unsafe { (api.set_int)(filter.handle, c"maxMemoryMB".as_ptr(), MAX_MEMORY_MB) };
        let mut out = vec![0.0f32; image.len()];
        for (input, output) in image.chunks(3 * w * h).zip(out.chunks_mut(3 * w * h)) {
            // SAFETY: each holds one frame, w·h RGB f32 values, alive
            // until the filter runs; OIDN writes only the output.
            let set =
                |name: &CStr, buf: *mut f32| unsafe { share(api, filter.handle, name, buf, w, h) };
            set(name, input.as_ptr().cast_mut());
            set(c"output", output.as_mut_ptr());
            // SAFETY: a live filter with both images set.
            unsafe {
                (api.commit_filter)(filter.handle);
                (api.execute_filter)(filter.handle);
            }
            s.check("prefiltering the auxiliary images")?;
        }
        Ok(out)
    };
    Ok((
        one(c"albedo", albedo)?,
        normal.map(|n| one(c"normal", n)).transpose()?,
    ))
}

/// Gives `filter` the image `name` in place: `buf`'s w × h RGB f32
/// values, row-major (OIDN's FLOAT3 with default strides).
///
/// # Safety
/// `filter` is live; `buf` holds w·h·3 values and stays alive, unmoved,
/// until the filter has run.
unsafe fn share(api: &Api, filter: Handle, name: &CStr, buf: *mut f32, w: usize, h: usize) {
    // SAFETY: as the caller vouches; `name` is NUL-terminated.
    unsafe {
        (api.shared_image)(
            filter,
            name.as_ptr(),
            buf.cast(),
            FORMAT_FLOAT3,
            w,
            h,
            0,
            0,
            0,
        )
    }
}

/// A filter of a [`Session`]'s device besides its own, released when
/// dropped.
struct Filter<'a> {
    api: &'a Api,
    handle: Handle,
}

impl Drop for Filter<'_> {
    fn drop(&mut self) {
        // SAFETY: a live filter, released once.
        unsafe { (self.api.release_filter)(self.handle) };
    }
}

/// The values OIDN is given for `img`'s frame `f`: RGB f32, row-major.
fn input(img: &Image, f: usize, non_finite: &mut u64, negative: &mut u64) -> Vec<f32> {
    let mut out = Vec::with_capacity(img.pixels_per_frame() * 3);
    for px in img.frame(f) {
        for &v in px {
            let v = v as f32;
            if !v.is_finite() {
                *non_finite += 1;
                out.push(0.0);
            } else if v < 0.0 {
                *negative += 1;
                out.push(0.0);
            } else {
                out.push(v);
            }
        }
    }
    out
}

/// Why OIDN made no image.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum OidnError {
    /// No library was found or loaded; says where it looked.
    #[error("OIDN: {0}")]
    Unavailable(&'static str),
    /// The library made no CPU device.
    #[error("OIDN: no CPU device")]
    NoDevice,
    /// The device made no `RT` filter.
    #[error("OIDN: no RT filter")]
    NoFilter,
    /// The library reported an error while doing `what`.
    #[error("OIDN: {what}: {message}")]
    Device { what: &'static str, message: String },
}

/// OIDN's `RT` filter (HDR) on every frame of `img`, with `aux` when given.
pub fn denoise(img: &Image, occupancy: &[u32], aux: Option<&Aux>) -> Result<Denoised, OidnError> {
    let lib = library().map_err(OidnError::Unavailable)?;
    denoise_with(lib, img, occupancy, aux)
}

fn denoise_with(
    lib: &Library,
    img: &Image,
    occupancy: &[u32],
    aux: Option<&Aux>,
) -> Result<Denoised, OidnError> {
    let api = &lib.api;
    // SAFETY: OIDN's documented call order: a device, committed, then a
    // filter of it; both released by the session's drop.
    let mut s = Session {
        api,
        device: unsafe { (api.new_device)(DEVICE_TYPE_CPU) },
        filter: std::ptr::null_mut(),
    };
    if s.device.is_null() {
        return Err(OidnError::NoDevice);
    }
    unsafe { (api.commit_device)(s.device) };
    s.check("the CPU device")?;
    let _ = lib
        .version
        .get_or_init(|| unsafe { (api.device_int)(s.device, c"version".as_ptr()) });
    s.filter = unsafe { (api.new_filter)(s.device, c"RT".as_ptr()) };
    s.check("the RT filter")?;
    if s.filter.is_null() {
        return Err(OidnError::NoFilter);
    }
    unsafe { (api.set_bool)(s.filter, c"hdr".as_ptr(), true) };
    let (w, h) = (img.width, img.height);
    let aux_images = aux
        .map(|a| a.for_oidn(|albedo, normal| prefilter(&s, albedo, normal, w, h)))
        .transpose()?;
    if let Some(a) = aux {
        // SAFETY: a live filter and a NUL-terminated parameter name.
        unsafe { (api.set_bool)(s.filter, c"cleanAux".as_ptr(), a.prefilter().clean()) };
    }
    // SAFETY: a live filter and a NUL-terminated parameter name.
    unsafe { (api.set_int)(s.filter, c"maxMemoryMB".as_ptr(), MAX_MEMORY_MB) };
    let (mut non_finite, mut negative) = (0, 0);
    let mut out = Image::new(w, h, img.frames);
    let n = img.pixels_per_frame();
    for f in 0..img.frames {
        let mut color = input(img, f, &mut non_finite, &mut negative);
        let mut result = vec![0.0f32; color.len()];
        let frame = |v: &[f32]| {
            debug_assert_eq!(
                v.len(),
                3 * n * img.frames,
                "an auxiliary image the film's size"
            );
            v[3 * n * f..3 * n * (f + 1)].as_ptr().cast_mut()
        };
        let albedo = aux_images.map(|(a, _)| frame(a));
        let normal = aux_images.and_then(|(_, n)| n).map(frame);
        let set = |name: &CStr, buf: Option<*mut f32>| match buf {
            // SAFETY: `buf` holds w·h RGB f32 values, alive until the
            // filter runs; OIDN writes only the output, so the auxiliary
            // images, read through a shared borrow, are never written.
            Some(b) => unsafe { share(api, s.filter, name, b, w, h) },
            None => unsafe { (api.unset_image)(s.filter, name.as_ptr()) },
        };
        set(c"color", Some(color.as_mut_ptr()));
        set(c"albedo", albedo);
        set(c"normal", normal);
        set(c"output", Some(result.as_mut_ptr()));
        unsafe { (api.commit_filter)(s.filter) };
        s.check("committing the filter")?;
        unsafe { (api.execute_filter)(s.filter) };
        s.check("denoising")?;
        for (p, px) in out.data[f * n..(f + 1) * n].iter_mut().enumerate() {
            if occupancy[f * n + p] > 0 {
                *px = std::array::from_fn(|c| result[3 * p + c] as f64);
            }
        }
    }
    Ok(Denoised {
        image: out,
        non_finite,
        negative,
    })
}

#[cfg(test)]
mod tests {
    use super::library::{find, pyoidn_in};
    use super::*;
    use std::path::{Path, PathBuf};

    /// The OIDN of `OIDN_DIR`, else of tools/oidn/.venv (`bash
    /// tools/oidn/setup.sh`); skipped loudly without one, unless
    /// `PATHDENSITY_REQUIRE_OIDN` is set.
    fn oidn() -> Option<Library> {
        let venv = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools/oidn/.venv");
        let dir = std::env::var_os("OIDN_DIR")
            .map(PathBuf::from)
            .or_else(|| pyoidn_in(&venv));
        let found = dir
            .ok_or_else(|| "OIDN is not set up (bash tools/oidn/setup.sh)".to_string())
            .and_then(|d| find(Some(d)));
        match found {
            Ok(lib) => Some(lib),
            Err(why) if std::env::var_os("PATHDENSITY_REQUIRE_OIDN").is_some() => {
                panic!("{why}, and PATHDENSITY_REQUIRE_OIDN is set")
            }
            Err(why) => {
                eprintln!("SKIPPED: {why}");
                None
            }
        }
    }

    #[test]
    fn an_oidn_dir_without_the_library_names_itself() {
        let dir = std::env::temp_dir();
        let why = find(Some(dir.clone())).err().unwrap();
        assert!(why.contains(&dir.display().to_string()), "{why}");
        let why = find(Some(dir.join("no-such"))).err().unwrap();
        assert!(why.contains("no-such"), "{why}");
    }

    #[test]
    fn non_finite_and_negative_input_is_zeroed_and_counted_and_empty_pixels_stay_zero() {
        let Some(lib) = oidn() else {
            return;
        };
        let denoise = |img: &Image, occupancy: &[u32], aux: Option<&Aux>| {
            denoise_with(&lib, img, occupancy, aux)
        };
        let mut img = Image::new(16, 12, 1);
        for (p, px) in img.data.iter_mut().enumerate() {
            *px = [0.2 + (p % 7) as f64 * 0.1, 0.5, 1.5];
        }
        img.data[5] = [f64::NAN, f64::INFINITY, -3.0];
        img.data[6] = [f64::NEG_INFINITY, 1.0, 1.0];
        let mut occupancy = vec![4u32; 16 * 12];
        occupancy[100] = 0;
        img.data[100] = [0.0; 3];
        let d = denoise(&img, &occupancy, None).unwrap();
        assert_eq!((d.non_finite, d.negative), (3, 1));
        assert!(d.image.data.iter().flatten().all(|v| v.is_finite()));
        assert_eq!(d.image.data[100], [0.0; 3]);
        assert!(d.image.data[5].iter().all(|&v| v >= 0.0));
    }

    /// An albedo with an edge the noisy colour hides: OIDN with it keeps
    /// the edge sharper than without (and an albedo alone, or with a
    /// normal, is accepted).
    #[test]
    fn the_albedo_sharpens_an_edge() {
        let Some(lib) = oidn() else {
            return;
        };
        let denoise = |img: &Image, occupancy: &[u32], aux: Option<&Aux>| {
            denoise_with(&lib, img, occupancy, aux)
        };
        let (w, h) = (32, 32);
        let mut img = Image::new(w, h, 1);
        let mut albedo = Image::new(w, h, 1);
        let mut state = 12345u64;
        for (p, px) in img.data.iter_mut().enumerate() {
            let level = if p % w < w / 2 { 0.2 } else { 0.8 };
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let noise = ((state >> 33) as f64 / (1u64 << 31) as f64) - 0.5;
            *px = [level + 0.6 * noise; 3];
            albedo.data[p] = [level; 3];
        }
        let occupancy = vec![16u32; w * h];
        let edge = |d: &Denoised| {
            let (l, r) = (
                d.image.data[16 * w + w / 2 - 1][0],
                d.image.data[16 * w + w / 2][0],
            );
            r - l
        };
        let plain = denoise(&img, &occupancy, None).unwrap();
        let aux = Aux::new(&albedo, None);
        let with = denoise(&img, &occupancy, Some(&aux)).unwrap();
        assert!(
            edge(&with) > edge(&plain),
            "{} vs {}",
            edge(&with),
            edge(&plain)
        );
        let normal = Image {
            data: vec![[0.0, 0.0, 1.0]; w * h],
            ..albedo.clone()
        };
        let both = Aux::new(&albedo, Some(&normal));
        assert!(denoise(&img, &occupancy, Some(&both)).is_ok());
    }

    /// `accurate` has OIDN denoise a noisy albedo and normal, each frame
    /// on its own, before the image: the albedo OIDN is then given is
    /// nearer the clean one than the renderer's, and the image differs
    /// from `fast`'s (the noisy albedo as it is) and `none`'s (the noisy
    /// albedo taken as clean), and `fast`'s from `none`'s (OIDN told the
    /// same images are clean).
    #[test]
    fn accurate_denoises_the_albedo_first() {
        let Some(lib) = oidn() else {
            return;
        };
        let (w, h, frames) = (32, 32, 2);
        let n = w * h;
        let mut state = 99u64;
        let mut noise = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as f64 / (1u64 << 31) as f64 - 0.5
        };
        // Frame f's left half at 0.2 and right at 0.8, swapped in frame 1.
        let level = |p: usize| {
            let left = (p % n) % w < w / 2;
            if left == (p < n) { 0.2 } else { 0.8 }
        };
        let (mut img, mut clean) = (Image::new(w, h, frames), Image::new(w, h, frames));
        let mut albedo = Image::new(w, h, frames);
        for p in 0..n * frames {
            img.data[p] = [level(p) + 0.6 * noise(); 3];
            clean.data[p] = [level(p); 3];
            albedo.data[p] = [level(p) + 0.4 * noise(); 3];
        }
        let normal = Image {
            data: (0..n * frames)
                .map(|_| [0.2 * noise(), 0.2 * noise(), 1.0])
                .collect(),
            ..albedo.clone()
        };
        let occupancy = vec![16u32; n * frames];
        let run = |p: AuxPrefilter| {
            let aux = Aux::new(&albedo, Some(&normal)).with_prefilter(p);
            let d = denoise_with(&lib, &img, &occupancy, Some(&aux)).unwrap();
            (aux, d.image.data)
        };
        let (aux, accurate) = run(AuxPrefilter::Accurate);
        let (given, _) = aux.for_oidn(|_, _| unreachable!("made once")).unwrap();
        let off = |v: &[f32]| {
            let sq: f64 = v
                .iter()
                .zip(clean.data.iter().flatten())
                .map(|(a, b)| (*a as f64 - b).powi(2))
                .sum();
            (sq / v.len() as f64).sqrt()
        };
        assert!(
            off(given) < 0.5 * off(aux.albedo()),
            "{} vs {}",
            off(given),
            off(aux.albedo())
        );
        let (fast, none) = (run(AuxPrefilter::Fast).1, run(AuxPrefilter::None).1);
        assert_ne!(fast, accurate);
        assert_ne!(none, accurate);
        assert_ne!(none, fast, "the same images, told clean or not");
    }

    /// Each frame of an animation is denoised with its own frame of the
    /// auxiliary images: two frames at once give the bits of each alone.
    #[test]
    fn each_frame_reads_its_own_auxiliary_frame() {
        let Some(lib) = oidn() else {
            return;
        };
        let (w, h) = (16, 16);
        let frame = |f: usize| {
            let mut img = Image::new(w, h, 1);
            let mut albedo = Image::new(w, h, 1);
            for (p, px) in img.data.iter_mut().enumerate() {
                let edge = if f == 0 { p % w < w / 2 } else { p / w < h / 2 };
                let level = if edge { 0.2 } else { 0.8 };
                *px = [level + 0.05 * ((p * 7 + f) % 5) as f64; 3];
                albedo.data[p] = [level; 3];
            }
            (img, albedo)
        };
        let [(a, albedo_a), (b, albedo_b)] = [frame(0), frame(1)];
        let join = |x: &Image, y: &Image| Image {
            frames: 2,
            data: [x.data.clone(), y.data.clone()].concat(),
            ..x.clone()
        };
        let occupancy = vec![4u32; w * h * 2];
        let bits = |d: Denoised| -> Vec<u64> {
            d.image.data.iter().flatten().map(|v| v.to_bits()).collect()
        };
        let alone = |img: &Image, albedo: &Image| {
            let aux = Aux::new(albedo, None);
            bits(denoise_with(&lib, img, &occupancy[..w * h], Some(&aux)).unwrap())
        };
        let aux = Aux::new(&join(&albedo_a, &albedo_b), None);
        let both = bits(denoise_with(&lib, &join(&a, &b), &occupancy, Some(&aux)).unwrap());
        assert_eq!(both, [alone(&a, &albedo_a), alone(&b, &albedo_b)].concat());
    }
}
