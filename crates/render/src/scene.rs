//! A scene: a camera, primitives (shape + material + emission), and an
//! optional environment. Lights are the emissive primitives plus the
//! environment; next-event estimation picks one uniformly.

use std::f64::consts::PI;

use crate::camera::Camera;
use crate::geometry::{Hit, Shape};
use crate::material::Material;
use crate::vec3::{Ray, Vec3};

#[derive(Clone, Debug)]
pub struct Primitive {
    pub shape: Shape,
    pub material: Material,
    /// Emitted radiance (front side only for quads).
    pub emission: Vec3,
}

/// A sky gradient with a small sun disc.
#[derive(Clone, Debug)]
pub struct Environment {
    pub zenith: Vec3,
    pub horizon: Vec3,
    pub ground: Vec3,
    /// Unit direction towards the sun.
    pub sun_dir: Vec3,
    pub sun_cos_max: f64,
    pub sun_radiance: Vec3,
}

/// Probability that environment sampling aims at the sun.
const SUN_PROBABILITY: f64 = 0.5;

impl Environment {
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        let up = dir.y;
        let sky = if up >= 0.0 {
            self.horizon + (self.zenith - self.horizon) * up.sqrt()
        } else {
            self.ground
        };
        if dir.dot(self.sun_dir) >= self.sun_cos_max {
            sky + self.sun_radiance
        } else {
            sky
        }
    }

    fn sun_solid_angle(&self) -> f64 {
        2.0 * PI * (1.0 - self.sun_cos_max)
    }

    /// A mixture: the sun's cone with probability SUN_PROBABILITY, else the
    /// uniform sphere, so every direction with radiance has density > 0.
    pub fn sample(&self, u: (f64, f64), u_pick: f64) -> (Vec3, f64) {
        let dir = if u_pick < SUN_PROBABILITY {
            let cos = 1.0 - u.0 * (1.0 - self.sun_cos_max);
            let sin = (1.0 - cos * cos).max(0.0).sqrt();
            let phi = 2.0 * PI * u.1;
            Vec3 {
                x: sin * phi.cos(),
                y: sin * phi.sin(),
                z: cos,
            }
            .from_local(self.sun_dir)
        } else {
            let z = 1.0 - 2.0 * u.0;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = 2.0 * PI * u.1;
            Vec3 {
                x: r * phi.cos(),
                y: r * phi.sin(),
                z,
            }
        };
        (dir, self.pdf(dir))
    }

    pub fn pdf(&self, dir: Vec3) -> f64 {
        let sun = if dir.dot(self.sun_dir) >= self.sun_cos_max {
            SUN_PROBABILITY / self.sun_solid_angle()
        } else {
            0.0
        };
        sun + (1.0 - SUN_PROBABILITY) / (4.0 * PI)
    }
}

#[derive(Clone, Debug)]
pub struct Scene {
    pub name: String,
    pub camera: Camera,
    pub primitives: Vec<Primitive>,
    pub environment: Option<Environment>,
    /// Indices of emissive primitives.
    pub lights: Vec<usize>,
    pub max_depth: u32,
}

/// The light NEE picked: a primitive or the environment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightRef {
    Primitive(usize),
    Environment,
}

impl Scene {
    pub fn new(name: &str, camera: Camera, primitives: Vec<Primitive>) -> Scene {
        let lights = (0..primitives.len())
            .filter(|&i| !primitives[i].emission.is_black())
            .collect();
        Scene {
            name: name.to_string(),
            camera,
            primitives,
            environment: None,
            lights,
            max_depth: 8,
        }
    }

    pub fn light_count(&self) -> usize {
        self.lights.len() + self.environment.is_some() as usize
    }

    pub fn light(&self, n: usize) -> LightRef {
        match self.lights.get(n) {
            Some(&i) => LightRef::Primitive(i),
            None => LightRef::Environment,
        }
    }

    /// The nearest hit and the index of the primitive hit.
    pub fn intersect(&self, ray: &Ray) -> Option<(Hit, usize)> {
        let mut best: Option<(Hit, usize)> = None;
        let mut t_max = f64::INFINITY;
        for (i, p) in self.primitives.iter().enumerate() {
            if let Some(h) = p.shape.intersect(ray, t_max) {
                t_max = h.dist;
                best = Some((h, i));
            }
        }
        best
    }

    /// Radiance emitted by primitive `i` at `hit` towards `-dir`.
    pub fn emitted(&self, i: usize, hit: &Hit, dir: Vec3) -> Vec3 {
        let p = &self.primitives[i];
        match p.shape {
            Shape::Quad { .. } if dir.dot(hit.normal) >= 0.0 => Vec3::ZERO,
            _ => p.emission,
        }
    }
}
