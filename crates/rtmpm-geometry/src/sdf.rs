//! Signed distance functions of collider shapes (negative inside, outward normals).

use super::mesh::MeshSdf;
use glam::Vec3;
use std::sync::Arc;

/// Collider shape in its rest pose; negative distance inside.
#[derive(Clone, Debug)]
pub enum Shape {
    /// Points `x` with `(x - point) . normal < 0` are inside. `normal` is a unit vector.
    HalfSpace {
        point: Vec3,
        normal: Vec3,
    },
    /// Axis-aligned box.
    Box {
        center: Vec3,
        half_extents: Vec3,
    },
    Sphere {
        center: Vec3,
        radius: f32,
    },
    /// Capped cylinder along unit `axis`.
    Cylinder {
        center: Vec3,
        axis: Vec3,
        radius: f32,
        half_height: f32,
    },
    /// Triangle mesh sampled into a signed distance grid.
    Mesh(Arc<MeshSdf>),
}

/// Signed distance to an axis-aligned box (exact, negative inside).
#[inline]
pub fn box_distance(x: Vec3, center: Vec3, half_extents: Vec3) -> f32 {
    let q = (x - center).abs() - half_extents;
    q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
}

/// Signed distance to a sphere.
#[inline]
pub fn sphere_distance(x: Vec3, center: Vec3, radius: f32) -> f32 {
    (x - center).length() - radius
}

/// Signed distance to a capped cylinder (exact, negative inside); `axis` must be a unit vector.
#[inline]
pub fn cylinder_distance(x: Vec3, center: Vec3, axis: Vec3, radius: f32, half_height: f32) -> f32 {
    let p = x - center;
    let h = p.dot(axis);
    let r = (p - h * axis).length();
    let dr = r - radius;
    let dh = h.abs() - half_height;
    let ox = dr.max(0.0);
    let oy = dh.max(0.0);
    (ox * ox + oy * oy).sqrt() + dr.max(dh).min(0.0)
}

/// Any unit vector perpendicular to unit `a`.
#[inline]
pub(crate) fn any_perpendicular(a: Vec3) -> Vec3 {
    let t = if a.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    a.cross(t).normalize()
}

impl Shape {
    /// Signed distance (negative inside).
    pub fn distance(&self, x: Vec3) -> f32 {
        match self {
            Shape::HalfSpace { point, normal } => (x - *point).dot(*normal),
            Shape::Box {
                center,
                half_extents,
            } => box_distance(x, *center, *half_extents),
            Shape::Sphere { center, radius } => sphere_distance(x, *center, *radius),
            Shape::Cylinder {
                center,
                axis,
                radius,
                half_height,
            } => cylinder_distance(x, *center, *axis, *radius, *half_height),
            Shape::Mesh(m) => m.distance(x),
        }
    }

    /// Outward unit normal (gradient of the distance). Analytic for the simple shapes; at
    /// points where the gradient is undefined (a sphere's centre) an arbitrary but fixed unit
    /// vector is returned.
    pub fn normal(&self, x: Vec3) -> Vec3 {
        match self {
            Shape::HalfSpace { normal, .. } => *normal,
            Shape::Sphere { center, .. } => (x - *center).try_normalize().unwrap_or(Vec3::Y),
            Shape::Box {
                center,
                half_extents,
            } => {
                let p = x - *center;
                let q = p.abs() - *half_extents;
                let sign = Vec3::select(p.cmplt(Vec3::ZERO), Vec3::NEG_ONE, Vec3::ONE);
                if q.max_element() > 0.0 {
                    // Outside: gradient of the distance to the nearest point.
                    (q.max(Vec3::ZERO) * sign)
                        .try_normalize()
                        .unwrap_or(Vec3::Y)
                } else {
                    // Inside: the face of least penetration.
                    let mut n = Vec3::ZERO;
                    let axis = if q.x >= q.y && q.x >= q.z {
                        0
                    } else if q.y >= q.z {
                        1
                    } else {
                        2
                    };
                    n[axis] = sign[axis];
                    n
                }
            }
            Shape::Cylinder {
                center,
                axis,
                radius,
                half_height,
            } => {
                let p = x - *center;
                let h = p.dot(*axis);
                let radial = p - h * *axis;
                let r = radial.length();
                let er = if r > 0.0 {
                    radial / r
                } else {
                    any_perpendicular(*axis)
                };
                let ea = if h >= 0.0 { *axis } else { -*axis };
                let dr = r - *radius;
                let dh = h.abs() - *half_height;
                if dr > 0.0 && dh > 0.0 {
                    (er * dr + ea * dh).normalize()
                } else if dr > 0.0 || (dr <= 0.0 && dh <= 0.0 && dr >= dh) {
                    er
                } else {
                    ea
                }
            }
            Shape::Mesh(m) => m.normal(x),
        }
    }

    /// Axis-aligned bounds of the shape in its rest pose; `None` for the unbounded half-space.
    /// A mesh is bounded by its distance grid.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        match self {
            Shape::HalfSpace { .. } => None,
            Shape::Box {
                center,
                half_extents,
            } => Some((*center - *half_extents, *center + *half_extents)),
            Shape::Sphere { center, radius } => Some((
                *center - Vec3::splat(*radius),
                *center + Vec3::splat(*radius),
            )),
            Shape::Cylinder {
                center,
                axis,
                radius,
                half_height,
            } => {
                // Per axis: the half-height along the axis plus the radius of the caps' discs.
                let a = axis.abs();
                let disc = (Vec3::ONE - *axis * *axis).max(Vec3::ZERO);
                let e = a * *half_height
                    + Vec3::new(disc.x.sqrt(), disc.y.sqrt(), disc.z.sqrt()) * *radius;
                Some((*center - e, *center + e))
            }
            Shape::Mesh(m) => Some((m.origin, m.grid_max())),
        }
    }

    /// A natural centre of the shape (default pivot of a collider): the point of a half-space,
    /// the centre of the analytic shapes, the centre of a mesh's bounding box.
    pub fn center(&self) -> Vec3 {
        match self {
            Shape::HalfSpace { point, .. } => *point,
            Shape::Box { center, .. }
            | Shape::Sphere { center, .. }
            | Shape::Cylinder { center, .. } => *center,
            Shape::Mesh(m) => 0.5 * (m.mesh_min + m.mesh_max),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() < 1e-5
    }
    fn vclose(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-5
    }

    #[test]
    fn half_space() {
        let s = Shape::HalfSpace {
            point: Vec3::new(0.0, 1.0, 0.0),
            normal: Vec3::Y,
        };
        assert!(close(s.distance(Vec3::new(5.0, 3.0, 2.0)), 2.0));
        assert!(close(s.distance(Vec3::new(5.0, 0.5, 2.0)), -0.5));
        assert!(close(s.distance(Vec3::new(0.0, 1.0, 0.0)), 0.0));
        assert_eq!(s.normal(Vec3::ZERO), Vec3::Y);
        assert!(vclose(s.center(), Vec3::Y));
    }

    #[test]
    fn sphere() {
        let s = Shape::Sphere {
            center: Vec3::ONE,
            radius: 0.5,
        };
        assert!(close(s.distance(Vec3::ONE), -0.5));
        assert!(close(s.distance(Vec3::new(2.0, 1.0, 1.0)), 0.5));
        assert!(close(s.distance(Vec3::new(1.0, 1.5, 1.0)), 0.0));
        assert!(vclose(s.normal(Vec3::new(1.0, 0.0, 1.0)), -Vec3::Y));
        assert!(vclose(s.normal(Vec3::new(1.2, 1.0, 1.0)), Vec3::X));
    }

    #[test]
    fn boxes() {
        let s = Shape::Box {
            center: Vec3::ZERO,
            half_extents: Vec3::new(1.0, 2.0, 3.0),
        };
        assert!(close(s.distance(Vec3::ZERO), -1.0));
        assert!(close(s.distance(Vec3::new(0.0, 1.5, 0.0)), -0.5));
        assert!(close(s.distance(Vec3::new(2.0, 0.0, 0.0)), 1.0));
        assert!(close(s.distance(Vec3::new(1.0, 0.0, 0.0)), 0.0));
        // Corner region: Euclidean distance to the corner.
        assert!(close(s.distance(Vec3::new(4.0, 6.0, 0.0)), 5.0));
        assert!(vclose(s.normal(Vec3::new(2.0, 0.0, 0.0)), Vec3::X));
        assert!(vclose(s.normal(Vec3::new(0.0, -1.9, 0.0)), -Vec3::Y));
        assert!(vclose(s.normal(Vec3::new(0.0, 0.0, 2.9)), Vec3::Z));
        let n = s.normal(Vec3::new(4.0, 6.0, 0.0));
        assert!(vclose(n, Vec3::new(3.0, 4.0, 0.0) / 5.0));
    }

    #[test]
    fn bounds_contain_the_shape() {
        let shapes = [
            Shape::Sphere {
                center: Vec3::ONE,
                radius: 0.5,
            },
            Shape::Box {
                center: Vec3::ZERO,
                half_extents: Vec3::new(1.0, 2.0, 3.0),
            },
            Shape::Cylinder {
                center: Vec3::new(0.2, 0.0, 0.0),
                axis: Vec3::new(1.0, 2.0, 0.5).normalize(),
                radius: 0.3,
                half_height: 0.8,
            },
        ];
        for s in &shapes {
            let (lo, hi) = s.bounds().unwrap();
            // Points just outside every face of the bounds are outside the shape, and the
            // bounds are tight: some point on each face is within 1e-3 of the surface.
            for axis in 0..3 {
                for (side, face) in [(-1.0f32, lo[axis]), (1.0, hi[axis])] {
                    let mut best = f32::INFINITY;
                    for i in 0..=40 {
                        for j in 0..=40 {
                            let mut p = lo + (hi - lo) * 0.5;
                            let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
                            p[a1] = lo[a1] + (hi[a1] - lo[a1]) * i as f32 / 40.0;
                            p[a2] = lo[a2] + (hi[a2] - lo[a2]) * j as f32 / 40.0;
                            p[axis] = face + side * 1e-4;
                            assert!(s.distance(p) > 0.0, "{s:?} {p}");
                            best = best.min(s.distance(p));
                        }
                    }
                    assert!(best < 0.02, "{s:?} axis {axis}: {best}");
                }
            }
        }
        assert!(
            Shape::HalfSpace {
                point: Vec3::ZERO,
                normal: Vec3::Y
            }
            .bounds()
            .is_none()
        );
    }

    #[test]
    fn cylinder() {
        let s = Shape::Cylinder {
            center: Vec3::ZERO,
            axis: Vec3::Z,
            radius: 1.0,
            half_height: 2.0,
        };
        assert!(close(s.distance(Vec3::ZERO), -1.0));
        assert!(close(s.distance(Vec3::new(0.0, 0.0, 1.8)), -0.2));
        assert!(close(s.distance(Vec3::new(3.0, 0.0, 0.0)), 2.0));
        assert!(close(s.distance(Vec3::new(0.0, 0.0, 3.0)), 1.0));
        assert!(close(s.distance(Vec3::new(0.0, 1.0, 0.0)), 0.0));
        assert!(close(s.distance(Vec3::new(4.0, 0.0, 6.0)), 5.0));
        assert!(vclose(s.normal(Vec3::new(0.0, 2.0, 0.0)), Vec3::Y));
        assert!(vclose(s.normal(Vec3::new(0.0, 0.5, -1.9)), -Vec3::Z));
        assert!(vclose(s.normal(Vec3::new(0.9, 0.0, 0.0)), Vec3::X));
        assert!(vclose(
            s.normal(Vec3::new(4.0, 0.0, 6.0)),
            Vec3::new(3.0, 0.0, 4.0) / 5.0
        ));
    }
}
