//! Validation of `[[rigid_body]]` tables.

use super::core::{R, V, fmt3};
use super::shapes::Fields;
use crate::schema::*;
use glam::Quat;
use rtmpm_geometry::shape::{Mesh, ShapeKind};
use rtmpm_geometry::{Shape, Use};
use rtmpm_physics::math::Vec3;
use rtmpm_rigid::{JointSpec, RigidBodySpec, RigidKind};
use std::path::Path;

impl V<'_> {
    /// `rigid_body[i]`: a box, sphere, cylinder or closed mesh inside the domain minus the walls, exactly one of
    /// `density` and `mass` (> 0; a fixed body needs neither), finite pose and velocities.
    pub(super) fn rigid_body(
        &self,
        i: usize,
        b: &RawRigidBody,
        base: &Path,
        dx: f32,
        interior: (Vec3, Vec3),
    ) -> R<RigidBodySpec> {
        let prefix = format!("rigid_body[{i}]");
        let f = |n: &str| format!("{prefix}.{n}");
        self.shape_use(&prefix, b.shape, Use::RigidBody)?;
        if b.convex.is_some() && b.shape.name() != Mesh::NAME {
            return Err(self.err(
                f("convex"),
                format!(
                    "`convex` is not a parameter of shape \"{}\"",
                    b.shape.name()
                ),
                "remove it; only a mesh body takes convex = true (collide as its convex hull)",
            ));
        }
        let g = b.geometry();
        self.shape_fields(&prefix, &g)?;
        // The shape about its centre: a cylinder's `axis` turns its rest orientation (rapier's
        // and ours: along local y); `rotation` then turns the body.
        let fields = Fields {
            v: self,
            prefix: &prefix,
            g: &g,
            use_: Use::RigidBody,
            base,
            dx,
            convex: b.convex.unwrap_or(false),
        };
        let (shape, position, rest) = Shape::read_body(g.shape.0, &fields)?;
        let rotation = match b.rotation {
            Some(r) => Quat::from_scaled_axis(self.vec3(&f("rotation"), r)?) * rest,
            None => rest,
        };
        let kind = match b.kind.unwrap_or(RawRigidKind::Dynamic) {
            RawRigidKind::Dynamic => RigidKind::Dynamic,
            RawRigidKind::Kinematic => RigidKind::Kinematic,
            RawRigidKind::Fixed => RigidKind::Fixed,
        };
        let volume = shape.volume();
        let mass = match (b.density, b.mass) {
            (Some(_), Some(_)) => {
                return Err(self.err(
                    f("mass"),
                    "both density and mass are given",
                    "keep density (kg/m^3) or mass (kg)",
                ));
            }
            (Some(d), None) => self.positive(&f("density"), d, "density (kg/m^3)")? * volume,
            (None, Some(m)) => self.positive(&f("mass"), m, "mass (kg)")?,
            (None, None) if kind == RigidKind::Fixed => 1.0,
            (None, None) => {
                return Err(self.err(
                    f("density"),
                    "a dynamic or kinematic rigid body needs a density or a mass",
                    "add density = <kg/m^3> (e.g. 500 floats on water) or mass = <kg>",
                ));
            }
        };
        if !mass.is_finite() {
            return Err(self.err(
                f(if b.mass.is_some() { "mass" } else { "density" }),
                format!("the body's mass {mass} kg (density x volume {volume} m^3) is not finite"),
                "give a body of a sensible size (check the mesh's units and `scale`) and density",
            ));
        }
        let velocity = match b.velocity {
            Some(v) => self.vec3(&f("velocity"), v)?,
            None => Vec3::ZERO,
        };
        let angular_velocity = match b.angular_velocity {
            Some(v) => self.vec3(&f("angular_velocity"), v)?,
            None => Vec3::ZERO,
        };
        if kind == RigidKind::Fixed && (b.velocity.is_some() || b.angular_velocity.is_some()) {
            return Err(self.err(
                f(if b.velocity.is_some() { "velocity" } else { "angular_velocity" }),
                "a fixed rigid body does not move",
                "remove the velocity, or use type = \"kinematic\" (moves at its velocity) or \"dynamic\"",
            ));
        }
        // Inside the domain minus the walls, in its initial pose.
        let h = shape.half_extents(glam::Mat3::from_quat(rotation));
        self.inside_interior(
            &prefix,
            "rigid body",
            (position - h, position + h),
            interior,
        )?;
        let condition = Self::condition(b.condition.unwrap_or(RawCondition::Slip));
        let friction = self.non_negative(&f("friction"), b.friction.unwrap_or(0.0), "friction")?;
        Ok(RigidBodySpec {
            name: b.name.clone().unwrap_or_else(|| format!("rigid_body{i}")),
            shape,
            kind,
            mass,
            position,
            rotation,
            velocity,
            angular_velocity,
            condition,
            friction,
        })
    }

    /// Bodies must not overlap at the start (their axis-aligned bounds in the initial pose),
    /// unless a joint holds one to the other (rapier ignores contacts between jointed bodies).
    pub(super) fn rigid_overlaps(&self, bodies: &[RigidBodySpec], joints: &[JointSpec]) -> R<()> {
        let jointed = |i: usize, j: usize| {
            joints
                .iter()
                .any(|k| (k.body, k.to) == (i, Some(j)) || (k.body, k.to) == (j, Some(i)))
        };
        let bounds: Vec<(Vec3, Vec3)> = bodies
            .iter()
            .map(|b| {
                let h = b.shape.half_extents(glam::Mat3::from_quat(b.rotation));
                (b.position - h, b.position + h)
            })
            .collect();
        for j in 0..bodies.len() {
            for i in 0..j {
                let (a, b) = (bounds[i], bounds[j]);
                if a.0.cmplt(b.1).all() && b.0.cmplt(a.1).all() && !jointed(i, j) {
                    return Err(self.err(
                        format!("rigid_body[{j}]"),
                        format!(
                            "rigid_body[{j}] overlaps rigid_body[{i}] at the start (their bounding boxes {} .. {} and {} .. {} intersect)",
                            fmt3(b.0),
                            fmt3(b.1),
                            fmt3(a.0),
                            fmt3(a.1)
                        ),
                        "move the bodies apart so that they do not touch at t = 0",
                    ));
                }
            }
        }
        Ok(())
    }
}
