//! A pinhole camera. Film coordinates follow docs/format.md: x to the right, y
//! down, pixel (i, j) covering [i, i+1) × [j, j+1).

use crate::vec3::{Ray, Vec3};

#[derive(Clone, Debug)]
pub struct Camera {
    pub eye: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    tan_half_fov: f64,
}

impl Camera {
    /// `vfov_degrees` is the full vertical field of view.
    pub fn look_at(eye: Vec3, target: Vec3, up: Vec3, vfov_degrees: f64) -> Camera {
        let forward = (target - eye).normalize();
        let right = forward.cross(up).normalize();
        let up = right.cross(forward);
        Camera {
            eye,
            forward,
            right,
            up,
            tan_half_fov: (vfov_degrees.to_radians() / 2.0).tan(),
        }
    }

    /// The primary ray through film point (x, y) of a width × height film.
    pub fn ray(&self, x: f64, y: f64, width: u32, height: u32, time: f64) -> Ray {
        let (w, h) = (width as f64, height as f64);
        let u = (2.0 * x / w - 1.0) * self.tan_half_fov * w / h;
        let v = (1.0 - 2.0 * y / h) * self.tan_half_fov;
        Ray {
            origin: self.eye,
            dir: (self.forward + self.right * u + self.up * v).normalize(),
            time,
        }
    }
}
