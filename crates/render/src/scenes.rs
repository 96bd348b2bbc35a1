//! The scenes, each built to show one effect from the paper. Units: the
//! rooms span x ∈ [−1, 1], y ∈ [0, 2], z ∈ [−1, 1], open towards the camera.
//! Radiance is scaled so that a lit white wall is about 0.3–1: the paper's
//! σ_color = 100 assumes radiance 1 is white (docs/filter.md §1).

use crate::camera::Camera;
use crate::geometry::Shape;
use crate::material::Material;
use crate::scene::{Environment, Primitive, Scene};
use crate::vec3::{Vec3, v3};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneName {
    /// Glass and glossy-metal spheres under a small ceiling light: caustics
    /// seen through diffuse bounces (the paper's Figure 1).
    GlossyRoom,
    /// The same room, every surface Lambertian (Figure 2).
    DiffuseRoom,
    /// A large dim yellow light and a small intense blue one (Figure 4).
    TwoLights,
    /// A ceiling lit only by bounced light (the paper's Sponza roof).
    IndirectRoom,
    /// Glossy objects under a sky with a small sun (the paper's Chess).
    Sky,
    /// The glossy room with a sphere moving across it over the frames.
    Moving,
}

impl std::str::FromStr for SceneName {
    type Err = String;
    fn from_str(s: &str) -> Result<SceneName, String> {
        SceneName::from_name(s).ok_or_else(|| {
            let names: Vec<&str> = SceneName::ALL.iter().map(|s| s.as_str()).collect();
            format!("unknown scene {s:?} (one of {})", names.join(", "))
        })
    }
}

impl std::fmt::Display for SceneName {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl SceneName {
    pub const ALL: [SceneName; 6] = [
        SceneName::GlossyRoom,
        SceneName::DiffuseRoom,
        SceneName::TwoLights,
        SceneName::IndirectRoom,
        SceneName::Sky,
        SceneName::Moving,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            SceneName::GlossyRoom => "glossy-room",
            SceneName::DiffuseRoom => "diffuse-room",
            SceneName::TwoLights => "two-lights",
            SceneName::IndirectRoom => "indirect-room",
            SceneName::Sky => "sky",
            SceneName::Moving => "moving",
        }
    }

    /// The scene called `name` (its [`SceneName::as_str`]).
    pub fn from_name(name: &str) -> Option<SceneName> {
        SceneName::ALL.into_iter().find(|s| s.as_str() == name)
    }

    /// Frames rendered when the user does not say.
    pub fn default_frames(self) -> u32 {
        if self == SceneName::Moving { 8 } else { 1 }
    }

    /// Builds the scene for an animation of `frames` frames.
    pub fn build(self, frames: u32) -> Scene {
        let mut prims = room();
        let camera = room_camera();
        let glass = Material::Dielectric { ior: 1.5 };
        let gold = Material::Conductor {
            f0: v3(1.0, 0.78, 0.34),
            alpha: 0.05,
        };
        let glass_ball = Shape::sphere(v3(-0.42, 0.35, -0.25), 0.35);
        let metal_ball = Shape::sphere(v3(0.45, 0.35, 0.2), 0.35);
        match self {
            SceneName::GlossyRoom | SceneName::Moving => {
                prims.push(ceiling_light(0.25, Vec3::splat(60.0)));
                prims.push(solid(glass_ball, glass));
                prims.push(solid(metal_ball, gold));
                if self == SceneName::Moving {
                    // Crosses the room once over the whole animation.
                    let f = frames.max(1) as f64;
                    prims.push(solid(
                        Shape::Sphere {
                            centre: v3(-0.7, 1.0, 0.3),
                            radius: 0.18,
                            velocity: v3(1.4 / f, 0.0, 0.0),
                        },
                        Material::Mirror {
                            reflectance: Vec3::splat(0.9),
                        },
                    ));
                }
                Scene::new(self.as_str(), camera, prims)
            }
            SceneName::DiffuseRoom => {
                prims.push(ceiling_light(0.25, Vec3::splat(60.0)));
                prims.push(solid(glass_ball, lambert(0.8, 0.8, 0.8)));
                prims.push(solid(metal_ball, lambert(0.8, 0.6, 0.3)));
                Scene::new(self.as_str(), camera, prims)
            }
            SceneName::TwoLights => {
                // The large lamp is a 3 × 3 panel fixture, so next-event
                // estimation picks the blue light for only 1 sample in 10:
                // each pixel sees the blue light in a few samples, which a
                // per-pixel trimmed mean drops, while in joint space they
                // form a dense population (the paper's Figure 4).
                for i in 0..3 {
                    for j in 0..3 {
                        let (x, z) = (-0.6 + 0.4 * i as f64, -0.6 + 0.4 * j as f64);
                        prims.push(Primitive {
                            shape: Shape::quad(
                                v3(x + 0.01, 1.98, z + 0.01),
                                v3(0.38, 0.0, 0.0),
                                v3(0.0, 0.0, 0.38),
                            ),
                            material: Material::Black,
                            emission: v3(1.1, 0.9, 0.35),
                        });
                    }
                }
                prims.push(Primitive {
                    shape: Shape::sphere(v3(0.6, 1.25, -0.55), 0.03),
                    material: Material::Black,
                    emission: v3(10.0, 30.0, 700.0),
                });
                prims.push(solid(glass_ball, glass));
                prims.push(solid(
                    metal_ball,
                    Material::Mirror {
                        reflectance: Vec3::splat(0.95),
                    },
                ));
                Scene::new(self.as_str(), camera, prims)
            }
            SceneName::IndirectRoom => {
                // A bright lamp in a shaft: it lights a patch of floor, and
                // the ceiling sees only light bounced from that patch.
                let (cx, cz, half, bottom) = (0.45, -0.4, 0.15, 1.7);
                prims.push(Primitive {
                    shape: Shape::quad(
                        v3(cx - half, 1.98, cz - half),
                        v3(2.0 * half, 0.0, 0.0),
                        v3(0.0, 0.0, 2.0 * half),
                    ),
                    material: Material::Black,
                    emission: Vec3::splat(200.0),
                });
                let white = lambert(0.75, 0.75, 0.75);
                let depth = v3(0.0, bottom - 2.0, 0.0);
                for (corner, edge) in [
                    (v3(cx - half, 2.0, cz - half), v3(2.0 * half, 0.0, 0.0)),
                    (v3(cx - half, 2.0, cz + half), v3(2.0 * half, 0.0, 0.0)),
                    (v3(cx - half, 2.0, cz - half), v3(0.0, 0.0, 2.0 * half)),
                    (v3(cx + half, 2.0, cz - half), v3(0.0, 0.0, 2.0 * half)),
                ] {
                    prims.push(solid(Shape::quad(corner, edge, depth), white.clone()));
                }
                prims.push(solid(metal_ball, lambert(0.7, 0.7, 0.7)));
                let camera = Camera::look_at(
                    v3(0.0, 0.9, 3.6),
                    v3(0.0, 1.25, 0.0),
                    v3(0.0, 1.0, 0.0),
                    40.0,
                );
                Scene::new(self.as_str(), camera, prims)
            }
            SceneName::Sky => sky(),
        }
    }
}

fn lambert(r: f64, g: f64, b: f64) -> Material {
    Material::Lambert {
        albedo: v3(r, g, b),
    }
}

fn solid(shape: Shape, material: Material) -> Primitive {
    Primitive {
        shape,
        material,
        emission: Vec3::ZERO,
    }
}

fn room_camera() -> Camera {
    Camera::look_at(
        v3(0.0, 1.0, 3.9),
        v3(0.0, 1.0, 0.0),
        v3(0.0, 1.0, 0.0),
        36.0,
    )
}

/// The Cornell-like room: white floor, ceiling and back wall, a red left
/// wall and a green right wall (Cornell box reflectances).
fn room() -> Vec<Primitive> {
    let white = lambert(0.725, 0.71, 0.68);
    vec![
        // floor, ceiling, back
        solid(
            Shape::quad(v3(-1.0, 0.0, -1.0), v3(0.0, 0.0, 2.0), v3(2.0, 0.0, 0.0)),
            white.clone(),
        ),
        solid(
            Shape::quad(v3(-1.0, 2.0, -1.0), v3(2.0, 0.0, 0.0), v3(0.0, 0.0, 2.0)),
            white.clone(),
        ),
        solid(
            Shape::quad(v3(-1.0, 0.0, -1.0), v3(2.0, 0.0, 0.0), v3(0.0, 2.0, 0.0)),
            white,
        ),
        solid(
            Shape::quad(v3(-1.0, 0.0, -1.0), v3(0.0, 2.0, 0.0), v3(0.0, 0.0, 2.0)),
            lambert(0.63, 0.065, 0.05),
        ),
        solid(
            Shape::quad(v3(1.0, 0.0, -1.0), v3(0.0, 0.0, 2.0), v3(0.0, 2.0, 0.0)),
            lambert(0.14, 0.45, 0.091),
        ),
    ]
}

/// A square light of side `side` just below the ceiling, facing down.
fn ceiling_light(side: f64, radiance: Vec3) -> Primitive {
    Primitive {
        shape: Shape::quad(
            v3(-side / 2.0, 1.98, -side / 2.0),
            v3(side, 0.0, 0.0),
            v3(0.0, 0.0, side),
        ),
        material: Material::Black,
        emission: radiance,
    }
}

/// Glossy and specular balls on a ground plane under a sky and a small sun.
fn sky() -> Scene {
    let mut prims = vec![solid(
        Shape::quad(
            v3(-30.0, 0.0, -30.0),
            v3(0.0, 0.0, 60.0),
            v3(60.0, 0.0, 0.0),
        ),
        lambert(0.5, 0.5, 0.5),
    )];
    let balls = [
        (v3(-1.3, 0.4, 0.0), 0.4, Material::Dielectric { ior: 1.5 }),
        (
            v3(-0.35, 0.45, -0.6),
            0.45,
            Material::Conductor {
                f0: Vec3::splat(0.95),
                alpha: 0.02,
            },
        ),
        (
            v3(0.6, 0.4, 0.1),
            0.4,
            Material::Conductor {
                f0: v3(0.95, 0.64, 0.54),
                alpha: 0.15,
            },
        ),
        (
            v3(1.5, 0.35, -0.4),
            0.35,
            Material::Mirror {
                reflectance: Vec3::splat(0.9),
            },
        ),
        (v3(0.2, 0.25, 1.0), 0.25, lambert(0.2, 0.3, 0.6)),
    ];
    for (c, r, m) in balls {
        prims.push(solid(Shape::sphere(c, r), m));
    }
    let camera = Camera::look_at(
        v3(0.0, 1.4, 5.0),
        v3(0.0, 0.4, 0.0),
        v3(0.0, 1.0, 0.0),
        36.0,
    );
    let mut scene = Scene::new(SceneName::Sky.as_str(), camera, prims);
    scene.environment = Some(Environment {
        zenith: v3(0.12, 0.25, 0.6),
        horizon: v3(0.55, 0.65, 0.8),
        ground: v3(0.2, 0.18, 0.15),
        sun_dir: v3(0.5, 0.55, -0.45).normalize(),
        sun_cos_max: 1.0f64.to_radians().cos(),
        sun_radiance: v3(2600.0, 2400.0, 2100.0),
    });
    scene
}
