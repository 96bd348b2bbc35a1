use super::features::{CUTOFF, Features, INV_A, INV_N, LN2_HI, LN2_LO, LOG2_E, TAYLOR};
use super::fields::Fields;
use super::run::{Pairs, pair_weights_portable};
use super::welch::{Kernel, MARGIN, TINY};
use super::{LAMBDA, Stats};
use std::arch::x86_64::*;

/// [`Stats::add`], each channel a lane: the same operations in the
/// same order (no fused multiply-add), each correctly rounded, so
/// the same bits; the divisions and square roots, which bound the
/// fold, three at a time.
#[target_feature(enable = "avx2")]
pub(super) fn add(s: &mut Stats, x: [f64; 3]) {
    let lanes = |a: [f64; 3]| _mm256_set_pd(0.0, a[2], a[1], a[0]);
    let store = |v: __m256d, a: &mut [f64; 3]| {
        let mut out = [0.0; 4];
        // SAFETY: `out` holds four f64.
        unsafe { _mm256_storeu_pd(out.as_mut_ptr(), v) };
        a.copy_from_slice(&out[..3]);
    };
    s.x.n += 1;
    let n = _mm256_set1_pd(s.x.n as f64);
    let x = lanes(x);
    // The moments of x.
    let mean = lanes(s.x.mean);
    let d = _mm256_sub_pd(x, mean);
    let mean = _mm256_add_pd(mean, _mm256_div_pd(d, n));
    let m2 = _mm256_add_pd(lanes(s.x.m2), _mm256_mul_pd(d, _mm256_sub_pd(x, mean)));
    store(mean, &mut s.x.mean);
    store(m2, &mut s.x.m2);
    // Those of its Box-Cox transform (√x⁺ − 1)/λ: max of two zeros is
    // either, whose square roots give the same y.
    let root = _mm256_sqrt_pd(_mm256_max_pd(x, _mm256_setzero_pd()));
    let y = _mm256_div_pd(
        _mm256_sub_pd(root, _mm256_set1_pd(1.0)),
        _mm256_set1_pd(LAMBDA),
    );
    let y_mean = lanes(s.y_mean);
    let d = _mm256_sub_pd(y, y_mean);
    let y_mean = _mm256_add_pd(y_mean, _mm256_div_pd(d, n));
    let y_m2 = _mm256_add_pd(lanes(s.y_m2), _mm256_mul_pd(d, _mm256_sub_pd(y, y_mean)));
    store(y_mean, &mut s.y_mean);
    store(y_m2, &mut s.y_m2);
}

#[target_feature(enable = "avx2")]
pub(super) fn pair_weights(f: &Fields, k: &Kernel, pairs: &Pairs, wq: &mut [f64]) -> bool {
    let (len, Pairs { ws, p, q }) = (wq.len(), *pairs);
    // Sample counts index t² as 32-bit integers.
    let last = k.t2.len() - 1;
    if last > i32::MAX as usize {
        return pair_weights_portable(f, k, pairs, wq, 0);
    }
    let (fields, end) = (Slices::new(f, p, q, len), len / 4 * 4);
    let mut undecided = _mm256_setzero_pd();
    for i in (0..end).step_by(4) {
        // SAFETY: i + 4 ≤ len, the length of every slice read.
        let (w, u) = unsafe { four(&fields, k, ws, last as i32, i) };
        wq[i..i + 4].copy_from_slice(&w);
        undecided = _mm256_or_pd(undecided, u);
    }
    let tail = pair_weights_portable(f, k, pairs, wq, end);
    _mm256_movemask_pd(undecided) != 0 || tail
}

/// The run's fields: p's and q's, `len` pixels each.
struct Slices<'a> {
    np: &'a [u32],
    nq: &'a [u32],
    sp: &'a [f64],
    sq: &'a [f64],
    lp: &'a [f64],
    lq: &'a [f64],
    yp: [&'a [f64]; 3],
    yq: [&'a [f64]; 3],
    ep: [&'a [f64]; 3],
    eq: [&'a [f64]; 3],
}

impl<'a> Slices<'a> {
    fn new(f: &'a Fields, p: usize, q: usize, len: usize) -> Slices<'a> {
        let (p, q) = (p..p + len, q..q + len);
        Slices {
            np: &f.n[p.clone()],
            nq: &f.n[q.clone()],
            sp: &f.spread[p.clone()],
            sq: &f.spread[q.clone()],
            lp: &f.limit[p.clone()],
            lq: &f.limit[q.clone()],
            yp: std::array::from_fn(|c| &f.y_mean[c][p.clone()]),
            yq: std::array::from_fn(|c| &f.y_mean[c][q.clone()]),
            ep: std::array::from_fn(|c| &f.se2[c][p.clone()]),
            eq: std::array::from_fn(|c| &f.se2[c][q.clone()]),
        }
    }
}

/// Pairs i … i + 3: their weights, and a mask of those undecided.
///
/// # Safety
/// AVX2, and i + 4 ≤ the slices' length.
#[target_feature(enable = "avx2")]
unsafe fn four(s: &Slices, k: &Kernel, ws: f64, last: i32, i: usize) -> ([f64; 4], __m256d) {
    // SAFETY: every load reads 4 elements from i, within the slices.
    unsafe {
        let ld = |v: &[f64]| _mm256_loadu_pd(v.as_ptr().add(i));
        let ldn = |v: &[u32]| _mm_loadu_si128(v.as_ptr().add(i).cast());
        let (np, nq) = (ldn(s.np), ldn(s.nq));
        // Each 32-bit comparison widened to a 64-bit lane's mask.
        let two_each = _mm_and_si128(
            _mm_cmpgt_epi32(np, _mm_set1_epi32(1)),
            _mm_cmpgt_epi32(nq, _mm_set1_epi32(1)),
        );
        let mut valid = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(two_each));
        let noisier_q = _mm256_cmp_pd::<_CMP_GT_OQ>(ld(s.sq), ld(s.lp));
        let noisier_p = _mm256_cmp_pd::<_CMP_GT_OQ>(ld(s.sp), ld(s.lq));
        valid = _mm256_andnot_pd(_mm256_or_pd(noisier_q, noisier_p), valid);
        let df = _mm_sub_epi32(_mm_add_epi32(np, nq), _mm_set1_epi32(2));
        let df = _mm_min_epi32(_mm_max_epi32(df, _mm_setzero_si128()), _mm_set1_epi32(last));
        let crit2 = _mm256_i32gather_pd::<8>(k.t2.as_ptr(), df);
        let (below, above) = (_mm256_set1_pd(1.0 - MARGIN), _mm256_set1_pd(1.0 + MARGIN));
        let (zero, tiny) = (_mm256_setzero_pd(), _mm256_set1_pd(TINY));
        let sign = _mm256_set1_pd(-0.0);
        let mut same = valid;
        let mut undecided = zero;
        for c in 0..3 {
            let d = _mm256_andnot_pd(sign, _mm256_sub_pd(ld(s.yp[c]), ld(s.yq[c])));
            let sum = _mm256_add_pd(ld(s.ep[c]), ld(s.eq[c]));
            let bound2 = _mm256_mul_pd(crit2, sum);
            let d2 = _mm256_mul_pd(d, d);
            let inside = _mm256_cmp_pd::<_CMP_LT_OQ>(d2, _mm256_mul_pd(bound2, below));
            let outside = _mm256_cmp_pd::<_CMP_GT_OQ>(d2, _mm256_mul_pd(bound2, above));
            let normal = _mm256_cmp_pd::<_CMP_GT_OQ>(bound2, tiny);
            let clear = _mm256_and_pd(normal, _mm256_or_pd(inside, outside));
            let s_zero = _mm256_cmp_pd::<_CMP_EQ_OQ>(sum, zero);
            let d_zero = _mm256_cmp_pd::<_CMP_LE_OQ>(d, zero);
            let agree = _mm256_or_pd(
                _mm256_and_pd(clear, inside),
                _mm256_andnot_pd(clear, _mm256_and_pd(s_zero, d_zero)),
            );
            same = _mm256_and_pd(same, agree);
            let open = _mm256_andnot_pd(_mm256_or_pd(clear, s_zero), valid);
            undecided = _mm256_or_pd(undecided, open);
        }
        let n = _mm256_cvtepi32_pd(nq);
        let one = _mm256_and_pd(same, _mm256_set1_pd(1.0));
        let w = _mm256_mul_pd(_mm256_mul_pd(_mm256_set1_pd(ws), n), one);
        let mut out = [0.0; 4];
        _mm256_storeu_pd(out.as_mut_ptr(), w);
        (out, undecided)
    }
}

/// [`Features::weigh`] four pairs at a time: the same operations as
/// [`Features::weight`] and [`exp_neg`](super::features::exp_neg), lane
/// by lane, in the same order (no fused multiply-add), so the same bits.
#[target_feature(enable = "avx2")]
pub(super) fn weigh(f: &Features, p: usize, q: usize, wq: &mut [f64]) {
    let len = wq.len();
    let end = len / 4 * 4;
    // The lanes of pixels at..at + 4 of one channel, in f64 (exact).
    let load = |v: &[f32], at: usize| {
        let v = &v[at..at + 4];
        // SAFETY: `v` holds four f32.
        _mm256_cvtps_pd(unsafe { _mm_loadu_ps(v.as_ptr()) })
    };
    let sq = |v: &[Vec<f32>; 3], i: usize| {
        let d = |c: usize| _mm256_sub_pd(load(&v[c], p + i), load(&v[c], q + i));
        let (d0, d1, d2) = (d(0), d(1), d(2));
        let s01 = _mm256_add_pd(_mm256_mul_pd(d0, d0), _mm256_mul_pd(d1, d1));
        _mm256_add_pd(s01, _mm256_mul_pd(d2, d2))
    };
    for i in (0..end).step_by(4) {
        let mut e = _mm256_mul_pd(sq(&f.albedo, i), _mm256_set1_pd(INV_A));
        if let Some(n) = &f.normal {
            e = _mm256_add_pd(e, _mm256_mul_pd(sq(n, i), _mm256_set1_pd(INV_N)));
        }
        let w = exp_neg(e);
        let out = &mut wq[i..i + 4];
        // SAFETY: `out` holds four f64.
        unsafe {
            let v = _mm256_loadu_pd(out.as_ptr());
            _mm256_storeu_pd(out.as_mut_ptr(), _mm256_mul_pd(v, w));
        }
    }
    f.weigh_portable(p, q, wq, end);
}

/// [`super::features::exp_neg`] in each lane.
#[target_feature(enable = "avx2")]
fn exp_neg(e: __m256d) -> __m256d {
    let set = _mm256_set1_pd;
    // All ones where e ≤ CUTOFF (false for a NaN); e held there, so that
    // 2^k stays in range in every lane.
    let inside = _mm256_cmp_pd::<_CMP_LE_OQ>(e, set(CUTOFF));
    let e = _mm256_min_pd(e, set(CUTOFF));
    let x = _mm256_sub_pd(_mm256_setzero_pd(), e);
    let k = _mm256_floor_pd(_mm256_add_pd(_mm256_mul_pd(x, set(LOG2_E)), set(0.5)));
    let r = _mm256_sub_pd(
        _mm256_sub_pd(x, _mm256_mul_pd(k, set(LN2_HI))),
        _mm256_mul_pd(k, set(LN2_LO)),
    );
    let mut y = set(TAYLOR[13]);
    for &c in TAYLOR[..13].iter().rev() {
        y = _mm256_add_pd(_mm256_mul_pd(y, r), set(c));
    }
    // 2^k from k's bits: (k + 1023) << 52.
    let k = _mm_add_epi32(_mm256_cvtpd_epi32(k), _mm_set1_epi32(1023));
    let scale = _mm256_castsi256_pd(_mm256_slli_epi64::<52>(_mm256_cvtepi32_epi64(k)));
    _mm256_and_pd(_mm256_mul_pd(y, scale), inside)
}
