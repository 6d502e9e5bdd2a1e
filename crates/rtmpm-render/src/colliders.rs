//! Colliders in the picture. Each collider's signed distance, clipped to the scene box, is
//! sphere-traced (Hart 1996, "Sphere tracing") through the pixels of its screen rectangle and
//! through the texels of the light's shadow map; a half-space clipped to the box is a convex
//! polyhedron, intersected exactly instead. Hits go into the same depth buffers as the
//! particle splats, so colliders and particles hide and shadow each other and are shaded by the
//! same lights.

use crate::camera::View;
use crate::gbuffer::GTexel;
use crate::shadow::{SHADOW_RES, ShadowMap};
use rayon::prelude::*;
use rtmpm_geometry::Collider;
use rtmpm_geometry::Shape;
use rtmpm_geometry::shape::box_distance;
use rtmpm_physics::math::Vec3;

/// G-buffer id of a collider texel (particle ids are their indices, far below).
pub(crate) const COLLIDER_ID: u32 = u32::MAX;

/// Grey of collider surfaces (0..1 RGB).
pub const COLLIDER_COLOR: [f32; 3] = [0.58, 0.58, 0.6];

/// Most sphere-tracing steps along one ray; a ray that has not converged by then (grazing a
/// silhouette) misses.
const MAX_STEPS: usize = 96;

/// A collider at one instant, clipped to the scene box (colliders only act inside the domain,
/// and an unclipped half-space would fill the sky).
pub(crate) struct PosedCollider<'a> {
    collider: &'a Collider,
    time: f32,
    clip_center: Vec3,
    clip_half: Vec3,
    /// World bounds of the clipped collider.
    lo: Vec3,
    hi: Vec3,
    /// A half-space at this time: a point of its plane and its outward unit normal.
    plane: Option<(Vec3, Vec3)>,
}

impl<'a> PosedCollider<'a> {
    /// `collider` at `time` clipped to the box `clip`; `None` when its bounds miss the box.
    pub fn new(collider: &'a Collider, time: f32, clip: (Vec3, Vec3)) -> Option<Self> {
        let (mut lo, mut hi) = clip;
        if let Some((clo, chi)) = collider.bounds(time) {
            lo = lo.max(clo);
            hi = hi.min(chi);
        }
        if !(lo.cmple(hi).all() && lo.is_finite() && hi.is_finite()) {
            return None;
        }
        let plane = match collider.shape {
            Shape::HalfSpace(h) => Some((
                collider.to_world(h.point, time),
                (collider.rotation(time) * h.normal).normalize_or(h.normal),
            )),
            _ => None,
        };
        Some(PosedCollider {
            collider,
            time,
            plane,
            clip_center: 0.5 * (clip.0 + clip.1),
            clip_half: 0.5 * (clip.1 - clip.0),
            lo,
            hi,
        })
    }

    /// Signed distance of the clipped collider (the intersection of the collider and the box).
    pub fn distance(&self, p: Vec3) -> f32 {
        self.collider
            .distance(p, self.time)
            .max(box_distance(p, self.clip_center, self.clip_half))
    }

    /// Outward unit normal at the hit `p` by central differences of step `h`.
    pub fn normal(&self, p: Vec3, h: f32) -> Vec3 {
        if let Some((_, n)) = self.plane {
            // On the plane unless the hit is on one of the clipping box's faces.
            let q = (p - self.clip_center).abs() - self.clip_half;
            let a = if q.x >= q.y && q.x >= q.z {
                0
            } else if q.y >= q.z {
                1
            } else {
                2
            };
            if q[a] > -h {
                let mut f = Vec3::ZERO;
                f[a] = (p[a] - self.clip_center[a]).signum();
                return f;
            }
            return n;
        }
        let d = |o: Vec3| self.distance(p + o) - self.distance(p - o);
        Vec3::new(d(Vec3::X * h), d(Vec3::Y * h), d(Vec3::Z * h))
            .try_normalize()
            .unwrap_or(Vec3::Y)
    }

    /// The parameter range `[s0, s1]` in which the ray `origin + dir s` (s >= 0) is inside the
    /// bounds, slightly padded; `None` if it misses them.
    fn slab(&self, origin: Vec3, dir: Vec3) -> Option<(f32, f32)> {
        let pad = Vec3::splat(1e-4 + 1e-3 * (self.hi - self.lo).max_element());
        let (lo, hi) = (self.lo - pad, self.hi + pad);
        let (mut s0, mut s1) = (0.0f32, f32::INFINITY);
        for a in 0..3 {
            if dir[a].abs() < 1e-12 {
                if origin[a] < lo[a] || origin[a] > hi[a] {
                    return None;
                }
            } else {
                let inv = 1.0 / dir[a];
                let (ta, tb) = ((lo[a] - origin[a]) * inv, (hi[a] - origin[a]) * inv);
                s0 = s0.max(ta.min(tb));
                s1 = s1.min(ta.max(tb));
            }
        }
        (s0 <= s1).then_some((s0, s1))
    }

    /// First hit of the ray `origin + dir s` with `s` below `s_max`: sphere tracing from the
    /// ray's entry into the bounds, converged when the distance is below `eps0 + eps1 s`.
    pub fn trace(&self, origin: Vec3, dir: Vec3, s_max: f32, eps0: f32, eps1: f32) -> Option<f32> {
        let (s0, s1) = self.slab(origin, dir)?;
        let s1 = s1.min(s_max);
        if let Some((point, n)) = self.plane {
            // Convex: the ray is inside for s in [s0, s1] (box) and where (x - point) . n < 0.
            let (f0, fd) = ((origin - point).dot(n), dir.dot(n));
            let (mut s0, mut s1) = (s0, s1);
            if fd.abs() < 1e-12 {
                if f0 >= 0.0 {
                    return None;
                }
            } else if fd < 0.0 {
                s0 = s0.max(-f0 / fd);
            } else {
                s1 = s1.min(-f0 / fd);
            }
            return (s0 <= s1).then_some(s0);
        }
        let inv_len = 1.0 / dir.length();
        let mut s = s0;
        for _ in 0..MAX_STEPS {
            if s > s1 {
                return None;
            }
            let d = self.distance(origin + dir * s);
            if d < eps0 + eps1 * s {
                return Some(s);
            }
            s += d * inv_len;
        }
        None
    }

    /// The 8 corners of the bounds.
    fn corners(&self) -> [Vec3; 8] {
        let (lo, hi) = (self.lo, self.hi);
        std::array::from_fn(|i| {
            Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        })
    }
}

/// Pixel rectangle `[x0, x1) x [y0, y1)` covering the projections of `corners`, clipped to the
/// image; the whole image when `project` fails for a corner (behind the camera).
fn screen_rect(
    corners: &[Vec3; 8],
    project: impl Fn(Vec3) -> Option<(f32, f32)>,
    w: usize,
    h: usize,
) -> (usize, usize, usize, usize) {
    let (mut x0, mut x1, mut y0, mut y1) = (
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::INFINITY,
        f32::NEG_INFINITY,
    );
    for c in corners {
        let Some((x, y)) = project(*c) else {
            return (0, w, 0, h);
        };
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    let clip = |v: f32, n: usize| v.clamp(0.0, n as f32) as usize;
    (
        clip(x0.floor() - 1.0, w),
        clip(x1.ceil() + 1.0, w),
        clip(y0.floor() - 1.0, h),
        clip(y1.ceil() + 1.0, h),
    )
}

/// Draw the colliders into the camera's G-buffer (`w` x `h`): a texel takes a collider hit that
/// is nearer than what it holds, with the hit's normal stored as splat coordinates
/// (`u = n . right`, `v = -n . up`, so the shading's sphere normal is the surface normal).
pub(crate) fn draw(
    colliders: &[PosedCollider],
    view: &View,
    near: f32,
    w: usize,
    h: usize,
    gbuf: &mut [GTexel],
) {
    // A hit is accepted within a quarter of a pixel's footprint.
    let eps1 = 0.25 / view.focal;
    for c in colliders {
        let (x0, x1, y0, y1) = screen_rect(
            &c.corners(),
            |p| {
                let (x, y, z) = view.project(p);
                (z > near).then_some((x, y))
            },
            w,
            h,
        );
        if x0 >= x1 || y0 >= y1 {
            continue;
        }
        gbuf.par_chunks_mut(w)
            .enumerate()
            .skip(y0)
            .take(y1 - y0)
            .for_each(|(y, row)| {
                for (x, t) in row.iter_mut().enumerate().take(x1).skip(x0) {
                    let ray = view.ray(x as f32 + 0.5, y as f32 + 0.5);
                    let Some(s) = c.trace(view.pos, ray, t.depth, 1e-6, eps1) else {
                        continue;
                    };
                    if s <= near || s >= t.depth {
                        continue;
                    }
                    let p = view.pos + ray * s;
                    let n = c.normal(p, (2.0 * eps1 * s).max(1e-5));
                    *t = GTexel {
                        depth: s,
                        u: n.dot(view.right),
                        v: -n.dot(view.up),
                        id: COLLIDER_ID,
                    };
                }
            });
    }
}

/// Add the colliders to the light's depth map, so they cast shadows.
pub(crate) fn cast_shadows(colliders: &[PosedCollider], map: &mut ShadowMap) {
    let texel = 1.0 / map.scale;
    for c in colliders {
        let project = |p: Vec3| {
            let d = p - map.origin;
            Some((d.dot(map.right) * map.scale, -d.dot(map.up) * map.scale))
        };
        let (x0, x1, y0, y1) = screen_rect(&c.corners(), project, SHADOW_RES, SHADOW_RES);
        if x0 >= x1 || y0 >= y1 {
            continue;
        }
        let (origin, right, up, fwd) = (map.origin, map.right, map.up, map.fwd);
        map.depth
            .par_chunks_mut(SHADOW_RES)
            .enumerate()
            .skip(y0)
            .take(y1 - y0)
            .for_each(|(y, row)| {
                for (x, d) in row.iter_mut().enumerate().take(x1).skip(x0) {
                    let o = origin + right * ((x as f32 + 0.5) * texel)
                        - up * ((y as f32 + 0.5) * texel);
                    if let Some(s) = c.trace(o, fwd, *d, 0.25 * texel, 0.0)
                        && s < *d
                    {
                        *d = s;
                    }
                }
            });
    }
}
