//! The images a run can produce: the path-density filter, its baselines
//! (SPEC §4) and the combinations the paper shows.

/// One output image. The names are the file names (`NAME.exr`).
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, clap::ValueEnum,
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
    #[value(name = "filtered_bilateral")]
    FilteredBilateral,
    /// Per-pixel median of means (Buisine et al. 2021).
    Mon,
    /// Gini-adaptive median of means (Buisine et al. 2021).
    Gmon,
    /// Reweighted cascades (Zirr et al. 2018).
    Rwmc,
    /// The filtered image with the removed energy spread back
    /// ([`crate::recon::energy`]).
    #[value(name = "filtered_energy")]
    FilteredEnergy,
}

impl Method {
    pub const ALL: [Method; 11] = [
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
        }
    }

    /// `list` plus what every run writes (mean and filtered), in the
    /// canonical order, without repeats.
    pub fn with_core(list: &[Method]) -> Vec<Method> {
        Method::ALL
            .into_iter()
            .filter(|m| matches!(m, Method::Mean | Method::Filtered) || list.contains(m))
            .collect()
    }
}
