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

/// Most density (kg/m^3) a moving rigid body may have: 44 times the densest element. rapier3d
/// stops moving bodies far heavier (a box of density 1e25 hung still under gravity; 1e22 fell).
pub const MAX_RIGID_DENSITY: f64 = 1e6;
/// Most speed (m/s) of a rigid body: rapier3d caps a body's speed at this (its default
/// `normalized_max_linear_velocity` for a length unit of 1 m).
pub const MAX_RIGID_SPEED: f32 = 400.0;

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
        let mass = self.rigid_mass(&prefix, b, kind, shape.volume())?;
        let (velocity, angular_velocity) = self.rigid_velocities(&prefix, b, kind)?;
        // Inside the domain minus the walls, in its initial pose.
        let h = shape.half_extents(glam::Mat3::from_quat(rotation));
        self.inside_interior(
            &prefix,
            "rigid body",
            (position - h, position + h),
            interior,
        )?;
        let condition = Self::condition(b.condition.unwrap_or(Self::DEFAULT_CONDITION));
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

    /// The body's mass (kg) from exactly one of `density` and `mass` (a fixed body needs
    /// neither): finite, and a moving body's density at most [`MAX_RIGID_DENSITY`].
    fn rigid_mass(&self, prefix: &str, b: &RawRigidBody, kind: RigidKind, volume: f32) -> R<f32> {
        let f = |n: &str| format!("{prefix}.{n}");
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
        let mass_field = f(if b.mass.is_some() { "mass" } else { "density" });
        if !mass.is_finite() {
            return Err(self.err(
                &mass_field,
                format!("the body's mass {mass} kg (density x volume {volume} m^3) is not finite"),
                "give a body of a sensible size (check the mesh's units and `scale`) and density",
            ));
        }
        let density = mass as f64 / volume as f64;
        if kind != RigidKind::Fixed && density > MAX_RIGID_DENSITY {
            return Err(self.err(
                &mass_field,
                format!(
                    "the body's density {density:.3e} kg/m^3 (mass {mass:.3e} kg over a volume of \
                     {volume:.3e} m^3) is above the {MAX_RIGID_DENSITY:e} kg/m^3 a rigid body may \
                     have (the densest element is 2.26e4; the rigid-body solver stops moving far \
                     heavier bodies)"
                ),
                "give a real density (or a mass that fits the body's volume); for a body the \
                 material cannot move use type = \"kinematic\" (moves at its velocity) or \
                 \"fixed\"",
            ));
        }
        Ok(mass)
    }

    /// The body's initial velocity and angular velocity: finite, at most [`MAX_RIGID_SPEED`],
    /// and none for a fixed body.
    fn rigid_velocities(&self, prefix: &str, b: &RawRigidBody, kind: RigidKind) -> R<(Vec3, Vec3)> {
        let f = |n: &str| format!("{prefix}.{n}");
        let velocity = match b.velocity {
            Some(v) => self.vec3(&f("velocity"), v)?,
            None => Vec3::ZERO,
        };
        let speed = velocity.as_dvec3().length();
        if speed > MAX_RIGID_SPEED as f64 {
            return Err(self.err(
                f("velocity"),
                format!(
                    "the body's speed {speed:.4e} m/s is above the {MAX_RIGID_SPEED} m/s the \
                     rigid-body solver (rapier3d) lets a body move at: it would be slowed to that \
                     speed"
                ),
                format!("give a speed of at most {MAX_RIGID_SPEED} m/s"),
            ));
        }
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
        Ok((velocity, angular_velocity))
    }

    /// Rigid bodies have unique names: joints name them, `bodies.csv` rows carry them.
    pub(super) fn rigid_names(&self, bodies: &[RigidBodySpec]) -> R<()> {
        for (j, b) in bodies.iter().enumerate() {
            if b.name.is_empty()
                || b.name.contains([',', '"', '\\'])
                || b.name.chars().any(char::is_control)
            {
                return Err(self.err(
                    format!("rigid_body[{j}].name"),
                    format!(
                        "the name {:?} is empty or holds a comma, a quote, a backslash or a \
                         control character; bodies.csv writes it in a column",
                        b.name
                    ),
                    "use letters, digits, spaces, `-` and `_` (e.g. name = \"flap\")",
                ));
            }
            if let Some(i) = bodies[..j].iter().position(|a| a.name == b.name) {
                return Err(self.err(
                    format!("rigid_body[{j}].name"),
                    format!(
                        "rigid_body[{j}] is named \"{}\" like rigid_body[{i}]: joints and the rows \
                         of bodies.csv name bodies, so a name must be unique",
                        b.name
                    ),
                    "give every [[rigid_body]] its own name",
                ));
            }
        }
        Ok(())
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
