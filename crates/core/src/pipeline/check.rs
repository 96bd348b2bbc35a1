//! What is refused before the replay (docs/filter.md §2): a configuration
//! that cannot give a useful result on this dump, and the white luminance
//! it asks for.

use super::PipelineError;
use crate::config::{ConfigError, FilterConfig, White};
use crate::dump::{Header, Record, Validity};
use crate::imagespace::oidn::Aux;
use crate::joint::white::auto_white;

/// The white luminance `config` asks for on these records. `auto` needs
/// a valid sample of positive luminance.
pub fn resolve_white(
    config: &FilterConfig,
    records: &[Record],
    header: &Header,
) -> Result<f64, PipelineError> {
    match config.white {
        White::Fixed(v) => Ok(v),
        White::Auto => auto_white(records, header).ok_or(PipelineError::NoWhite),
    }
}

/// A [`ConfigError`] on `albedo` (or `normal`) unless the renderer's
/// images hold the film `h`'s pixels, every frame.
pub(crate) fn aux_fits(aux: &Aux, h: &Header) -> Result<(), ConfigError> {
    let want = 3 * h.pixels() * h.frames as usize;
    let check = |field, v: &[f32]| match v.len() {
        n if n == want => Ok(()),
        n => Err(ConfigError {
            field,
            problem: format!(
                "holds {} pixels, and the film {} × {} × {} frames",
                n / 3,
                h.width,
                h.height,
                h.frames
            ),
        }),
    };
    check("albedo", aux.albedo())?;
    aux.normal().map_or(Ok(()), |n| check("normal", n))
}

/// Checks `config` against the dump before the replay: k below the number
/// of valid samples (else every sample is rejected), joint coordinates
/// that stay finite in f32 on this film. Valid samples are counted only
/// until there are more than k: a dump that has them is not read on.
pub fn check(
    config: &FilterConfig,
    records: &[Record],
    header: &Header,
) -> Result<(), PipelineError> {
    config.validate()?;
    let valid = records
        .iter()
        .filter(|r| r.validity(header) == Validity::Valid)
        .take(config.k.saturating_add(1))
        .count() as u64;
    check_counted(config, header, valid)
}

/// k against the number of valid samples: at or above it every σ is +∞
/// and every sample rejected.
pub fn k_fits(k: usize, valid: u64) -> Result<(), PipelineError> {
    if valid == 0 {
        return Err(PipelineError::NoValidSample);
    }
    if k as u64 >= valid {
        return Err(ConfigError {
            field: "k",
            problem: format!(
                "{} needs more than {valid} valid samples: every sample would be rejected",
                k
            ),
        }
        .into());
    }
    Ok(())
}

/// [`check`] for a caller that has counted the valid samples already (a
/// sweep, once for all its configurations); `config` is valid.
pub fn check_counted(
    config: &FilterConfig,
    header: &Header,
    valid: u64,
) -> Result<(), PipelineError> {
    k_fits(config.k, valid)?;
    // Coordinates beyond this would round to ±∞ in f32 (docs/filter.md, F4).
    const MAX_COORD: f64 = 1e30;
    let film = header.width.max(header.height) as f64;
    if film / config.sigma_image > MAX_COORD {
        return Err(ConfigError {
            field: "sigma_image",
            problem: format!(
                "{:?} is too small for a {film}-pixel film: image coordinates would overflow",
                config.sigma_image
            ),
        }
        .into());
    }
    if header.animated() && header.frames as f64 / config.sigma_time > MAX_COORD {
        return Err(ConfigError {
            field: "sigma_time",
            problem: format!(
                "{:?} is too small for {} frames: time coordinates would overflow",
                config.sigma_time, header.frames
            ),
        }
        .into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recon::Image;

    /// The renderer's images must hold the film's pixels, every frame.
    #[test]
    fn auxiliary_images_fit_the_film() {
        let aux = Aux::new(&Image::new(2, 2, 1), Some(&Image::new(2, 2, 1)));
        let mut h = crate::recon::test_header(2, 2);
        assert_eq!(aux_fits(&aux, &h), Ok(()));
        h.frames = 2;
        assert_eq!(aux_fits(&aux, &h).unwrap_err().field, "albedo");
        let short = Aux::new(&Image::new(2, 2, 2), Some(&Image::new(2, 2, 1)));
        assert_eq!(aux_fits(&short, &h).unwrap_err().field, "normal");
    }
}
