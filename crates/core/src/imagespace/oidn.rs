//! Intel Open Image Denoise (OIDN) on a reconstructed image: its `RT`
//! filter, HDR, on the CPU device, frame by frame; colour only, or with
//! the renderer's albedo (and normal) images as OIDN's auxiliary inputs
//! ([`Aux`]: a dump has none of its own, `filter --albedo --normal` reads
//! them). Built only with the `oidn` feature, which
//! links `libOpenImageDenoise` (README, "OIDN"); [`AVAILABLE`] says whether
//! this build has it, and the configuration refuses OIDN when it does not.
//!
//! Input treatment: OIDN's HDR mode expects finite, non-negative values. A
//! non-finite channel is replaced by 0 and a negative one clamped to 0
//! before denoising (the counts come back in [`Denoised`]); a mean image
//! has no non-finite pixel, and negative samples are rare. Pixels with no
//! sample (occupancy 0) go in as 0 and are written back as 0, as in every
//! image (docs/filter.md §3).

use crate::recon::Image;

/// Whether this build can run OIDN.
pub const AVAILABLE: bool = cfg!(feature = "oidn");

/// OIDN's auxiliary images, the film's size and frames: the first-hit
/// albedo, and optionally the normal (OIDN takes a normal only with an
/// albedo). Non-finite values go in as 0.
#[derive(Clone, Debug)]
pub struct Aux {
    pub albedo: Image,
    pub normal: Option<Image>,
}

/// A denoised image and what had to be changed in its input.
pub struct Denoised {
    pub image: Image,
    /// Channels that were NaN or ±∞, set to 0.
    pub non_finite: u64,
    /// Channels below 0, set to 0.
    pub negative: u64,
}

/// The values OIDN is given for `img`'s frame `f`: RGB f32, row-major.
#[cfg_attr(not(feature = "oidn"), allow(dead_code))]
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

/// An auxiliary image's frame `f` as OIDN takes it: f32, non-finite as 0.
#[cfg_attr(not(feature = "oidn"), allow(dead_code))]
fn aux_input(img: &Image, f: usize) -> Vec<f32> {
    img.frame(f)
        .iter()
        .flatten()
        .map(|&v| if v.is_finite() { v as f32 } else { 0.0 })
        .collect()
}

/// OIDN's `RT` filter (HDR) on every frame of `img`, with `aux` when given.
#[cfg(feature = "oidn")]
pub fn denoise(img: &Image, occupancy: &[u32], aux: Option<&Aux>) -> Result<Denoised, String> {
    let device = oidn::Device::cpu().map_err(|e| format!("OIDN: no CPU device ({e:?})"))?;
    let mut filter =
        oidn::RayTracing::try_new(&device).map_err(|e| format!("OIDN: no RT filter ({e:?})"))?;
    filter.hdr(true).image_dimensions(img.width, img.height);
    let (mut non_finite, mut negative) = (0, 0);
    let mut out = Image::new(img.width, img.height, img.frames);
    let n = img.pixels_per_frame();
    for f in 0..img.frames {
        let color = input(img, f, &mut non_finite, &mut negative);
        let albedo = aux.map(|a| aux_input(&a.albedo, f));
        let normal = aux.and_then(|a| a.normal.as_ref()).map(|n| aux_input(n, f));
        match (&albedo, &normal) {
            (Some(a), Some(n)) => {
                filter.albedo_normal(a, n);
            }
            (Some(a), None) => {
                filter.albedo(a);
            }
            _ => {}
        }
        let mut result = vec![0.0f32; color.len()];
        filter
            .filter(&color, &mut result)
            .map_err(|e| format!("OIDN failed: {e:?}"))?;
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

/// Without the `oidn` feature: the configuration refuses OIDN before a run
/// gets here.
#[cfg(not(feature = "oidn"))]
pub fn denoise(_img: &Image, _occupancy: &[u32], _aux: Option<&Aux>) -> Result<Denoised, String> {
    Err("this build has no OIDN (build with --features oidn)".into())
}

#[cfg(all(test, feature = "oidn"))]
mod tests {
    use super::*;

    #[test]
    fn non_finite_and_negative_input_is_zeroed_and_counted_and_empty_pixels_stay_zero() {
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
        let aux = Aux {
            albedo: albedo.clone(),
            normal: None,
        };
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
        let both = Aux {
            albedo,
            normal: Some(normal),
        };
        assert!(denoise(&img, &occupancy, Some(&both)).is_ok());
    }
}
