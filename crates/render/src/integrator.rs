//! Unidirectional path tracing with next-event estimation, multiple
//! importance sampling (Veach 1997, the power heuristic, eq. 9.13),
//! Russian roulette and a maximum depth.

use crate::geometry::EPSILON;
use crate::sampler::Sampler;
use crate::scene::{LightRef, Scene};
use crate::vec3::{Ray, Vec3};

/// Depth after which Russian roulette may end a path.
const ROULETTE_DEPTH: u32 = 3;

/// Veach's power heuristic with β = 2 for one sample from each strategy.
fn power_heuristic(pdf_a: f64, pdf_b: f64) -> f64 {
    let (a, b) = (pdf_a * pdf_a, pdf_b * pdf_b);
    if a + b == 0.0 { 0.0 } else { a / (a + b) }
}

/// An estimate of the radiance arriving along `ray` (towards its origin).
pub fn radiance(scene: &Scene, mut ray: Ray, rng: &mut Sampler) -> Vec3 {
    let mut l = Vec3::ZERO;
    let mut beta = Vec3::ONE;
    // The previous vertex: its position and BSDF density for the current
    // direction, or None after the camera or a delta bounce (no MIS: light
    // sampling could not have produced this direction).
    let mut prev: Option<(Vec3, f64)> = None;
    let light_pick = 1.0 / scene.light_count().max(1) as f64;
    for depth in 0..scene.max_depth {
        let Some((hit, id)) = scene.intersect(&ray) else {
            if let Some(env) = &scene.environment {
                let w = prev.map_or(1.0, |(_, pdf)| {
                    power_heuristic(pdf, light_pick * env.pdf(ray.dir))
                });
                l += beta * env.radiance(ray.dir) * w;
            }
            break;
        };
        let prim = &scene.primitives[id];
        let le = scene.emitted(id, &hit, ray.dir);
        if !le.is_black() {
            let w = prev.map_or(1.0, |(from, pdf)| {
                power_heuristic(pdf, light_pick * prim.shape.direction_pdf(from, &hit))
            });
            l += beta * le * w;
        }
        let wo = -ray.dir;
        let material = &prim.material;
        if !material.is_delta() && scene.light_count() > 0 {
            l += beta * next_event(scene, &hit, wo, id, ray.time, light_pick, rng);
        }
        let Some(s) = material.sample(wo, hit.normal, rng.uniform2(), rng.uniform()) else {
            break;
        };
        beta = beta * s.weight;
        prev = if s.delta {
            None
        } else {
            Some((hit.point, s.pdf))
        };
        if depth >= ROULETTE_DEPTH {
            let q = beta.max_component().min(0.95);
            if rng.uniform() >= q {
                break;
            }
            beta = beta / q;
        }
        ray = Ray {
            origin: hit.point,
            dir: s.wi,
            time: ray.time,
        };
    }
    l
}

/// The first surface `ray` hits: its material's albedo and its shading
/// normal, a denoiser's auxiliary features; zeros where it hits nothing.
pub fn first_hit(scene: &Scene, ray: &Ray) -> (Vec3, Vec3) {
    match scene.intersect(ray) {
        Some((hit, id)) => (scene.primitives[id].material.albedo(), hit.normal),
        None => (Vec3::ZERO, Vec3::ZERO),
    }
}

/// One light sample with its MIS weight against BSDF sampling.
fn next_event(
    scene: &Scene,
    hit: &crate::geometry::Hit,
    wo: Vec3,
    id: usize,
    time: f64,
    light_pick: f64,
    rng: &mut Sampler,
) -> Vec3 {
    let n = scene.light_count();
    let pick = ((rng.uniform() * n as f64) as usize).min(n - 1);
    let (u, u_pick) = (rng.uniform2(), rng.uniform());
    let light = scene.light(pick);
    let sampled = match light {
        LightRef::Primitive(i) => scene.primitives[i].shape.sample_direction(hit.point, u),
        LightRef::Environment => scene.environment.as_ref().map(|env| env.sample(u, u_pick)),
    };
    let Some((wi, pdf)) = sampled else {
        return Vec3::ZERO;
    };
    if pdf <= 0.0 || !pdf.is_finite() {
        return Vec3::ZERO;
    }
    let material = &scene.primitives[id].material;
    let (f, bsdf_pdf) = material.eval(wo, wi, hit.normal);
    if f.is_black() {
        return Vec3::ZERO;
    }
    let shadow = Ray {
        origin: hit.point + wi * EPSILON,
        dir: wi,
        time,
    };
    let le = match (light, scene.intersect(&shadow)) {
        (LightRef::Primitive(i), Some((h, j))) if i == j => scene.emitted(j, &h, wi),
        (LightRef::Environment, None) => scene
            .environment
            .as_ref()
            .map_or(Vec3::ZERO, |env| env.radiance(wi)),
        _ => Vec3::ZERO,
    };
    let light_pdf = light_pick * pdf;
    f * le * (power_heuristic(light_pdf, bsdf_pdf) / light_pdf)
}
