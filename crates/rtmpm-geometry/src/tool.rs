//! The user's tool: a kinematic collider that a live view moves with the cursor
//! (`rtmpm_sim::Backend::set_tool`).
//!
//! It acts in the grid update like a collider with the separating rule and no friction
//! (`BoundaryRule::default`): a node inside it loses the part of its velocity,
//! relative to the tool, that goes into the tool. The backend holds it where it was put; the
//! caller moves it between steps (each call gives its new centre and the velocity it moves at).

use super::shape::{Cuboid, Shape, Sphere};
use glam::Vec3;

/// The shape of a [`Tool`], centred on [`Tool::center`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ToolShape {
    /// A ball of this radius (m).
    Sphere { radius: f32 },
    /// An axis-aligned box of these half extents (m).
    Box { half: Vec3 },
}

/// A kinematic tool steered by the user: a separating collider that follows the cursor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tool {
    pub shape: ToolShape,
    /// Centre (m).
    pub center: Vec3,
    /// Velocity the tool moves at (m/s): the velocity it gives the material it pushes.
    pub velocity: Vec3,
}

impl Tool {
    /// Its shape in world coordinates.
    pub fn sdf(&self) -> Shape {
        match self.shape {
            ToolShape::Sphere { radius } => Shape::Sphere(Sphere {
                center: self.center,
                radius,
            }),
            ToolShape::Box { half } => Shape::Box(Cuboid::centred(self.center, half)),
        }
    }

    /// A clear message when the tool is not usable: non-finite numbers, a size that is not
    /// positive.
    pub fn check(&self) -> Result<(), String> {
        let size_ok = match self.shape {
            ToolShape::Sphere { radius } => radius.is_finite() && radius > 0.0,
            ToolShape::Box { half } => half.is_finite() && half.min_element() > 0.0,
        };
        if !size_ok {
            let size = match self.shape {
                ToolShape::Sphere { radius } => format!("radius {radius}"),
                ToolShape::Box { half } => {
                    format!("half extents ({}, {}, {})", half.x, half.y, half.z)
                }
            };
            return Err(format!(
                "the tool's size must be positive and finite, got {size}"
            ));
        }
        if !self.center.is_finite() || !self.velocity.is_finite() {
            return Err(format!(
                "the tool's centre and velocity must be finite, got {} and {}",
                self.center, self.velocity
            ));
        }
        Ok(())
    }

    /// If `x` is inside the tool (signed distance <= 0), its outward unit normal there and the
    /// tool's velocity, as [`super::Collider::query`] answers.
    #[inline]
    pub fn query(&self, x: Vec3) -> Option<(Vec3, Vec3)> {
        let shape = self.sdf();
        if shape.distance(x) > 0.0 {
            return None;
        }
        let n = shape.normal(x).try_normalize().unwrap_or(Vec3::Y);
        Some((n, self.velocity))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sphere_tool_answers_inside_only_with_its_outward_normal_and_velocity() {
        let t = Tool {
            shape: ToolShape::Sphere { radius: 0.1 },
            center: Vec3::new(0.5, 0.5, 0.5),
            velocity: Vec3::new(1.0, 0.0, 0.0),
        };
        assert!(t.query(Vec3::new(0.65, 0.5, 0.5)).is_none());
        let (n, v) = t.query(Vec3::new(0.55, 0.5, 0.5)).unwrap();
        assert!((n - Vec3::X).length() < 1e-6, "{n}");
        assert_eq!(v, Vec3::X);
        assert!(t.check().is_ok());
    }

    #[test]
    fn a_box_tool_uses_the_face_of_least_penetration() {
        let t = Tool {
            shape: ToolShape::Box {
                half: Vec3::new(0.2, 0.05, 0.2),
            },
            center: Vec3::ZERO,
            velocity: Vec3::ZERO,
        };
        let (n, _) = t.query(Vec3::new(0.0, -0.04, 0.1)).unwrap();
        assert!((n + Vec3::Y).length() < 1e-6, "{n}");
        assert!(t.query(Vec3::new(0.0, 0.06, 0.0)).is_none());
    }

    #[test]
    fn bad_tools_are_refused() {
        let mut t = Tool {
            shape: ToolShape::Sphere { radius: 0.0 },
            center: Vec3::ZERO,
            velocity: Vec3::ZERO,
        };
        assert!(t.check().unwrap_err().contains("positive"));
        t.shape = ToolShape::Box {
            half: Vec3::new(0.1, f32::NAN, 0.1),
        };
        assert!(t.check().is_err());
        t.shape = ToolShape::Sphere { radius: 0.1 };
        t.velocity = Vec3::new(f32::INFINITY, 0.0, 0.0);
        assert!(t.check().unwrap_err().contains("finite"));
    }
}
