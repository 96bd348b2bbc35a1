//! The BSDFs the scenes need: Lambertian, GGX rough conductor, smooth
//! dielectric and mirror. Directions point away from the surface; `n` is
//! the unit geometric normal (outward for closed shapes).

use std::f64::consts::PI;

use crate::vec3::{Vec3, v3};

#[derive(Clone, Debug)]
pub enum Material {
    Lambert {
        albedo: Vec3,
    },
    /// Microfacet conductor: GGX distribution (Walter et al. 2007) with
    /// roughness `alpha`, separable Smith masking, Schlick's Fresnel from
    /// the normal-incidence reflectance `f0`.
    Conductor {
        f0: Vec3,
        alpha: f64,
    },
    /// A smooth dielectric interface with index of refraction `ior`.
    Dielectric {
        ior: f64,
    },
    Mirror {
        reflectance: Vec3,
    },
    /// An emitter's surface: absorbs everything it does not emit.
    Black,
}

impl Material {
    /// The first-hit albedo a denoiser takes (OIDN's definition): the
    /// diffuse colour, a conductor's normal-incidence reflectance, a
    /// mirror's reflectance, 1 for glass, 0 for an emitter's surface.
    pub fn albedo(&self) -> Vec3 {
        match *self {
            Material::Lambert { albedo } => albedo,
            Material::Conductor { f0, .. } => f0,
            Material::Dielectric { .. } => Vec3::ONE,
            Material::Mirror { reflectance } => reflectance,
            Material::Black => Vec3::ZERO,
        }
    }
}

/// A sampled incident direction. `weight` = f · |cos θ_i| / pdf.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    pub wi: Vec3,
    pub weight: Vec3,
    /// Solid-angle density; meaningless when `delta`.
    pub pdf: f64,
    pub delta: bool,
}

impl Material {
    /// True when the BSDF is a Dirac delta, so light sampling cannot help.
    pub fn is_delta(&self) -> bool {
        matches!(self, Material::Dielectric { .. } | Material::Mirror { .. })
    }

    /// f(wo, wi) · |cos θ_i| and the density of sampling wi, for non-delta
    /// materials.
    pub fn eval(&self, wo: Vec3, wi: Vec3, n: Vec3) -> (Vec3, f64) {
        let n = if wo.dot(n) < 0.0 { -n } else { n };
        let (cos_o, cos_i) = (wo.dot(n), wi.dot(n));
        if cos_o <= 0.0 || cos_i <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        match *self {
            Material::Lambert { albedo } => (albedo * (cos_i / PI), cos_i / PI),
            Material::Conductor { f0, alpha } => {
                let h = (wo + wi).normalize();
                let (cos_h, o_h) = (h.dot(n), wo.dot(h));
                let d = ggx_d(cos_h, alpha);
                let g = smith_g1(cos_o, alpha) * smith_g1(cos_i, alpha);
                let f = schlick(f0, o_h);
                // f = D G F / (4 cos_o cos_i); pdf = D cos_h / (4 (wo·h)).
                (f * (d * g / (4.0 * cos_o)), d * cos_h / (4.0 * o_h))
            }
            _ => (Vec3::ZERO, 0.0),
        }
    }

    /// Samples wi given wo; `None` when the path is absorbed.
    pub fn sample(&self, wo: Vec3, n: Vec3, u: (f64, f64), u_lobe: f64) -> Option<BsdfSample> {
        match *self {
            Material::Lambert { albedo } => {
                let n = if wo.dot(n) < 0.0 { -n } else { n };
                // Cosine-weighted hemisphere (Malley's method).
                let r = u.0.sqrt();
                let phi = 2.0 * PI * u.1;
                let z = (1.0 - u.0).max(0.0).sqrt();
                let wi = v3(r * phi.cos(), r * phi.sin(), z).from_local(n);
                Some(BsdfSample {
                    wi,
                    weight: albedo,
                    pdf: z / PI,
                    delta: false,
                })
            }
            Material::Conductor { f0, alpha } => {
                let nf = if wo.dot(n) < 0.0 { -n } else { n };
                // Half vector from D(h) cos θ_h (Walter et al. 2007, eq. 35–36).
                let a2 = alpha * alpha;
                let cos2 = (1.0 - u.0) / (u.0 * (a2 - 1.0) + 1.0);
                let cos_h = cos2.sqrt();
                let sin_h = (1.0 - cos2).max(0.0).sqrt();
                let phi = 2.0 * PI * u.1;
                let h = v3(sin_h * phi.cos(), sin_h * phi.sin(), cos_h).from_local(nf);
                let o_h = wo.dot(h);
                if o_h <= 0.0 {
                    return None;
                }
                let wi = wo.reflect(h);
                let (cos_o, cos_i) = (wo.dot(nf), wi.dot(nf));
                if cos_i <= 0.0 || cos_o <= 0.0 {
                    return None;
                }
                let g = smith_g1(cos_o, alpha) * smith_g1(cos_i, alpha);
                // weight = F G (wo·h) / (cos_o cos_h): D cancels.
                Some(BsdfSample {
                    wi,
                    weight: schlick(f0, o_h) * (g * o_h / (cos_o * cos_h)),
                    pdf: ggx_d(cos_h, alpha) * cos_h / (4.0 * o_h),
                    delta: false,
                })
            }
            Material::Mirror { reflectance } => {
                let nf = if wo.dot(n) < 0.0 { -n } else { n };
                Some(BsdfSample {
                    wi: wo.reflect(nf),
                    weight: reflectance,
                    pdf: 1.0,
                    delta: true,
                })
            }
            Material::Dielectric { ior } => {
                let cos_o = wo.dot(n);
                let (eta, nf, cos_o) = if cos_o > 0.0 {
                    (1.0 / ior, n, cos_o)
                } else {
                    (ior, -n, -cos_o)
                };
                let f = fresnel_dielectric(cos_o, eta);
                let wi = if u_lobe < f {
                    wo.reflect(nf)
                } else {
                    // Snell: eta = n_outside / n_inside along the path.
                    let sin2_t = eta * eta * (1.0 - cos_o * cos_o);
                    let cos_t = (1.0 - sin2_t).sqrt();
                    -wo * eta + nf * (eta * cos_o - cos_t)
                };
                // Radiance scaling by eta² is left out: it cancels on
                // closed paths that leave the glass again.
                Some(BsdfSample {
                    wi,
                    weight: Vec3::ONE,
                    pdf: 1.0,
                    delta: true,
                })
            }
            Material::Black => None,
        }
    }
}

fn ggx_d(cos_h: f64, alpha: f64) -> f64 {
    let a2 = alpha * alpha;
    let t = cos_h * cos_h * (a2 - 1.0) + 1.0;
    a2 / (PI * t * t)
}

fn smith_g1(cos: f64, alpha: f64) -> f64 {
    let a2 = alpha * alpha;
    2.0 * cos / (cos + (a2 + (1.0 - a2) * cos * cos).sqrt())
}

fn schlick(f0: Vec3, cos: f64) -> Vec3 {
    let m = (1.0 - cos).clamp(0.0, 1.0).powi(5);
    f0 + (Vec3::ONE - f0) * m
}

/// Unpolarised Fresnel reflectance; `eta` = n_incident / n_transmitted.
/// Returns 1 under total internal reflection.
fn fresnel_dielectric(cos_i: f64, eta: f64) -> f64 {
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (rs * rs + rp * rp)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::Sampler;

    /// Sampling and evaluation agree: for sampled wi, weight = eval / pdf.
    #[test]
    fn sample_weight_matches_eval_over_pdf() {
        let n = v3(0.0, 0.0, 1.0);
        let wo = v3(0.3, -0.2, 0.9).normalize();
        let mats = [
            Material::Lambert {
                albedo: v3(0.5, 0.6, 0.7),
            },
            Material::Conductor {
                f0: v3(0.9, 0.6, 0.3),
                alpha: 0.2,
            },
        ];
        for m in &mats {
            let mut rng = Sampler::new(1, 0, 0, 0, 0);
            for _ in 0..200 {
                let Some(s) = m.sample(wo, n, rng.uniform2(), rng.uniform()) else {
                    continue;
                };
                let (f, pdf) = m.eval(wo, s.wi, n);
                assert!((pdf - s.pdf).abs() <= 1e-9 * pdf.max(1.0));
                for c in 0..3 {
                    assert!((f[c] / pdf - s.weight[c]).abs() <= 1e-9 * s.weight[c].max(1.0));
                }
            }
        }
    }

    /// The directional albedo ∫ f cos θ_i dω_i: by importance sampling it
    /// must match a brute-force quadrature of `eval` over the hemisphere.
    /// A Lambertian with albedo 1 reflects everything; the single-scattering
    /// GGX conductor with f0 = 1 loses some energy, more when rougher.
    #[test]
    fn albedo_by_sampling_matches_quadrature() {
        let n = v3(0.0, 0.0, 1.0);
        let wo = v3(0.0, 0.6, 0.8);
        let sampled = |m: &Material| {
            let mut rng = Sampler::new(2, 0, 0, 0, 0);
            let k = 400_000;
            (0..k)
                .filter_map(|_| m.sample(wo, n, rng.uniform2(), rng.uniform()))
                .map(|s| s.weight.x)
                .sum::<f64>()
                / k as f64
        };
        let quadrature = |m: &Material| {
            // Midpoint rule in (cos θ, φ): dω = d(cos θ) dφ.
            let (nt, np) = (2000, 400);
            let mut sum = 0.0;
            for a in 0..nt {
                let z = (a as f64 + 0.5) / nt as f64;
                let r = (1.0 - z * z).sqrt();
                for b in 0..np {
                    let phi = 2.0 * PI * (b as f64 + 0.5) / np as f64;
                    let wi = v3(r * phi.cos(), r * phi.sin(), z);
                    sum += m.eval(wo, wi, n).0.x;
                }
            }
            sum * 2.0 * PI / (nt * np) as f64
        };
        let lambert = Material::Lambert { albedo: Vec3::ONE };
        assert!((sampled(&lambert) - 1.0).abs() < 1e-12);
        assert!((quadrature(&lambert) - 1.0).abs() < 1e-3);
        let mut previous = 1.0;
        for alpha in [0.1, 0.3, 0.6] {
            let m = Material::Conductor {
                f0: Vec3::ONE,
                alpha,
            };
            let (s, q) = (sampled(&m), quadrature(&m));
            assert!(
                (s - q).abs() < 0.01,
                "alpha {alpha}: sampled {s}, quadrature {q}"
            );
            assert!(q < previous && q > 0.5, "alpha {alpha}: albedo {q}");
            previous = q;
        }
    }

    #[test]
    fn dielectric_refracts_by_snell() {
        let n = v3(0.0, 0.0, 1.0);
        let wo = v3(0.6, 0.0, 0.8);
        let glass = Material::Dielectric { ior: 1.5 };
        // u_lobe = 1 always transmits.
        let s = glass.sample(wo, n, (0.0, 0.0), 1.0).unwrap();
        let sin_t = (s.wi.x * s.wi.x + s.wi.y * s.wi.y).sqrt();
        assert!((sin_t * 1.5 - 0.6).abs() < 1e-12);
        assert!(s.wi.z < 0.0);
        assert!((s.wi.length() - 1.0).abs() < 1e-12);
    }
}
