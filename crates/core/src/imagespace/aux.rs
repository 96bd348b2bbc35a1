//! The renderer's auxiliary images, its first-hit albedo and normal: OIDN
//! takes them beside the colour, statmc weighs its neighbours by them, and
//! [`AuxPrefilter`] says how OIDN is to treat them (docs/filter.md, "OIDN").

use std::fmt;
use std::str::FromStr;
use std::sync::OnceLock;

use super::oidn::OidnError;
use crate::recon::Image;

/// How OIDN treats the auxiliary images, under the names Blender gives
/// the same choice. OIDN's `cleanAux` says they are noise-free; its
/// documented prefiltering makes them so.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AuxPrefilter {
    /// Denoised by OIDN first, each on its own (its `RT` filter given the
    /// albedo alone, then the normal alone), then taken as noise-free:
    /// right whether they were rendered with few samples or many.
    /// Blender's default, and ours.
    #[default]
    Accurate,
    /// Taken as they are, as possibly noisy (`cleanAux` off): OIDN's own
    /// default, and no prefiltering.
    Fast,
    /// Taken as they are, as noise-free (`cleanAux` on): for images
    /// rendered with many samples, or denoised already.
    None,
}

impl AuxPrefilter {
    pub const ALL: [AuxPrefilter; 3] = [Self::Accurate, Self::Fast, Self::None];

    pub fn name(self) -> &'static str {
        match self {
            Self::Accurate => "accurate",
            Self::Fast => "fast",
            Self::None => "none",
        }
    }

    /// Whether OIDN is told the images it is given are noise-free.
    pub(crate) fn clean(self) -> bool {
        self != Self::Fast
    }
}

impl fmt::Display for AuxPrefilter {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for AuxPrefilter {
    type Err = String;
    fn from_str(s: &str) -> Result<AuxPrefilter, String> {
        Self::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| format!("expected accurate, fast or none, got {s:?}"))
    }
}

/// An albedo and, optionally, a normal as OIDN reads them.
pub(crate) type AuxImages = (Vec<f32>, Option<Vec<f32>>);

/// The renderer's first-hit albedo, and optionally its normal (only with
/// an albedo), the film's size and frames. Kept as OIDN reads them, f32
/// with non-finite values as 0, made once for every use of a run (every
/// OIDN call: the image, two held-out halves, `--denoise oidn`'s), and
/// prefiltered at most once. Not `Clone`: a copy would prefilter again.
#[derive(Debug)]
pub struct Aux {
    albedo: Vec<f32>,
    normal: Option<Vec<f32>>,
    prefilter: AuxPrefilter,
    /// The images OIDN denoised ([`AuxPrefilter::Accurate`]), made by the
    /// first OIDN call of the run.
    prefiltered: OnceLock<Result<AuxImages, OidnError>>,
}

impl Aux {
    /// The images, prefiltered as [`AuxPrefilter`]'s default says.
    pub fn new(albedo: &Image, normal: Option<&Image>) -> Aux {
        Aux {
            albedo: oidn_values(albedo),
            normal: normal.map(oidn_values),
            prefilter: AuxPrefilter::default(),
            prefiltered: OnceLock::new(),
        }
    }

    pub fn with_prefilter(self, prefilter: AuxPrefilter) -> Aux {
        Aux { prefilter, ..self }
    }

    pub fn prefilter(&self) -> AuxPrefilter {
        self.prefilter
    }

    /// The albedo as the renderer gave it (statmc's guide).
    pub(crate) fn albedo(&self) -> &[f32] {
        &self.albedo
    }

    /// The normal as the renderer gave it.
    pub(crate) fn normal(&self) -> Option<&[f32]> {
        self.normal.as_deref()
    }

    /// The albedo and normal OIDN is given: as the renderer gave them, or
    /// for [`AuxPrefilter::Accurate`] as `denoise(albedo, normal)` makes
    /// them, once for the run (a failure is the run's every call's).
    pub(crate) fn for_oidn(
        &self,
        denoise: impl FnOnce(&[f32], Option<&[f32]>) -> Result<AuxImages, OidnError>,
    ) -> Result<(&[f32], Option<&[f32]>), OidnError> {
        if self.prefilter != AuxPrefilter::Accurate {
            return Ok((&self.albedo, self.normal.as_deref()));
        }
        let made = self
            .prefiltered
            .get_or_init(|| denoise(&self.albedo, self.normal.as_deref()));
        match made {
            Ok((albedo, normal)) => Ok((albedo, normal.as_deref())),
            Err(e) => Err(e.clone()),
        }
    }
}

/// An auxiliary image's values as OIDN takes them: RGB f32, row-major,
/// frame after frame, non-finite as 0.
fn oidn_values(img: &Image) -> Vec<f32> {
    // Finite after the cast: an f64 beyond f32's range would be ∞.
    let value = |&v: &f64| Some(v as f32).filter(|v| v.is_finite()).unwrap_or(0.0);
    img.data.iter().flatten().map(value).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A value beyond f32's range is kept as 0, not ∞.
    #[test]
    fn auxiliary_images_stay_finite() {
        let albedo = Image {
            data: vec![[0.5, 1e300, f64::NAN]; 4],
            ..Image::new(2, 2, 1)
        };
        let aux = Aux::new(&albedo, None);
        assert_eq!(&aux.albedo()[..3], &[0.5, 0.0, 0.0]);
    }

    #[test]
    fn prefilter_names_parse_back() {
        for p in AuxPrefilter::ALL {
            assert_eq!(p.name().parse::<AuxPrefilter>(), Ok(p));
        }
        assert!("clean".parse::<AuxPrefilter>().is_err());
        assert_eq!(AuxPrefilter::default(), AuxPrefilter::Accurate);
    }

    /// Only `accurate` asks for the denoised images, once for every call;
    /// a failure to make them is every call's.
    #[test]
    fn only_accurate_denoises_the_images_once() {
        let img = Image {
            data: vec![[0.25; 3]; 4],
            ..Image::new(2, 2, 1)
        };
        let calls = std::cell::Cell::new(0);
        let halved = |a: &[f32], n: Option<&[f32]>| {
            calls.set(calls.get() + 1);
            let half = |v: &[f32]| v.iter().map(|x| x / 2.0).collect::<Vec<f32>>();
            Ok((half(a), n.map(half)))
        };
        for p in [AuxPrefilter::Fast, AuxPrefilter::None] {
            let aux = Aux::new(&img, Some(&img)).with_prefilter(p);
            let (albedo, normal) = aux.for_oidn(halved).unwrap();
            assert_eq!((albedo[0], normal.unwrap()[0]), (0.25, 0.25));
        }
        assert_eq!(calls.get(), 0);
        let aux = Aux::new(&img, Some(&img));
        for _ in 0..3 {
            let (albedo, normal) = aux.for_oidn(halved).unwrap();
            assert_eq!((albedo[0], normal.unwrap()[0]), (0.125, 0.125));
        }
        assert_eq!(calls.get(), 1);
        assert_eq!(aux.albedo()[0], 0.25, "statmc's guide is the renderer's");
        let failing = Aux::new(&img, None);
        let tries = std::cell::Cell::new(0);
        for _ in 0..2 {
            let err = failing.for_oidn(|_, _| {
                tries.set(tries.get() + 1);
                Err(OidnError::NoFilter)
            });
            assert_eq!(err, Err(OidnError::NoFilter));
        }
        assert_eq!(tries.get(), 1, "the failure is kept, not retried");
    }
}
