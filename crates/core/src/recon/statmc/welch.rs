//! The Welch t-test two pixels' statistics pass to average each other,
//! and the window's constants: the test's critical values and the
//! spatial Gaussian.

use super::{ALPHA, PATCH, PATCH_ALPHA, RADIUS};

/// z of the standard normal at upper tail `p` (Acklam's rational
/// approximation, relative error below 1.2·10⁻⁹ for p in (0, 0.5]).
fn normal_quantile(p: f64) -> f64 {
    let q = (-2.0 * p.ln()).sqrt();
    let c = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    let d = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    -(((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5])
        / ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0)
}

/// Student's t at upper tail `p` with `df` degrees of freedom (the
/// Cornish-Fisher expansion about the normal; within 1 % for df ≥ 3 at
/// the tails used here).
fn t_quantile(p: f64, df: f64) -> f64 {
    let z = normal_quantile(p);
    let (z3, z5, z7) = (z.powi(3), z.powi(5), z.powi(7));
    z + (z3 + z) / (4.0 * df)
        + (5.0 * z5 + 16.0 * z3 + 3.0 * z) / (96.0 * df * df)
        + (3.0 * z7 + 19.0 * z5 + 17.0 * z3 - 15.0 * z) / (384.0 * df.powi(3))
}

/// χ² at upper tail `p` with `df` degrees of freedom (Wilson and
/// Hilferty's cube of a normal; within 2 % of the tables for df ≥ 3 at
/// p = 0.001).
fn chi2_quantile(p: f64, df: f64) -> f64 {
    let z = normal_quantile(p);
    let v = 2.0 / (9.0 * df);
    df * (1.0 - v + z * v.sqrt()).powi(3)
}

/// Whether two pixels' transformed means ȳ_p, ȳ_q agree on a channel,
/// given s = s_p²/n_p + s_q²/n_q: |ȳ_p − ȳ_q| ≤ t·√s, exactly as written.
/// The squares decide first, without the square root, wherever they are
/// clear of the boundary by far more than the rounding of either form (a
/// relative [`MARGIN`], against about 10⁻¹⁵), and in the normal range
/// ([`TINY`]); the written form decides the rest, so the result is the
/// written form's, bit for bit.
#[inline]
pub(super) fn agree(y_p: f64, y_q: f64, s: f64, crit: f64, crit2: f64) -> bool {
    let d = (y_p - y_q).abs();
    let bound2 = crit2 * s;
    let d2 = d * d;
    let (inside, outside) = (d2 < bound2 * (1.0 - MARGIN), d2 > bound2 * (1.0 + MARGIN));
    // Which side is not predictable; whether either is clear nearly always is.
    if bound2 > TINY && (inside | outside) {
        inside
    } else {
        d <= crit * s.sqrt()
    }
}

/// [`agree`]'s margin around the boundary, relative.
pub(super) const MARGIN: f64 = 1e-12;
/// Below this t²·s the squares may have lost bits: [`agree`] takes the
/// written form.
pub(super) const TINY: f64 = 1e-290;

/// The window's constants.
pub(super) struct Kernel {
    /// t(α/2, ν) for ν = 0 … 2 × the largest n (one entry per ν).
    pub(super) t: Vec<f64>,
    pub(super) t2: Vec<f64>,
    /// The spatial Gaussian at each offset 0 … R along an axis.
    pub(super) spatial: [f64; RADIUS + 1],
    /// The patch test's bound per term, χ²(1 − [`PATCH_ALPHA`], 3m)/3m,
    /// for m = 1 … 9 pairs of the patch (both of two samples or more);
    /// m = 0 never passes.
    pub(super) patch: [f64; PATCH * PATCH + 1],
}

impl Kernel {
    pub(super) fn new(largest: u32) -> Kernel {
        let t: Vec<f64> = (0..=2 * largest as usize)
            .map(|df| t_quantile(ALPHA / 2.0, df.max(1) as f64))
            .collect();
        let t2 = t.iter().map(|t| t * t).collect();
        let sigma = RADIUS as f64 / 2.0;
        let spatial = std::array::from_fn(|d| (-((d * d) as f64) / (2.0 * sigma * sigma)).exp());
        let patch = std::array::from_fn(|m| {
            let df = 3.0 * m.max(1) as f64;
            chi2_quantile(PATCH_ALPHA, df) / df
        });
        Kernel {
            t,
            t2,
            spatial,
            patch,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_against_tables() {
        assert!((normal_quantile(0.0025) - 2.807_033_768).abs() < 1e-6);
        assert!((normal_quantile(0.025) - 1.959_963_985).abs() < 1e-6);
        // t tables: t(0.0025, 30) = 3.0298, t(0.0025, 10) = 3.5814.
        assert!((t_quantile(0.0025, 30.0) - 3.0298).abs() < 2e-3);
        assert!((t_quantile(0.0025, 10.0) - 3.5814).abs() < 2e-2);
        // χ² tables at 0.001: 16.266 (3), 27.877 (9), 55.476 (27).
        for (df, want) in [(3.0, 16.266), (9.0, 27.877), (27.0, 55.476)] {
            let got = chi2_quantile(0.001, df);
            assert!((got / want - 1.0).abs() < 0.02, "{df}: {got}");
        }
    }
}
