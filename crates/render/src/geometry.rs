//! Analytic shapes: spheres (optionally moving linearly in time) and quads
//! (parallelograms). Each can be hit by a ray and sampled as a light.

use std::f64::consts::PI;

use crate::vec3::{Ray, Vec3};

/// Rays start this far from the surface they leave (scene units ~ 1).
pub const EPSILON: f64 = 1e-6;

#[derive(Clone, Debug)]
pub enum Shape {
    /// A sphere whose centre at time t (frames) is `centre + velocity · t`.
    Sphere {
        centre: Vec3,
        radius: f64,
        velocity: Vec3,
    },
    /// The parallelogram `corner + a·edge_u + b·edge_v`, a, b ∈ [0, 1]; its
    /// front side faces `edge_u × edge_v`.
    Quad {
        corner: Vec3,
        edge_u: Vec3,
        edge_v: Vec3,
    },
}

/// A ray–surface intersection; `normal` is the unit outward (front) normal.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub dist: f64,
    pub point: Vec3,
    pub normal: Vec3,
}

impl Shape {
    pub fn sphere(centre: Vec3, radius: f64) -> Shape {
        Shape::Sphere {
            centre,
            radius,
            velocity: Vec3::ZERO,
        }
    }

    pub fn quad(corner: Vec3, edge_u: Vec3, edge_v: Vec3) -> Shape {
        Shape::Quad {
            corner,
            edge_u,
            edge_v,
        }
    }

    /// The nearest hit with distance in (EPSILON, t_max).
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<Hit> {
        match *self {
            Shape::Sphere {
                centre,
                radius,
                velocity,
            } => {
                let c = centre + velocity * ray.time;
                let oc = ray.origin - c;
                let a = ray.dir.length_squared();
                let half_b = oc.dot(ray.dir);
                let cc = oc.length_squared() - radius * radius;
                let disc = half_b * half_b - a * cc;
                if disc < 0.0 {
                    return None;
                }
                let sq = disc.sqrt();
                let mut t = (-half_b - sq) / a;
                if t <= EPSILON {
                    t = (-half_b + sq) / a;
                }
                if t <= EPSILON || t >= t_max {
                    return None;
                }
                let point = ray.at(t);
                Some(Hit {
                    dist: t,
                    point,
                    normal: (point - c) / radius,
                })
            }
            Shape::Quad {
                corner,
                edge_u,
                edge_v,
            } => {
                let n = edge_u.cross(edge_v);
                let denom = n.dot(ray.dir);
                if denom.abs() < 1e-12 {
                    return None;
                }
                let t = n.dot(corner - ray.origin) / denom;
                if t <= EPSILON || t >= t_max {
                    return None;
                }
                let point = ray.at(t);
                let rel = point - corner;
                let nn = n.length_squared();
                let a = rel.cross(edge_v).dot(n) / nn;
                let b = edge_u.cross(rel).dot(n) / nn;
                if !(0.0..=1.0).contains(&a) || !(0.0..=1.0).contains(&b) {
                    return None;
                }
                Some(Hit {
                    dist: t,
                    point,
                    normal: n / nn.sqrt(),
                })
            }
        }
    }

    /// Samples a direction from `from` towards the shape: the direction and
    /// its solid-angle density. `None` when the shape is not visible from
    /// `from` (inside a sphere, behind a one-sided quad).
    pub fn sample_direction(&self, from: Vec3, u: (f64, f64)) -> Option<(Vec3, f64)> {
        match *self {
            Shape::Sphere { centre, radius, .. } => {
                // Uniform in the cone the sphere subtends (PBRT-v4 §6.2.4).
                let axis = centre - from;
                let d2 = axis.length_squared();
                if d2 <= radius * radius {
                    return None;
                }
                let cos_max = (1.0 - radius * radius / d2).sqrt();
                let cos = 1.0 - u.0 * (1.0 - cos_max);
                let sin = (1.0 - cos * cos).max(0.0).sqrt();
                let phi = 2.0 * PI * u.1;
                let local = Vec3 {
                    x: sin * phi.cos(),
                    y: sin * phi.sin(),
                    z: cos,
                };
                Some((
                    local.from_local(axis / d2.sqrt()),
                    1.0 / (2.0 * PI * (1.0 - cos_max)),
                ))
            }
            Shape::Quad {
                corner,
                edge_u,
                edge_v,
            } => {
                let p = corner + edge_u * u.0 + edge_v * u.1;
                let to = p - from;
                let d2 = to.length_squared();
                let dir = to / d2.sqrt();
                let n = edge_u.cross(edge_v);
                let area = n.length();
                let cos_light = -dir.dot(n) / area;
                if cos_light <= 0.0 {
                    return None;
                }
                Some((dir, d2 / (cos_light * area)))
            }
        }
    }

    /// The solid-angle density with which `sample_direction` from `from`
    /// produces the direction that hits this shape at `hit`.
    pub fn direction_pdf(&self, from: Vec3, hit: &Hit) -> f64 {
        match *self {
            Shape::Sphere { centre, radius, .. } => {
                let d2 = (centre - from).length_squared();
                if d2 <= radius * radius {
                    return 0.0;
                }
                let cos_max = (1.0 - radius * radius / d2).sqrt();
                1.0 / (2.0 * PI * (1.0 - cos_max))
            }
            Shape::Quad { edge_u, edge_v, .. } => {
                let to = hit.point - from;
                let d2 = to.length_squared();
                let cos_light = -to.dot(hit.normal) / d2.sqrt();
                if cos_light <= 0.0 {
                    return 0.0;
                }
                d2 / (cos_light * edge_u.cross(edge_v).length())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vec3::v3;

    fn ray(o: Vec3, d: Vec3) -> Ray {
        Ray {
            origin: o,
            dir: d.normalize(),
            time: 0.0,
        }
    }

    #[test]
    fn sphere_hit_from_outside_and_inside() {
        let s = Shape::sphere(v3(0.0, 0.0, 0.0), 1.0);
        let h = s
            .intersect(&ray(v3(0.0, 0.0, -3.0), v3(0.0, 0.0, 1.0)), 1e9)
            .unwrap();
        assert!((h.dist - 2.0).abs() < 1e-12);
        assert!((h.normal.z + 1.0).abs() < 1e-12);
        let h = s
            .intersect(&ray(v3(0.0, 0.0, 0.0), v3(1.0, 0.0, 0.0)), 1e9)
            .unwrap();
        assert!((h.dist - 1.0).abs() < 1e-12);
    }

    #[test]
    fn moving_sphere_follows_time() {
        let s = Shape::Sphere {
            centre: v3(0.0, 0.0, 0.0),
            radius: 0.5,
            velocity: v3(1.0, 0.0, 0.0),
        };
        let mut r = ray(v3(2.0, 0.0, -3.0), v3(0.0, 0.0, 1.0));
        assert!(s.intersect(&r, 1e9).is_none());
        r.time = 2.0;
        assert!(s.intersect(&r, 1e9).is_some());
    }

    #[test]
    fn quad_bounds_and_normal() {
        let q = Shape::quad(v3(0.0, 0.0, 0.0), v3(1.0, 0.0, 0.0), v3(0.0, 1.0, 0.0));
        let h = q
            .intersect(&ray(v3(0.5, 0.5, 1.0), v3(0.0, 0.0, -1.0)), 1e9)
            .unwrap();
        assert!((h.normal.z - 1.0).abs() < 1e-12);
        assert!(
            q.intersect(&ray(v3(1.5, 0.5, 1.0), v3(0.0, 0.0, -1.0)), 1e9)
                .is_none()
        );
    }

    /// The densities integrate to one over the directions that hit the
    /// shape: E[1/pdf] over sampled directions is the solid angle, which we
    /// check against a direct estimate.
    #[test]
    fn direction_pdf_matches_sampling() {
        let shapes = [
            Shape::sphere(v3(0.0, 2.0, 0.0), 0.3),
            Shape::quad(v3(-0.2, 2.0, -0.2), v3(0.4, 0.0, 0.0), v3(0.0, 0.0, 0.4)),
        ];
        let from = v3(0.1, 0.0, 0.05);
        for s in &shapes {
            let mut rng = crate::sampler::Sampler::new(3, 0, 0, 0, 0);
            for _ in 0..100 {
                let (dir, pdf) = s.sample_direction(from, rng.uniform2()).unwrap();
                let r = Ray {
                    origin: from,
                    dir,
                    time: 0.0,
                };
                let hit = s.intersect(&r, 1e9).expect("sampled direction hits");
                let p2 = s.direction_pdf(from, &hit);
                assert!((pdf - p2).abs() <= 1e-9 * pdf, "{pdf} vs {p2}");
            }
        }
    }
}
