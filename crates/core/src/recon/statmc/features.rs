//! The renderer's features in statmc's window: two pixels the test
//! passes average each other with a further weight from the difference
//! of their first-hit albedo and normal, as Sakai et al.'s released code
//! weighs its feature buffers.

/// The renderer's first-hit albedo, and its normal where given, RGB f32
/// a pixel, frame after frame (OIDN's auxiliary images): two compatible
/// pixels p, q average each other with the further weight
/// exp(−|a_p − a_q|²/2σ_a² − |n_p − n_q|²/2σ_n²), as Sakai et al.'s
/// released code weighs its feature buffers. The test cannot tell a
/// texture's or an edge's two sides apart when their radiance differs by
/// less than the samples' noise; the features can.
#[derive(Clone, Copy)]
pub struct Guide<'a> {
    albedo: &'a [f32],
    normal: Option<&'a [f32]>,
}

/// σ_a of the albedo's weight: the authors' released configuration's.
pub const ALBEDO_SD: f64 = 0.02;
/// σ_n of the normal's weight: the authors' released configuration's.
pub const NORMAL_SD: f64 = 0.1;

impl<'a> Guide<'a> {
    /// The features of a film's pixels, three values a pixel each.
    pub fn new(albedo: &'a [f32], normal: Option<&'a [f32]>) -> Guide<'a> {
        debug_assert!(normal.is_none_or(|n| n.len() == albedo.len()));
        Guide { albedo, normal }
    }

    /// The features of the film's pixels `pixels` alone.
    pub(crate) fn of(self, pixels: std::ops::Range<usize>) -> Guide<'a> {
        let at = |v: &'a [f32]| &v[3 * pixels.start..3 * pixels.end];
        Guide {
            albedo: at(self.albedo),
            normal: self.normal.map(at),
        }
    }
}

/// The exponent's factors 1/2σ².
pub(super) const INV_A: f64 = 1.0 / (2.0 * ALBEDO_SD * ALBEDO_SD);
pub(super) const INV_N: f64 = 1.0 / (2.0 * NORMAL_SD * NORMAL_SD);

/// What the window reads of a [`Guide`]: each channel of each feature one
/// array, so that a run's pixels are one slice of each.
pub(super) struct Features {
    pub(super) albedo: [Vec<f32>; 3],
    pub(super) normal: Option<[Vec<f32>; 3]>,
}

impl Features {
    pub(super) fn new(g: Guide) -> Features {
        let planes = |v: &[f32]| -> [Vec<f32>; 3] {
            std::array::from_fn(|c| v.iter().skip(c).step_by(3).copied().collect())
        };
        Features {
            albedo: planes(g.albedo),
            normal: g.normal.map(planes),
        }
    }

    /// Pixels p and q's weight exp(−e), e = |Δa|²/2σ_a² + |Δn|²/2σ_n²
    /// ([`exp_neg`]); 1 where their features are equal.
    #[inline]
    pub(super) fn weight(&self, p: usize, q: usize) -> f64 {
        let sq = |v: &[Vec<f32>; 3]| {
            let d = |c: usize| f64::from(v[c][p]) - f64::from(v[c][q]);
            let (d0, d1, d2) = (d(0), d(1), d(2));
            (d0 * d0 + d1 * d1) + d2 * d2
        };
        let mut e = sq(&self.albedo) * INV_A;
        if let Some(n) = &self.normal {
            e += sq(n) * INV_N;
        }
        exp_neg(e)
    }

    /// `wq[i]` times the weight of pixels p + i and q + i, for each i: in
    /// AVX2 where the CPU has it (the same bits).
    pub(super) fn weigh(&self, p: usize, q: usize, wq: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            return unsafe { super::avx2::weigh(self, p, q, wq) };
        }
        self.weigh_portable(p, q, wq, 0);
    }

    /// [`Self::weigh`] from pair `from` on, one pair at a time.
    pub(super) fn weigh_portable(&self, p: usize, q: usize, wq: &mut [f64], from: usize) {
        for (i, w) in wq.iter_mut().enumerate().skip(from) {
            *w *= self.weight(p + i, q + i);
        }
    }
}

/// Beyond this e the weight is 0 (exp(−708) ≈ 3·10⁻³⁰⁸, the least normal
/// f64's order): 2^k below stays a normal number.
pub(super) const CUTOFF: f64 = 708.0;
pub(super) const LOG2_E: f64 = std::f64::consts::LOG2_E;
/// ln 2 in two parts (fdlibm's): k·LN2_HI is exact for the k used here.
pub(super) const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
pub(super) const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);
/// 1/i!, the Taylor series of exp about 0, to degree 13 (its remainder on
/// |r| ≤ ln 2/2 is below 10⁻¹⁷).
pub(super) const TAYLOR: [f64; 14] = [
    1.0,
    1.0,
    1.0 / 2.0,
    1.0 / 6.0,
    1.0 / 24.0,
    1.0 / 120.0,
    1.0 / 720.0,
    1.0 / 5040.0,
    1.0 / 40320.0,
    1.0 / 362_880.0,
    1.0 / 3_628_800.0,
    1.0 / 39_916_800.0,
    1.0 / 479_001_600.0,
    1.0 / 6_227_020_800.0,
];

/// exp(−e) for e ≥ 0 by operations that AVX2 repeats lane by lane, bit
/// for bit (`avx2::exp_neg`): −e = k·ln 2 + r with k = ⌊−e·log₂e + ½⌋,
/// r reduced in two parts, exp(r) by the Taylor polynomial (Horner), times
/// 2^k; 0 beyond [`CUTOFF`] (and for a NaN). Within a few ulp of `exp`.
#[inline]
pub(super) fn exp_neg(e: f64) -> f64 {
    if e.is_nan() || e > CUTOFF {
        return 0.0;
    }
    let x = 0.0 - e;
    let k = (x * LOG2_E + 0.5).floor();
    let r = (x - k * LN2_HI) - k * LN2_LO;
    let mut y = TAYLOR[13];
    for &c in TAYLOR[..13].iter().rev() {
        y = y * r + c;
    }
    y * f64::from_bits(((k as i64 + 1023) as u64) << 52)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Within 4·10⁻¹⁶ of `exp` across the range, exactly 1 at 0, and 0
    /// beyond the cutoff.
    #[test]
    fn exp_neg_is_exp() {
        assert_eq!(exp_neg(0.0), 1.0);
        assert_eq!(exp_neg(CUTOFF + 0.5), 0.0);
        assert_eq!(exp_neg(f64::NAN), 0.0);
        let mut worst = 0.0f64;
        for i in 0..=1_000_000 {
            let e = CUTOFF * i as f64 / 1e6;
            worst = worst.max((exp_neg(e) / (-e).exp() - 1.0).abs());
        }
        assert!(worst < 4e-16, "{worst}");
    }

    /// The vector weights are the pair-by-pair weights, bit for bit, on
    /// runs of any length, with and without normals, from equal features
    /// to far ones.
    #[test]
    fn the_vector_weights_are_the_portable_weights() {
        let mut unit = crate::synth::test_units(13);
        let (px, mut partial) = (300, 0);
        for trial in 0..200 {
            let levels = [0.2f32, 0.2, 0.21, 0.5, 0.9, -0.3];
            let mut plane = || -> Vec<f32> {
                (0..3 * px)
                    .map(|_| levels[(unit() * 6.0) as usize])
                    .collect()
            };
            let (albedo, normal) = (plane(), plane());
            let f = Features::new(Guide::new(&albedo, (trial % 2 == 0).then_some(&normal[..])));
            let len = 1 + trial % 130;
            let start: Vec<f64> = (0..len).map(|i| [0.0, 1.0, 7.5][i % 3]).collect();
            let (mut fast, mut slow) = (start.clone(), start.clone());
            f.weigh(5, 160, &mut fast);
            f.weigh_portable(5, 160, &mut slow, 0);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&fast), bits(&slow), "trial {trial}");
            partial += slow
                .iter()
                .zip(&start)
                .filter(|(w, s)| 0.0 < **w && w < s)
                .count();
        }
        // Weights strictly between 0 and 1 were made, not only 0 and 1.
        assert!(partial > 1000, "{partial}");
    }
}
