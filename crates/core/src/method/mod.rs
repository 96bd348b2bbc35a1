//! The images a run can produce: the path-density filter, its baselines
//! (docs/filter.md, "Methods"), the peer methods and the combinations the
//! paper shows, each one row of [`TABLE`]: its name, what it needs, the
//! work it shares, its role in sweeps, whether it is made by default and
//! whether it can be the recommended image. Everything else about methods
//! (the list of all, the names, the default set, the sweeps' peers, the
//! recommended order) is derived from the table. How each image is made is
//! its estimator, [`crate::pipeline::estimate::Estimators::image`].

use std::str::FromStr;

mod image;
mod set;

pub use image::ImageId;
pub use set::MethodSet;

/// One output image. The names are the file names (`NAME.exr`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
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
    /// ([`crate::recon::confidence`]).
    FilteredEnergyBilateralCi,
    /// Intel Open Image Denoise's `RT` filter on the mean
    /// ([`crate::imagespace::oidn`]; needs OIDN found at run time).
    Oidn,
    /// OIDN's image of the mean held, per pixel and channel, inside the
    /// confidence interval of the pixel's mean
    /// ([`crate::recon::confidence`]; needs OIDN).
    OidnCi,
    /// The density-guided image ([`crate::recon::guided`]): statmc with
    /// the removed energy spread back where the pixel is noise, raised to
    /// what the accepted samples vouch for where they vouch for more,
    /// never above what all its samples allow. The recommended image
    /// where no OIDN is found.
    Guided,
    /// The same with OIDN's image of the mean as the denoiser (needs
    /// OIDN; the recommended image where it is found).
    GuidedOidn,
    /// The statistical denoiser ([`crate::recon::statmc`], Sakai et al.
    /// 2024) on the accepted samples.
    Statmc,
}

/// What an image is made from besides the samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Needs {
    /// The filter's decisions: the image is made after the replay. The
    /// others are made from the samples alone, beside it.
    pub decisions: bool,
    /// The white luminance (docs/filter.md §1): the bilateral filter's ΔE.
    pub white: bool,
    /// Intel Open Image Denoise, found at run time
    /// ([`crate::imagespace::oidn::library`]).
    pub oidn: bool,
}

const SAMPLES: Needs = Needs {
    decisions: false,
    white: false,
    oidn: false,
};
const DECISIONS: Needs = Needs {
    decisions: true,
    ..SAMPLES
};
const WHITE: Needs = Needs {
    white: true,
    ..SAMPLES
};
const OIDN: Needs = Needs {
    oidn: true,
    ..SAMPLES
};

/// Work several images share, made once per configuration
/// ([`crate::pipeline::estimate::Estimators::prepare`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Piece {
    /// Median and trimmed (`recon::robust::robust_images`).
    Robust,
    /// mon and gmon (`recon::mon::mon_images`).
    Mon,
    /// filtered_energy's image.
    FilteredEnergy,
    /// Every pixel's confidence interval.
    Interval,
    /// OIDN's image of the mean.
    OidnMean,
    /// Every pixel's confidence interval of its accepted samples.
    AcceptedInterval,
    /// statmc's image.
    Statmc,
}

impl Piece {
    pub const ALL: [Piece; 7] = [
        Piece::Robust,
        Piece::Mon,
        Piece::FilteredEnergy,
        Piece::Interval,
        Piece::OidnMean,
        Piece::AcceptedInterval,
        Piece::Statmc,
    ];

    /// The shared pieces `method`'s image is made from (a test checks
    /// that no image uses a piece not listed).
    pub fn of(method: Method) -> &'static [Piece] {
        method.row().pieces
    }
}

/// The one parameter `sweep` varies for a peer method.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Param {
    /// `mon_groups`.
    MonGroups,
    /// `rwmc_kappa`.
    RwmcKappa,
    /// `clamp`.
    Clamp,
}

impl Param {
    /// In the order sweeps list them.
    pub const ALL: [Param; 3] = [Param::MonGroups, Param::RwmcKappa, Param::Clamp];

    /// How a sweep's label names it: `mon groups=11`.
    pub fn key(self) -> &'static str {
        match self {
            Param::MonGroups => "groups",
            Param::RwmcKappa => "kappa",
            Param::Clamp => "C",
        }
    }
}

/// A method's part in `sweep` and `sweep --equal-time`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// The filter's own images, made at every point of the grid (and at
    /// every prefix of the equal-time comparison).
    Grid,
    /// A baseline, made once at the sweep's base configuration and in
    /// the equal-time comparison of the whole dump.
    Baseline,
    /// A baseline that is also compared at equal time, prefix by prefix.
    EqualTime,
    /// A peer method: one image per value of its parameter, and compared
    /// at equal time.
    Peer(Param),
    /// Not in sweeps.
    Outside,
}

/// Whether a run makes an image when `--methods` is not given
/// ([`MethodSet::default_here`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Made {
    /// Only when named (`--methods NAME`, or `all`).
    ByName,
    /// By default, where this process can make it.
    ByDefault,
    /// By default where this process can make it, and then the given
    /// default image is not made: one recommended image a run.
    InsteadOf(Method),
}

/// One row of the method table.
#[derive(Clone, Copy, Debug)]
pub struct Row {
    pub method: Method,
    /// The image's name: its file (`NAME.exr`), its key in reports, its
    /// spelling in `--methods` and in JSON.
    pub name: &'static str,
    pub needs: Needs,
    /// The work it shares with other images.
    pub pieces: &'static [Piece],
    pub role: Role,
    /// Whether a run makes it when `--methods` is not given.
    pub default: Made,
    /// Its rank as the image a user should use, 0 first, no two alike:
    /// the first of the ranked images a run made is its `recommended`
    /// image (README, "Which image to use"; measured in docs/RESULTS.md,
    /// "The guided image").
    pub recommend: Option<u8>,
    /// The bytes a pixel of every frame its image costs at its peak,
    /// beyond the bare run's (0 for mean and filtered, which the bare run
    /// makes): the image (24, three f64), its own working buffers and its
    /// shared pieces', for `guided` and `guided_oidn` the held-out halves.
    /// OIDN's library is counted once a run instead (`pipeline::memory`;
    /// the values: docs/BENCHMARKS.md, "Memory a film needs").
    pub bytes_per_pixel: u16,
}

/// Every method, in the canonical order: `TABLE[m as usize].method == m`
/// (checked when the crate compiles).
pub const TABLE: &[Row] = &[
    Row {
        method: Method::Mean,
        name: "mean",
        needs: SAMPLES,
        pieces: &[],
        role: Role::Baseline,
        default: Made::ByDefault,
        recommend: None,
        bytes_per_pixel: 0,
    },
    Row {
        method: Method::Filtered,
        name: "filtered",
        needs: DECISIONS,
        pieces: &[],
        role: Role::Grid,
        default: Made::ByDefault,
        recommend: Some(5),
        bytes_per_pixel: 0,
    },
    Row {
        method: Method::Median,
        name: "median",
        needs: SAMPLES,
        pieces: &[Piece::Robust],
        role: Role::Baseline,
        default: Made::ByName,
        recommend: None,
        bytes_per_pixel: 78,
    },
    Row {
        method: Method::Trimmed,
        name: "trimmed",
        needs: SAMPLES,
        pieces: &[Piece::Robust],
        role: Role::Baseline,
        default: Made::ByName,
        recommend: None,
        bytes_per_pixel: 78,
    },
    Row {
        method: Method::Bilateral,
        name: "bilateral",
        needs: WHITE,
        pieces: &[],
        role: Role::Baseline,
        default: Made::ByName,
        recommend: None,
        bytes_per_pixel: 25,
    },
    Row {
        method: Method::Median3,
        name: "median3",
        needs: SAMPLES,
        pieces: &[],
        role: Role::Outside,
        default: Made::ByName,
        recommend: None,
        bytes_per_pixel: 24,
    },
    Row {
        method: Method::FilteredBilateral,
        name: "filtered_bilateral",
        needs: Needs {
            white: true,
            ..DECISIONS
        },
        pieces: &[],
        role: Role::Outside,
        default: Made::ByName,
        recommend: None,
        bytes_per_pixel: 25,
    },
    Row {
        method: Method::Mon,
        name: "mon",
        needs: SAMPLES,
        pieces: &[Piece::Mon],
        role: Role::Peer(Param::MonGroups),
        default: Made::ByName,
        recommend: None,
        bytes_per_pixel: 78,
    },
    Row {
        method: Method::Gmon,
        name: "gmon",
        needs: SAMPLES,
        pieces: &[Piece::Mon],
        role: Role::Peer(Param::MonGroups),
        default: Made::ByName,
        recommend: None,
        bytes_per_pixel: 78,
    },
    Row {
        method: Method::Rwmc,
        name: "rwmc",
        needs: SAMPLES,
        pieces: &[],
        role: Role::Peer(Param::RwmcKappa),
        default: Made::ByName,
        recommend: None,
        bytes_per_pixel: 49,
    },
    Row {
        method: Method::FilteredEnergy,
        name: "filtered_energy",
        needs: DECISIONS,
        pieces: &[Piece::FilteredEnergy],
        role: Role::Grid,
        default: Made::ByDefault,
        recommend: Some(4),
        bytes_per_pixel: 28,
    },
    Row {
        method: Method::Clamp,
        name: "clamp",
        needs: SAMPLES,
        pieces: &[],
        role: Role::Peer(Param::Clamp),
        default: Made::ByName,
        recommend: None,
        bytes_per_pixel: 24,
    },
    Row {
        method: Method::FilteredEnergyBilateralCi,
        name: "filtered_energy_bilateral_ci",
        needs: Needs {
            white: true,
            ..DECISIONS
        },
        pieces: &[Piece::FilteredEnergy, Piece::Interval],
        role: Role::Outside,
        default: Made::ByName,
        recommend: Some(3),
        bytes_per_pixel: 78,
    },
    Row {
        method: Method::Oidn,
        name: "oidn",
        needs: OIDN,
        pieces: &[Piece::OidnMean],
        role: Role::EqualTime,
        // Asked for by name, or with `denoise`.
        default: Made::ByName,
        recommend: None,
        bytes_per_pixel: 58,
    },
    Row {
        method: Method::OidnCi,
        name: "oidn_ci",
        needs: OIDN,
        pieces: &[Piece::OidnMean, Piece::Interval],
        role: Role::EqualTime,
        default: Made::ByName,
        recommend: Some(2),
        bytes_per_pixel: 89,
    },
    Row {
        method: Method::Guided,
        name: "guided",
        needs: DECISIONS,
        pieces: &[Piece::Statmc, Piece::Interval, Piece::AcceptedInterval],
        role: Role::Outside,
        default: Made::ByDefault,
        recommend: Some(1),
        bytes_per_pixel: 365,
    },
    Row {
        method: Method::GuidedOidn,
        name: "guided_oidn",
        needs: Needs {
            oidn: true,
            ..DECISIONS
        },
        pieces: &[Piece::OidnMean, Piece::Interval, Piece::AcceptedInterval],
        role: Role::Outside,
        default: Made::InsteadOf(Method::Guided),
        recommend: Some(0),
        bytes_per_pixel: 307,
    },
    Row {
        method: Method::Statmc,
        name: "statmc",
        needs: DECISIONS,
        pieces: &[Piece::Statmc],
        role: Role::Outside,
        default: Made::ByName,
        recommend: None,
        bytes_per_pixel: 200,
    },
];

const _: () = {
    let mut i = 0;
    while i < TABLE.len() {
        assert!(TABLE[i].method as usize == i, "TABLE is in Method's order");
        i += 1;
    }
};

impl Method {
    /// How many methods there are.
    pub const COUNT: usize = TABLE.len();

    /// Every method, in the canonical order.
    pub const ALL: [Method; Method::COUNT] = {
        let mut all = [Method::Mean; Method::COUNT];
        let mut i = 0;
        while i < Method::COUNT {
            all[i] = TABLE[i].method;
            i += 1;
        }
        all
    };

    /// This method's row of [`TABLE`].
    pub const fn row(self) -> &'static Row {
        &TABLE[self as usize]
    }

    pub const fn name(self) -> &'static str {
        self.row().name
    }

    /// Whether the image depends on the filter's decisions.
    pub const fn needs_decisions(self) -> bool {
        self.row().needs.decisions
    }

    /// Whether the image needs the white luminance.
    pub const fn needs_white(self) -> bool {
        self.row().needs.white
    }

    /// Whether the image needs OIDN.
    pub const fn needs_oidn(self) -> bool {
        self.row().needs.oidn
    }

    /// Whether this process can make the image (OIDN is found at run
    /// time: [`crate::imagespace::oidn::library`]).
    pub fn available(self) -> bool {
        !self.needs_oidn() || crate::imagespace::oidn::available()
    }

    /// The methods that can be recommended, most preferred first.
    pub fn by_preference() -> Vec<Method> {
        let mut ranked: Vec<(u8, Method)> = TABLE
            .iter()
            .filter_map(|r| r.recommend.map(|rank| (rank, r.method)))
            .collect();
        ranked.sort();
        ranked.into_iter().map(|(_, m)| m).collect()
    }

    /// The methods whose role in sweeps is `role` and that this build
    /// can make, in the canonical order.
    pub fn with_role(role: impl Fn(Role) -> bool) -> impl Iterator<Item = Method> {
        Method::ALL
            .into_iter()
            .filter(move |m| role(m.row().role) && m.available())
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

// A method is its name in JSON, as on the command line.
impl serde::Serialize for Method {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> serde::Deserialize<'de> for Method {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Method, D::Error> {
        let name = String::deserialize(d)?;
        name.parse().map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tie would leave the recommended image to the enum's order.
    #[test]
    fn no_two_methods_share_a_recommend_rank() {
        let mut ranks: Vec<u8> = TABLE.iter().filter_map(|r| r.recommend).collect();
        let n = ranks.len();
        ranks.sort_unstable();
        ranks.dedup();
        assert_eq!(ranks.len(), n, "{ranks:?}");
    }
}
