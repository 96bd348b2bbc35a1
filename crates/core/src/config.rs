//! The one configuration of a run: every parameter of the filter, its
//! reconstruction and the methods it is compared with, with its defaults
//! defined once ([`FilterConfig::DEFAULT`]) and checked in one place
//! ([`FilterConfig::validate`]).
//!
//! The command line fills it (each flag is a field, `--sigma-color` is
//! `sigma_color`), fixture manifests embed it, `report.json` records it and
//! sweeps vary its fields. In JSON every field is optional and defaults as
//! below; an unknown field is an error.
//!
//! ```
//! use pathdensity_core::config::{FilterConfig, White};
//! let c: FilterConfig = serde_json::from_str(r#"{"k": 20, "white": "auto"}"#).unwrap();
//! assert_eq!(c.k, 20);
//! assert_eq!(c.white, White::Auto);
//! assert_eq!(c.sigma_color, FilterConfig::DEFAULT.sigma_color);
//! assert!(c.validate().is_ok());
//! ```

use serde::{Deserialize, Serialize};

pub use crate::density::FinalPass;
use crate::density::IndexKind;
use crate::imagespace::bilateral::BilateralParams;
pub use crate::joint::ColorSpace;
use crate::joint::JointSpace;
pub use crate::joint::white::White;
pub use crate::method::{Method, MethodSet};
use crate::recon::ReconFilter;
use crate::recon::rwmc::RwmcParams;

/// A learned denoiser run on every selected method's image as well
/// (`METHOD+oidn`), or none.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Denoise {
    #[default]
    None,
    /// Intel Open Image Denoise ([`crate::imagespace::oidn`]).
    Oidn,
}

crate::names::named!(Denoise, "denoiser", { None => "none", Oidn => "oidn" });

/// The reconstruction filter W by name (docs/filter.md, "Reconstruction").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Recon {
    /// A sample counts for the pixel that contains it.
    Box,
    /// A Gaussian of s = 0.5 px truncated at 1.5 px.
    Gaussian,
}

crate::names::named!(Recon, "reconstruction filter", { Box => "box", Gaussian => "gaussian" });

impl Recon {
    pub fn filter(self) -> ReconFilter {
        match self {
            Recon::Box => ReconFilter::Box,
            Recon::Gaussian => ReconFilter::gaussian(),
        }
    }
}

/// Every parameter of a run. See the module documentation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FilterConfig {
    /// Neighbours whose mean distance is σ (the paper's k).
    pub k: usize,
    /// Image-axis scale of the joint space, in pixels.
    pub sigma_image: f64,
    /// Colour-axis scale of the joint space, in CIELAB units.
    pub sigma_color: f64,
    /// Time-axis scale of the joint space, in frames.
    pub sigma_time: f64,
    /// Luminance that maps to L* = 100, or `auto`.
    pub white: White,
    pub recon: Recon,
    /// The neighbour index (results do not depend on it).
    pub index: IndexKind,
    /// The images to make; mean and filtered are always made.
    pub methods: MethodSet,
    /// α of the trimmed mean: ⌊α n⌋ samples dropped at each end.
    pub alpha: f64,
    /// Spatial σ of the bilateral filter, in pixels.
    pub bilateral_sigma_s: f64,
    /// Range σ of the bilateral filter, in CIELAB ΔE.
    pub bilateral_sigma_r: f64,
    /// Groups of the median of means (mon, gmon).
    pub mon_groups: usize,
    /// rwmc: number of cascades S.
    pub rwmc_cascades: usize,
    /// rwmc: luminance s₀ where the second cascade starts.
    pub rwmc_start: f64,
    /// rwmc: ratio b between cascades.
    pub rwmc_base: f64,
    /// rwmc: κ, samples a bright feature needs to be trusted.
    pub rwmc_kappa: f64,
    /// rwmc: luminance always considered reliable.
    pub rwmc_min_luminance: f64,
    /// filtered_energy: σ (pixels) of the spread of the removed energy.
    pub energy_sigma: f64,
    /// clamp: the largest RGB component a sample may keep (C).
    pub clamp: f64,
    /// guided: z of the accepted samples' confidence interval.
    pub guide_z: f64,
    /// guided, guided_oidn: decide white channels (guided) or white pixels
    /// (guided_oidn) by held-out halves of the samples (docs/filter.md
    /// F10), which makes each image twice more when anything is white.
    pub held_out: bool,
    /// Exposure of the display transform (RMS_display, previews).
    pub exposure: f64,
    /// Also denoise every selected method's image (`METHOD+oidn`).
    pub denoise: Denoise,
    /// The joint space's colour coordinates.
    pub color_space: ColorSpace,
    /// What the final pass judges a stored sample against.
    pub final_pass: FinalPass,
}

impl FilterConfig {
    /// The defaults, chosen by measurement on our scenes and a real
    /// renderer's (docs/RESULTS.md, "HDR fidelity: the defaults"): the
    /// joint space `logluv` (F2b) with the white from the dump, the final
    /// pass against every sample (F6a), k = 8 (docs/RESULTS.md, "Planted
    /// fireflies"), σ_color = 50, σ_image = 3,
    /// σ_time = 2; the methods of [`MethodSet::DEFAULT`] (mean, filtered,
    /// filtered_energy and the recommended image), the comparison images'
    /// parameters at their authors' defaults.
    pub const DEFAULT: FilterConfig = FilterConfig {
        k: 8,
        sigma_image: JointSpace::DEFAULT.sigma_image,
        sigma_color: JointSpace::DEFAULT.sigma_color,
        sigma_time: JointSpace::DEFAULT.sigma_time,
        white: White::Auto,
        recon: Recon::Box,
        index: IndexKind::Grid,
        methods: MethodSet::DEFAULT,
        alpha: 0.1,
        bilateral_sigma_s: BilateralParams::DEFAULT.sigma_s,
        bilateral_sigma_r: BilateralParams::DEFAULT.sigma_r,
        mon_groups: 11,
        rwmc_cascades: RwmcParams::DEFAULT.cascades,
        rwmc_start: RwmcParams::DEFAULT.start,
        rwmc_base: RwmcParams::DEFAULT.base,
        rwmc_kappa: RwmcParams::DEFAULT.kappa,
        rwmc_min_luminance: RwmcParams::DEFAULT.min_luminance,
        energy_sigma: 8.0,
        clamp: 10.0,
        guide_z: crate::recon::guided::Z,
        held_out: true,
        exposure: 1.0,
        denoise: Denoise::None,
        color_space: JointSpace::DEFAULT.color,
        final_pass: FinalPass::All,
    };

    /// The paper's filter exactly: CIELAB (F2) against white 1, the
    /// paper's final pass (F6), k = 10, σ_image = 3, σ_color = 100,
    /// σ_time = 2; the rest as [`FilterConfig::DEFAULT`].
    /// `filter --color-space cielab --final-pass stored --white 1 --k 10
    /// --sigma-color 100` on the command line.
    pub const PAPER: FilterConfig = FilterConfig {
        k: 10,
        sigma_image: JointSpace::PAPER.sigma_image,
        sigma_color: JointSpace::PAPER.sigma_color,
        sigma_time: JointSpace::PAPER.sigma_time,
        white: White::Fixed(JointSpace::PAPER.white),
        color_space: JointSpace::PAPER.color,
        final_pass: FinalPass::Stored,
        ..FilterConfig::DEFAULT
    };

    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |field: &'static str, problem: String| Err(ConfigError { field, problem });
        let positive = |v: f64| v > 0.0 && v.is_finite();
        if self.k == 0 {
            return bad("k", "must be at least 1".into());
        }
        for (field, v) in [
            ("sigma_image", self.sigma_image),
            ("sigma_color", self.sigma_color),
            ("sigma_time", self.sigma_time),
            ("exposure", self.exposure),
            ("bilateral_sigma_s", self.bilateral_sigma_s),
            ("bilateral_sigma_r", self.bilateral_sigma_r),
            ("rwmc_start", self.rwmc_start),
            ("rwmc_kappa", self.rwmc_kappa),
            ("clamp", self.clamp),
            ("guide_z", self.guide_z),
        ] {
            if !positive(v) {
                return bad(field, format!("must be a positive finite number, got {v}"));
            }
        }
        if let White::Fixed(v) = self.white
            && !positive(v)
        {
            return bad(
                "white",
                format!("must be `auto` or a positive number, got {v}"),
            );
        }
        // A scale divides distances that are then squared: outside this
        // range the squares leave the finite doubles and the images turn
        // to NaN.
        let white = match self.white {
            White::Fixed(v) => v,
            White::Auto => 1.0,
        };
        for (field, v) in [
            ("sigma_image", self.sigma_image),
            ("sigma_color", self.sigma_color),
            ("sigma_time", self.sigma_time),
            ("bilateral_sigma_s", self.bilateral_sigma_s),
            ("bilateral_sigma_r", self.bilateral_sigma_r),
            ("energy_sigma", self.energy_sigma),
            ("rwmc_start", self.rwmc_start),
            ("rwmc_kappa", self.rwmc_kappa),
            ("white", white),
        ] {
            if !(SCALE_MIN..=SCALE_MAX).contains(&v) {
                return bad(
                    field,
                    format!(
                        "must lie in [{SCALE_MIN:e}, {SCALE_MAX:e}], where its square stays a finite number, got {v:e}"
                    ),
                );
            }
        }
        let oidn_wanted = self.methods.iter().find(|m| m.needs_oidn());
        if (oidn_wanted.is_some() || self.denoise == Denoise::Oidn)
            && let Err(none) = crate::imagespace::oidn::library()
        {
            let why = format!("needs OIDN, and {none} (README, \"OIDN\")");
            return match oidn_wanted {
                Some(m) => bad("methods", format!("{m} {why}")),
                None => bad("denoise", format!("oidn {why}")),
            };
        }
        if !(0.0..0.5).contains(&self.alpha) {
            return bad("alpha", format!("must lie in [0, 0.5), got {}", self.alpha));
        }
        if self.bilateral_sigma_s > 1000.0 {
            return bad("bilateral_sigma_s", "is above 1000 pixels".into());
        }
        if self.mon_groups == 0 {
            return bad("mon_groups", "must be at least 1".into());
        }
        if !(2..=32).contains(&self.rwmc_cascades) {
            return bad(
                "rwmc_cascades",
                format!("must be in 2..=32, got {}", self.rwmc_cascades),
            );
        }
        if !(positive(self.rwmc_base) && self.rwmc_base > 1.0) {
            return bad(
                "rwmc_base",
                format!("must be above 1, got {}", self.rwmc_base),
            );
        }
        let last = self.rwmc_start * self.rwmc_base.powi(self.rwmc_cascades as i32 - 1);
        if last > SCALE_MAX {
            return bad(
                "rwmc_base",
                format!(
                    "makes the last cascade's scale rwmc_start × rwmc_base^(rwmc_cascades − 1) = {last:e}, above {SCALE_MAX:e}"
                ),
            );
        }
        if !(self.rwmc_min_luminance.is_finite() && self.rwmc_min_luminance >= 0.0) {
            return bad(
                "rwmc_min_luminance",
                format!("must be finite and ≥ 0, got {}", self.rwmc_min_luminance),
            );
        }
        if !(self.energy_sigma > 0.0 && self.energy_sigma <= 1e4) {
            return bad(
                "energy_sigma",
                format!("must lie in (0, 10000] pixels, got {}", self.energy_sigma),
            );
        }
        Ok(())
    }

    /// The joint space with the resolved white luminance `white`.
    pub fn space(&self, white: f64) -> JointSpace {
        JointSpace {
            sigma_image: self.sigma_image,
            sigma_color: self.sigma_color,
            sigma_time: self.sigma_time,
            white,
            color: self.color_space,
        }
    }

    pub fn bilateral(&self) -> BilateralParams {
        BilateralParams {
            sigma_s: self.bilateral_sigma_s,
            sigma_r: self.bilateral_sigma_r,
        }
    }

    pub fn rwmc(&self) -> RwmcParams {
        RwmcParams {
            cascades: self.rwmc_cascades,
            start: self.rwmc_start,
            base: self.rwmc_base,
            kappa: self.rwmc_kappa,
            min_luminance: self.rwmc_min_luminance,
        }
    }
}

impl Default for FilterConfig {
    fn default() -> Self {
        FilterConfig::DEFAULT
    }
}

/// The smallest and largest scale a configuration takes (σ, κ, the
/// white): far beyond any real scene, well inside the finite doubles once
/// squared.
pub const SCALE_MIN: f64 = 1e-100;
pub const SCALE_MAX: f64 = 1e100;

/// A configuration field with a value it cannot take.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{field} {problem}")]
pub struct ConfigError {
    /// The field's name (the command line spells it with dashes).
    pub field: &'static str,
    pub problem: String,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_round_trip_through_json() {
        let c = FilterConfig::DEFAULT;
        c.validate().unwrap();
        let json = serde_json::to_string(&c).unwrap();
        assert_eq!(serde_json::from_str::<FilterConfig>(&json).unwrap(), c);
        let auto = FilterConfig {
            white: White::Auto,
            methods: MethodSet::CORE.with(Method::Rwmc),
            ..c
        };
        let json = serde_json::to_string(&auto).unwrap();
        assert!(json.contains(r#""white":"auto""#), "{json}");
        assert!(
            json.contains(r#""methods":["mean","filtered","rwmc"]"#),
            "{json}"
        );
        assert_eq!(serde_json::from_str::<FilterConfig>(&json).unwrap(), auto);
    }

    #[test]
    fn errors_name_the_field() {
        let e = FilterConfig {
            sigma_color: 0.0,
            ..FilterConfig::DEFAULT
        }
        .validate()
        .unwrap_err();
        assert_eq!(e.field, "sigma_color");
        let e = FilterConfig {
            alpha: 0.5,
            ..FilterConfig::DEFAULT
        }
        .validate()
        .unwrap_err();
        assert_eq!(e.field, "alpha");
        assert!(serde_json::from_str::<FilterConfig>(r#"{"kk": 3}"#).is_err());
        assert!(serde_json::from_str::<FilterConfig>(r#"{"white": "bright"}"#).is_err());
    }
}
