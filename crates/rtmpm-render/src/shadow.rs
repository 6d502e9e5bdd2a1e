//! The light's shadow map: an orthographic depth map of the particles (and colliders and
//! surface meshes, which add themselves) seen from the light, for the renderer's shadows.

use crate::input::{RenderInput, RenderOptions};
use crate::raster::{Splat, raster};
use rayon::prelude::*;
use rtmpm_physics::math::Vec3;

/// Direction towards the light (normalised where it is used).
pub const LIGHT: Vec3 = Vec3::new(-0.45, 1.0, 0.55);
/// Shadow map resolution.
pub const SHADOW_RES: usize = 1024;

/// The light's orthographic view of a scene box: texel `(x, y)` of the shadow map looks along
/// `fwd` from `origin + (right (x + 1/2) - up (y + 1/2)) / scale`, at depth `(p - origin) . fwd`.
#[derive(Clone, Copy, Debug)]
pub struct ShadowFrame {
    /// The corner of texel (0, 0) on the map's near plane.
    pub origin: Vec3,
    /// Image right (unit).
    pub right: Vec3,
    /// Image up (unit).
    pub up: Vec3,
    /// From the light (unit).
    pub fwd: Vec3,
    /// Texels per metre.
    pub scale: f32,
}

impl ShadowFrame {
    /// The frame that holds the box `bounds` (padded by two particle radii `radius`).
    pub fn new(bounds: (Vec3, Vec3), radius: f32) -> ShadowFrame {
        let fwd = -LIGHT.normalize();
        let right = fwd.cross(Vec3::Z).normalize();
        let up = right.cross(fwd);
        let (lo, hi) = bounds;
        let (mut u0, mut u1, mut v0, mut v1, mut d0) = (
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::INFINITY,
        );
        for i in 0..8 {
            let c = Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            );
            u0 = u0.min(c.dot(right));
            u1 = u1.max(c.dot(right));
            v0 = v0.min(c.dot(up));
            v1 = v1.max(c.dot(up));
            d0 = d0.min(c.dot(fwd));
        }
        let pad = 2.0 * radius;
        ShadowFrame {
            origin: right * (u0 - pad) + up * (v1 + pad) + fwd * (d0 - pad),
            right,
            up,
            fwd,
            scale: SHADOW_RES as f32 / ((u1 - u0).max(v1 - v0) + 2.0 * pad).max(1e-6),
        }
    }
}

/// An orthographic depth map seen from the light.
pub(super) struct ShadowMap {
    pub(super) origin: Vec3,
    pub(super) right: Vec3,
    pub(super) up: Vec3,
    pub(super) fwd: Vec3,
    pub(super) scale: f32,
    pub(super) depth: Vec<f32>,
}

impl ShadowMap {
    pub(super) fn build(input: &RenderInput, opts: &RenderOptions) -> ShadowMap {
        let ShadowFrame {
            origin,
            right,
            up,
            fwd,
            scale,
        } = ShadowFrame::new(opts.bounds, opts.radius);
        let wr = opts.radius;
        let splats: Vec<Splat> = input
            .positions
            .par_iter()
            .enumerate()
            .filter(|(_, p)| p.is_finite())
            .map(|(i, p)| {
                let d = *p - origin;
                Splat {
                    x: d.dot(right) * scale,
                    y: -d.dot(up) * scale,
                    r: (wr * scale).max(0.75),
                    z: d.dot(fwd),
                    wr,
                    id: i as u32,
                }
            })
            .collect();
        let mut depth = vec![f32::INFINITY; SHADOW_RES * SHADOW_RES];
        raster(&splats, SHADOW_RES, SHADOW_RES, &mut depth, |t, s, u, v| {
            let d = s.z - (1.0 - u * u - v * v).max(0.0).sqrt() * s.wr;
            if d < *t {
                *t = d;
            }
        });
        ShadowMap {
            origin,
            right,
            up,
            fwd,
            scale,
            depth,
        }
    }

    /// Fraction of light reaching `p` (0: in shadow), 3x3 percentage-closer filtered.
    pub(super) fn light(&self, p: Vec3, bias: f32) -> f32 {
        let d = p - self.origin;
        let x = d.dot(self.right) * self.scale;
        let y = -d.dot(self.up) * self.scale;
        let z = d.dot(self.fwd) - bias;
        let (xi, yi) = (x.floor() as i64, y.floor() as i64);
        let mut lit = 0.0;
        for dy in -1..=1 {
            for dx in -1..=1 {
                let (sx, sy) = (xi + dx, yi + dy);
                let occluded = sx >= 0
                    && sy >= 0
                    && (sx as usize) < SHADOW_RES
                    && (sy as usize) < SHADOW_RES
                    && self.depth[sy as usize * SHADOW_RES + sx as usize] < z;
                if !occluded {
                    lit += 1.0;
                }
            }
        }
        lit / 9.0
    }
}
