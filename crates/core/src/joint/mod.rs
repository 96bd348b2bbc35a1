//! The joint image–colour(–time) space of docs/filter.md §1, where the density filter
//! measures distances.

pub mod hdr;
pub mod lab;
pub mod white;

use crate::dump::{Header, Record};

/// The colour coordinates of the joint space (docs/filter.md §1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ColorSpace {
    /// CIELAB (F2), the paper's.
    #[default]
    Cielab,
    /// CIELAB continued logarithmically above the white (F2a).
    Loglab,
    /// Log lightness with CIELUV chroma capped at the white (F2b).
    Logluv,
}

impl ColorSpace {
    /// The three colour coordinates of linear RGB for white luminance `white`.
    #[inline]
    pub fn coords(self, rgb: [f64; 3], white: f64) -> [f64; 3] {
        match self {
            ColorSpace::Cielab => lab::rgb_to_lab(rgb, white),
            ColorSpace::Loglab => hdr::rgb_to_loglab(rgb, white),
            ColorSpace::Logluv => hdr::rgb_to_logluv(rgb, white),
        }
    }

    /// The first colour coordinate (L*, or the log lightness of F2a and
    /// F2b) of a colour whose luminance is `y` ([`lab::luminance`]): the
    /// same bits as `coords`' first, which depends on nothing else. Lets a
    /// pass that only sorts samples by lightness skip the chroma.
    #[inline]
    pub fn lightness(self, y: f64, white: f64) -> f64 {
        let u = y / (white * lab::WHITE_D65[1]);
        match self {
            ColorSpace::Cielab => 116.0 * lab::f(u) - 16.0,
            ColorSpace::Loglab | ColorSpace::Logluv => 116.0 * hdr::f_log(u) - 16.0,
        }
    }
}

crate::names::named!(ColorSpace, "colour space", {
    Cielab => "cielab",
    Loglab => "loglab",
    Logluv => "logluv",
});

/// Scales of the joint space. A point is
/// `(x/σ_image, y/σ_image, [t/σ_time], c₁/σ_color, c₂/σ_color, c₃/σ_color)`
/// with c the colour coordinates of `color` (L*, a*, b* for CIELAB).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct JointSpace {
    pub sigma_image: f64,
    pub sigma_color: f64,
    pub sigma_time: f64,
    /// Luminance of white, Y_w: radiance `white` maps to L* ≈ 100.
    pub white: f64,
    pub color: ColorSpace,
}

impl JointSpace {
    /// The shipped joint space, chosen by measurement (docs/RESULTS.md,
    /// "HDR fidelity: the defaults"): `logluv` (F2b), σ_image = 3 px,
    /// σ_color = 50, σ_time = 2 frames; white 1 until a run resolves it.
    pub const DEFAULT: JointSpace = JointSpace {
        sigma_image: 3.0,
        sigma_color: 50.0,
        sigma_time: 2.0,
        white: 1.0,
        color: ColorSpace::Logluv,
    };

    /// The paper's joint space: CIELAB (F2), σ_image = 3, σ_color = 100,
    /// σ_time = 2, white 1.
    pub const PAPER: JointSpace = JointSpace {
        sigma_color: 100.0,
        color: ColorSpace::Cielab,
        ..JointSpace::DEFAULT
    };

    /// The same scales with the white luminance `white`.
    pub const fn with_white(self, white: f64) -> JointSpace {
        JointSpace { white, ..self }
    }
}

impl Default for JointSpace {
    fn default() -> Self {
        JointSpace::DEFAULT
    }
}

/// Rounds an f64 coordinate to f32, clamped to the finite range (docs/filter.md §1).
#[inline]
fn coord(v: f64) -> f32 {
    (v as f32).clamp(-f32::MAX, f32::MAX)
}

impl JointSpace {
    /// The film of `header` in joint units along x, y and t: where every
    /// valid record's point lies (from 0), what the grids cover.
    pub fn extent(&self, header: &Header) -> [f64; 3] {
        [
            header.width as f64 / self.sigma_image,
            header.height as f64 / self.sigma_image,
            header.frames as f64 / self.sigma_time,
        ]
    }

    /// The joint point of a valid record (docs/filter.md F1). `D` is 5 for
    /// a still (no time axis) and 6 for an animation.
    #[inline]
    pub fn point<const D: usize>(&self, r: &Record) -> [f32; D] {
        debug_assert!(D == 5 || D == 6);
        let lab = self
            .color
            .coords([r.r as f64, r.g as f64, r.b as f64], self.white);
        let mut p = [0f32; D];
        p[0] = coord(r.x as f64 / self.sigma_image);
        p[1] = coord(r.y as f64 / self.sigma_image);
        let c = D - 3;
        if D == 6 {
            p[2] = coord(r.t as f64 / self.sigma_time);
        }
        for i in 0..3 {
            p[c + i] = coord(lab[i] / self.sigma_color);
        }
        p
    }

    /// [`JointSpace::point`]'s first colour coordinate (index `D - 3`) of a
    /// record whose luminance ([`lab::luminance`]) is `y`, the same bits.
    #[inline]
    pub fn lightness_coord(&self, y: f64) -> f32 {
        coord(self.color.lightness(y, self.white) / self.sigma_color)
    }

    /// [`JointSpace::point`]'s image (and time) coordinates, the colour
    /// ones left 0: what an index over the image axes needs, without the
    /// colour transform.
    #[inline]
    pub fn image_point<const D: usize>(&self, r: &Record) -> [f32; D] {
        let mut p = [0f32; D];
        p[0] = coord(r.x as f64 / self.sigma_image);
        p[1] = coord(r.y as f64 / self.sigma_image);
        if D == 6 {
            p[2] = coord(r.t as f64 / self.sigma_time);
        }
        p
    }
}

/// The canonical joint distance: computed in f64 from the f32 coordinates,
/// squared differences added in coordinate order (docs/filter.md §1). Returns the
/// squared distance; `sqrt` of it is the distance.
#[inline(always)]
pub fn dist2<const D: usize>(p: &[f32; D], q: &[f32; D]) -> f64 {
    let mut s = 0.0f64;
    for j in 0..D {
        let d = p[j] as f64 - q[j] as f64;
        s += d * d;
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lightness from luminance alone is the point's coordinate, bit
    /// for bit, in every colour space: dark, negative, around the white
    /// and far above it, and at the f32 clamp.
    #[test]
    fn the_lightness_of_the_luminance_is_the_points_coordinate() {
        let mut uniform = crate::synth::test_units(11);
        let mut checked = 0;
        for color in [ColorSpace::Cielab, ColorSpace::Loglab, ColorSpace::Logluv] {
            for white in [1.0, 0.37, 250.0] {
                let space = JointSpace {
                    color,
                    white,
                    ..JointSpace::DEFAULT
                };
                for i in 0..3000 {
                    let scale = [1e-6, 0.01, 1.0, 30.0, 1e5, 3e38][i % 6];
                    let mut c = || ((uniform() * 2.2 - 0.2) * scale) as f32;
                    let r = Record {
                        x: 0.5,
                        y: 0.5,
                        t: 0.0,
                        r: c(),
                        g: c(),
                        b: c(),
                    };
                    let y = lab::luminance([r.r as f64, r.g as f64, r.b as f64]);
                    let p = space.point::<5>(&r);
                    assert_eq!(
                        space.lightness_coord(y).to_bits(),
                        p[2].to_bits(),
                        "{color:?} white {white} {r:?}"
                    );
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 27_000);
    }
}
