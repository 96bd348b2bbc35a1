//! The images a run can produce: the path-density filter, its baselines
//! (docs/filter.md, "Methods") and the combinations the paper shows. How
//! each is made is [`super::estimate`]'s table.

use std::str::FromStr;

/// One output image. The names are the file names (`NAME.exr`).
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// All valid samples.
    Mean,
    /// The accepted samples (the path-density filter).
    Filtered,
    /// Per-pixel, per-channel median of the samples.
    Median,
    /// Per-pixel, per-channel α-trimmed mean.
    Trimmed,
    /// The bilateral filter applied to the mean.
    Bilateral,
    /// 3 × 3 image-space median of the mean (the paper's Figure 3).
    Median3,
    /// The bilateral filter applied to the filtered image (Figure 6d).
    FilteredBilateral,
    /// Per-pixel median of means (Buisine et al. 2021).
    Mon,
    /// Gini-adaptive median of means (Buisine et al. 2021).
    Gmon,
    /// Reweighted cascades (Zirr et al. 2018).
    Rwmc,
    /// The filtered image with the removed energy spread back
    /// ([`crate::recon::energy`]).
    FilteredEnergy,
    /// Every sample clamped to a largest component of C, then the mean
    /// (pbrt-v4's `maxcomponentvalue`; [`crate::recon::clamp`]).
    Clamp,
    /// filtered_energy, then the bilateral filter, held per pixel and
    /// channel inside the confidence interval of the pixel's mean
    /// ([`crate::recon::confidence`]): the pure-Rust build's recommended
    /// image.
    FilteredEnergyBilateralCi,
    /// Intel Open Image Denoise's `RT` filter on the mean
    /// ([`crate::imagespace::oidn`]; only in builds with the `oidn` feature).
    Oidn,
    /// OIDN's image of the mean held, per pixel and channel, inside the
    /// confidence interval of the pixel's mean
    /// ([`crate::recon::confidence`]; only with the `oidn` feature).
    OidnCi,
}

impl Method {
    pub const ALL: [Method; 15] = [
        Method::Mean,
        Method::Filtered,
        Method::Median,
        Method::Trimmed,
        Method::Bilateral,
        Method::Median3,
        Method::FilteredBilateral,
        Method::Mon,
        Method::Gmon,
        Method::Rwmc,
        Method::FilteredEnergy,
        Method::Clamp,
        Method::FilteredEnergyBilateralCi,
        Method::Oidn,
        Method::OidnCi,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Method::Mean => "mean",
            Method::Filtered => "filtered",
            Method::Median => "median",
            Method::Trimmed => "trimmed",
            Method::Bilateral => "bilateral",
            Method::Median3 => "median3",
            Method::FilteredBilateral => "filtered_bilateral",
            Method::Mon => "mon",
            Method::Gmon => "gmon",
            Method::Rwmc => "rwmc",
            Method::FilteredEnergy => "filtered_energy",
            Method::Clamp => "clamp",
            Method::FilteredEnergyBilateralCi => "filtered_energy_bilateral_ci",
            Method::Oidn => "oidn",
            Method::OidnCi => "oidn_ci",
        }
    }

    /// Whether the image depends on the filter's decisions. The others
    /// are made from the samples alone, so a run makes them beside the
    /// replay.
    pub fn needs_decisions(self) -> bool {
        matches!(
            self,
            Method::Filtered
                | Method::FilteredBilateral
                | Method::FilteredEnergy
                | Method::FilteredEnergyBilateralCi
        )
    }

    /// Whether the image needs the white luminance (docs/filter.md §1):
    /// the bilateral filter's ΔE does.
    pub fn needs_white(self) -> bool {
        matches!(
            self,
            Method::Bilateral | Method::FilteredBilateral | Method::FilteredEnergyBilateralCi
        )
    }

    /// Whether the image needs OIDN (a build with the `oidn` feature).
    pub fn needs_oidn(self) -> bool {
        matches!(self, Method::Oidn | Method::OidnCi)
    }

    fn bit(self) -> u16 {
        1 << self as u16
    }
}

impl FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Method, String> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
                format!("unknown method {s:?} (one of {})", names.join(", "))
            })
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A set of methods that always holds mean and filtered, which every run
/// makes. Iterates in the canonical order of [`Method::ALL`]; in JSON a
/// list of names.
///
/// ```
/// use pathdensity_core::config::{Method, MethodSet};
/// let s: MethodSet = [Method::Rwmc].into_iter().collect();
/// let v: Vec<Method> = s.iter().collect();
/// assert_eq!(v, [Method::Mean, Method::Filtered, Method::Rwmc]);
/// ```
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct MethodSet(u16);

impl MethodSet {
    /// Mean and filtered.
    pub const CORE: MethodSet = MethodSet(1 << Method::Mean as u16 | 1 << Method::Filtered as u16);
    pub const ALL: MethodSet = MethodSet((1 << Method::ALL.len()) - 1);
    /// What a run makes unless told otherwise: every method but plain
    /// `oidn` (asked for by name, or with `denoise`), and `oidn_ci` only in
    /// builds that have OIDN, where it is the recommended image.
    pub const DEFAULT: MethodSet = {
        let oidn_ci = if crate::imagespace::oidn::AVAILABLE {
            0
        } else {
            1 << Method::OidnCi as u16
        };
        MethodSet(MethodSet::ALL.0 & !(1 << Method::Oidn as u16) & !oidn_ci)
    };

    pub fn contains(self, m: Method) -> bool {
        self.0 & m.bit() != 0
    }

    /// This set without `m` (mean and filtered stay).
    pub fn without(self, m: Method) -> MethodSet {
        MethodSet(self.0 & !m.bit())
            .with(Method::Mean)
            .with(Method::Filtered)
    }

    /// This set and `m`.
    pub fn with(self, m: Method) -> MethodSet {
        MethodSet(self.0 | m.bit())
    }

    /// The methods in the canonical order.
    pub fn iter(self) -> impl Iterator<Item = Method> {
        Method::ALL.into_iter().filter(move |&m| self.contains(m))
    }
}

impl FromIterator<Method> for MethodSet {
    fn from_iter<I: IntoIterator<Item = Method>>(iter: I) -> MethodSet {
        iter.into_iter().fold(MethodSet::CORE, MethodSet::with)
    }
}

impl std::fmt::Debug for MethodSet {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

impl serde::Serialize for MethodSet {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.iter())
    }
}

impl<'de> serde::Deserialize<'de> for MethodSet {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<MethodSet, D::Error> {
        Ok(Vec::<Method>::deserialize(d)?.into_iter().collect())
    }
}
