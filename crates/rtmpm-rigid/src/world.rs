//! The rigid bodies in rapier3d: one dynamic, kinematic or fixed body per `[[rigid_body]]`
//! with one collider of its shape, and the six faces of the domain minus the walls as fixed
//! slabs, so bodies rest on the floor and bounce off each other.

use crate::joint::{JointKind, JointSpec};
use crate::spec::{RigidBodySpec, RigidKind};
use crate::state::{BodyPose, BodyState, Exchange};
use rapier3d::prelude as rp;
use rtmpm_geometry::Shape;

/// rapier3d's vectors (its own glam) from ours, and back.
fn rv(v: glam::Vec3) -> rp::Vector {
    rp::Vector::new(v.x, v.y, v.z)
}
fn gv(v: rp::Vector) -> glam::Vec3 {
    glam::Vec3::new(v.x, v.y, v.z)
}

/// A body's pose and velocities as rapier holds them.
fn pose_of(b: &rp::RigidBody) -> BodyPose {
    BodyPose {
        position: gv(b.translation()),
        rotation: glam::Quat::from_array(b.rotation().to_array()),
        velocity: gv(b.linvel()),
        angular_velocity: gv(b.angvel()),
    }
}

/// Put a body at pose `p` with its velocities (rapier's no-op for an unchanged value).
fn put_pose(b: &mut rp::RigidBody, p: &BodyPose) {
    b.set_translation(rv(p.position), true);
    b.set_rotation(rp::Rotation::from_array(p.rotation.to_array()), true);
    b.set_linvel(rv(p.velocity), true);
    b.set_angvel(rv(p.angular_velocity), true);
}

/// Thickness of the fixed slabs around the interior (m): thick enough that no body tunnels.
const SLAB: f32 = 1.0;

/// `RTMPM_KINEMATIC=rapier`: a world with no dynamic body is stepped through rapier's pipeline
/// as before [`RigidWorld::advance`]'s own integration of its kinematic bodies (for comparing
/// the two in one binary). Read once.
fn kinematic_through_rapier() -> bool {
    static RAPIER: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *RAPIER.get_or_init(|| std::env::var("RTMPM_KINEMATIC").is_ok_and(|v| v.trim() == "rapier"))
}

/// The bodies' rapier world.
pub struct RigidWorld {
    world: rp::PhysicsWorld,
    handles: Vec<rp::RigidBodyHandle>,
    specs: Vec<RigidBodySpec>,
    states: Vec<BodyState>,
    /// No dynamic body (decided once: the kinds never change) and `RTMPM_KINEMATIC` is not
    /// `rapier`: [`RigidWorld::advance`] moves the kinematic bodies by their velocities itself
    /// instead of stepping rapier's pipeline.
    kinematic_only: bool,
}

impl std::fmt::Debug for RigidWorld {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RigidWorld")
            .field("states", &self.states)
            .finish()
    }
}

impl RigidWorld {
    /// The world of `bodies` held by `joints` under `gravity`, boxed in by `interior` (the
    /// domain minus the walls); `None` without bodies.
    pub fn new(
        bodies: &[RigidBodySpec],
        joints: &[JointSpec],
        gravity: glam::Vec3,
        interior: (glam::Vec3, glam::Vec3),
    ) -> Result<Option<RigidWorld>, String> {
        if bodies.is_empty() {
            return Ok(None);
        }
        let mut world = rp::PhysicsWorld::new();
        world.gravity = rv(gravity);
        let (lo, hi) = interior;
        let mid = 0.5 * (lo + hi);
        let half = 0.5 * (hi - lo) + glam::Vec3::splat(SLAB);
        for axis in 0..3 {
            for side in [-1.0f32, 1.0] {
                let mut h = half;
                h[axis] = 0.5 * SLAB;
                let mut c = mid;
                c[axis] = if side < 0.0 {
                    lo[axis] - 0.5 * SLAB
                } else {
                    hi[axis] + 0.5 * SLAB
                };
                world.insert_collider(
                    rp::ColliderBuilder::cuboid(h.x, h.y, h.z).translation(rv(c)),
                    None,
                );
            }
        }
        let mut handles = Vec::new();
        for b in bodies {
            let builder = match b.kind {
                RigidKind::Dynamic => rp::RigidBodyBuilder::dynamic(),
                RigidKind::Kinematic => rp::RigidBodyBuilder::kinematic_velocity_based(),
                RigidKind::Fixed => rp::RigidBodyBuilder::fixed(),
            };
            let (axis, angle) = b.rotation.to_axis_angle();
            let body = builder
                .translation(rv(b.position))
                .rotation(rv(axis * angle))
                .linvel(rv(b.velocity))
                .angvel(rv(b.angular_velocity))
                .can_sleep(false);
            let collider = collider(b)?;
            let (handle, _) = world.insert(body, collider);
            handles.push(handle);
        }
        insert_joints(&mut world, bodies, &handles, joints);
        let mut w = RigidWorld {
            world,
            handles,
            specs: bodies.to_vec(),
            states: Vec::new(),
            kinematic_only: bodies.iter().all(|b| b.kind != RigidKind::Dynamic)
                && !kinematic_through_rapier(),
        };
        w.refresh();
        Ok(Some(w))
    }

    /// The bodies' states for the grid from rapier's bodies (in place once they exist).
    fn refresh(&mut self) {
        if self.states.len() != self.handles.len() {
            // The shapes once (they never change); the moving fields just below.
            self.states = self
                .specs
                .iter()
                .map(|s| BodyState {
                    shape: s.shape.clone(),
                    rotation: glam::Mat3::IDENTITY,
                    center: glam::Vec3::ZERO,
                    velocity: glam::Vec3::ZERO,
                    angular_velocity: glam::Vec3::ZERO,
                    dynamic: s.kind == RigidKind::Dynamic,
                    condition: s.condition,
                    friction: s.friction,
                })
                .collect();
        }
        for (&h, state) in self.handles.iter().zip(&mut self.states) {
            let b = &self.world.bodies[h];
            state.rotation = glam::Mat3::from_quat(glam::Quat::from_array(b.rotation().to_array()));
            state.center = gv(b.center_of_mass());
            state.velocity = gv(b.linvel());
            state.angular_velocity = gv(b.angvel());
        }
    }

    /// Change gravity from the next advance on.
    pub fn set_gravity(&mut self, gravity: glam::Vec3) {
        self.world.gravity = rv(gravity);
    }

    /// Mass (kg) and principal moments of inertia (kg m^2, ascending) of body `i` as the
    /// engine holds them.
    pub fn mass_properties(&self, i: usize) -> Option<(f32, glam::Vec3)> {
        let b = &self.world.bodies[*self.handles.get(i)?];
        let m = b.mass_properties().local_mprops;
        let mut p = gv(m.principal_inertia()).to_array();
        p.sort_by(f32::total_cmp);
        Some((m.mass(), glam::Vec3::from_array(p)))
    }

    /// Every body's state at the current time.
    pub fn states(&self) -> &[BodyState] {
        &self.states
    }

    /// Every body's pose and velocities as rapier holds them (for checkpoints).
    pub fn poses(&self) -> Vec<BodyPose> {
        let mut out = Vec::with_capacity(self.handles.len());
        self.poses_into(&mut out);
        out
    }

    /// Put every body at `poses` (one per body, in the scene's order, as [`RigidWorld::poses`]
    /// gave them): resuming a checkpoint. What rapier keeps besides the bodies is not restored:
    /// the contacts' cached impulses (the solver's warm start), which the next step rebuilds
    /// from zero, so bodies in contact at the checkpoint continue slightly differently from an
    /// uninterrupted run; bodies not touching anything continue identically.
    pub fn set_poses(&mut self, poses: &[BodyPose]) -> Result<(), String> {
        if poses.len() != self.handles.len() {
            return Err(format!(
                "{} rigid-body states for the scene's {} rigid bodies",
                poses.len(),
                self.handles.len()
            ));
        }
        for (&h, p) in self.handles.iter().zip(poses) {
            put_pose(&mut self.world.bodies[h], p);
        }
        self.refresh();
        Ok(())
    }

    /// Body `i`'s pose and velocities as rapier holds them (one of [`RigidWorld::poses`],
    /// without building the others); `None` past the last body.
    pub fn pose(&self, i: usize) -> Option<BodyPose> {
        let &h = self.handles.get(i)?;
        Some(pose_of(&self.world.bodies[h]))
    }

    /// Every body's pose and velocities into `out` (emptied first): [`RigidWorld::poses`]
    /// without a new vector.
    pub fn poses_into(&self, out: &mut Vec<BodyPose>) {
        out.clear();
        out.extend(self.handles.iter().map(|&h| pose_of(&self.world.bodies[h])));
    }

    /// Put body `i` at `pose`, the others where they are: exactly what
    /// [`RigidWorld::set_poses`] of [`RigidWorld::poses`] with row `i` replaced does (every
    /// body set again, rapier's no-op for an unchanged value), without building either vector
    /// (a script posing one body of many worlds: a batch's tool).
    pub fn set_pose(&mut self, i: usize, pose: &BodyPose) -> Result<(), String> {
        if i >= self.handles.len() {
            return Err(format!(
                "rigid body {i}: the scene has {} rigid bodies",
                self.handles.len()
            ));
        }
        for (j, &h) in self.handles.iter().enumerate() {
            let b = &mut self.world.bodies[h];
            let p = if j == i { *pose } else { pose_of(b) };
            put_pose(b, &p);
        }
        self.refresh();
        Ok(())
    }

    /// Every advance of this world through rapier's step, also without a dynamic body (what
    /// `RTMPM_KINEMATIC=rapier` does for every world; for comparisons in one binary).
    pub fn with_rapier_steps(mut self) -> RigidWorld {
        self.kinematic_only = false;
        self
    }

    /// This world's advance moves its kinematic bodies itself, without rapier's step (no
    /// dynamic body, `RTMPM_KINEMATIC` not `rapier`; see [`RigidWorld::advance`]).
    pub fn kinematic_only(&self) -> bool {
        self.kinematic_only
    }

    /// Give each dynamic body the impulses the grid gave it this step, then advance the world
    /// by `dt` (gravity, contacts).
    ///
    /// A world with no dynamic body ([`RigidWorld::kinematic_only`]) is not stepped through
    /// rapier's pipeline (broad and narrow phase, islands, the solver's substeps): rapier
    /// computes no contact between kinematic and fixed bodies, nothing pushes a kinematic body,
    /// joints then constrain nothing and no contact event is read, so such a step only moves
    /// each kinematic body by its velocities. That is done here ([`advance_kinematic`]): the
    /// pose rotated about the centre of mass by `angular_velocity * dt`, then translated by
    /// `velocity * dt` (rapier's exact form, `RigidBodyVelocity::integrate`), the rotation
    /// renormalised; the velocities are kept. rapier's step integrates the same motion in its
    /// solver's substeps with a linearised rotation, renormalised every substep, so the two
    /// differ in the last bits (tested: `the_fast_path_follows_rapiers_step`); rapier's speed
    /// caps (400 m/s, a turn of pi/4 a step) are not applied. The colliders are not moved with
    /// their bodies (nothing here reads them: no scene queries, no contacts). Every consumer
    /// (single runs on the CPU and GPU, the CPU and GPU batches) advances through here, so a
    /// batch's worlds stay bit for bit their separate runs. `RTMPM_KINEMATIC=rapier` steps
    /// such worlds through rapier as before.
    pub fn advance(&mut self, exchange: &[Exchange], dt: f32) {
        self.world.integration_parameters.dt = dt;
        if self.kinematic_only {
            advance_kinematic(&mut self.world.bodies, &self.handles, &self.specs, dt);
            self.refresh();
            return;
        }
        for ((&h, s), e) in self.handles.iter().zip(&self.specs).zip(exchange) {
            if s.kind != RigidKind::Dynamic {
                continue;
            }
            let b = &mut self.world.bodies[h];
            let f = |a: [f64; 3]| rp::Vector::new(a[0] as f32, a[1] as f32, a[2] as f32);
            b.apply_impulse(f(e.impulse), true);
            b.apply_torque_impulse(f(e.torque), true);
        }
        self.world.step();
        self.refresh();
    }
}

/// Each kinematic body of `handles` (kinds `specs`) moved by its velocities over `dt`: rotated
/// about its centre of mass by `angvel * dt`, then translated by `linvel * dt` (rapier's
/// `RigidBodyVelocity::integrate`, the exact rotation), the rotation renormalised (rapier's
/// step renormalises after each substep; without it the rounding of many steps' products
/// would drift its norm). A body with both velocities zero, or a zero `dt`, is left as it is,
/// bit for bit; without angular velocity the rotation is kept as it is.
fn advance_kinematic(
    bodies: &mut rp::RigidBodySet,
    handles: &[rp::RigidBodyHandle],
    specs: &[RigidBodySpec],
    dt: f32,
) {
    for (&h, s) in handles.iter().zip(specs) {
        if s.kind != RigidKind::Kinematic {
            continue;
        }
        let b = &bodies[h];
        let vels = *b.vels();
        if dt == 0.0 || (vels.linvel == rp::Vector::ZERO && vels.angvel == rp::Vector::ZERO) {
            continue;
        }
        let mut pose = vels.integrate(dt, b.position(), &b.local_center_of_mass());
        pose.rotation = if vels.angvel == rp::Vector::ZERO {
            *b.rotation()
        } else {
            pose.rotation.normalize()
        };
        // Moves the body's pose (and its world centre of mass), keeps its velocities.
        bodies[h].set_position(pose, false);
    }
}

/// The engine's collider of body `b`: its shape (in the body frame) with its mass.
fn collider(b: &RigidBodySpec) -> Result<rp::ColliderBuilder, String> {
    Ok(match &b.shape {
        Shape::Box(c) => {
            let h = c.half_size();
            rp::ColliderBuilder::cuboid(h.x, h.y, h.z).mass(b.mass)
        }
        Shape::Sphere(s) => rp::ColliderBuilder::ball(s.radius).mass(b.mass),
        // rapier's cylinders are along their local y, as ours in the body frame.
        Shape::Cylinder(c) => rp::ColliderBuilder::cylinder(c.half_height, c.radius).mass(b.mass),
        Shape::Mesh(m) => match &m.solid {
            Some(solid) => mesh_collider(&b.name, solid, b.mass)?,
            None => {
                return Err(format!(
                    "rigid body `{}`: its mesh is not a closed solid",
                    b.name
                ));
            }
        },
        s @ (Shape::HalfSpace(_) | Shape::Particles(_)) => {
            return Err(format!(
                "rigid body `{}`: {} cannot be a rigid body",
                b.name,
                s.info().noun
            ));
        }
    })
}

/// The engine's collider of a mesh body: its convex hull (`convex = true`) or the triangle mesh,
/// with the mass, centre of mass (the body's origin) and inertia tensor of the closed mesh's
/// solid (rapier's own mass properties of a triangle mesh are not those of the solid).
fn mesh_collider(
    name: &str,
    m: &rtmpm_geometry::RigidMesh,
    mass: f32,
) -> Result<rp::ColliderBuilder, String> {
    let points: Vec<rp::Vector> = m.mesh.vertices.iter().map(|v| rv(*v)).collect();
    let builder = if m.convex {
        rp::ColliderBuilder::convex_hull(&points).ok_or_else(|| {
            format!("rigid body `{name}`: no convex hull of its mesh (degenerate points)")
        })?
    } else {
        rp::ColliderBuilder::trimesh(points, m.mesh.triangles.clone()).map_err(|e| {
            format!("rigid body `{name}`: its mesh is not a valid triangle mesh: {e}")
        })?
    };
    let inertia = m.unit_inertia * (mass / m.volume);
    let inertia = rp::Matrix::from_cols_array(&inertia.to_cols_array());
    Ok(
        builder.mass_properties(rp::MassProperties::with_inertia_matrix(
            rp::Vector::ZERO,
            mass,
            inertia,
        )),
    )
}

/// rapier's pose of a body placed at `position` turned by `rotation`.
fn pose(position: glam::Vec3, rotation: glam::Quat) -> rp::Pose {
    rp::Pose::from_parts(rv(position), rp::Rotation::from_array(rotation.to_array()))
}

/// Each joint as a rapier impulse joint. The joint's frame in the world at t = 0 has its origin
/// at the anchor and its x axis along the hinge or slide axis (rapier's revolute joint turns
/// about the frame's x, its prismatic joint slides along it); each body carries that frame in
/// its own coordinates from then on. A joint to the world holds the body to a fixed body with no
/// collider at the world's origin. Contacts between jointed bodies are off (rapier's default).
fn insert_joints(
    world: &mut rp::PhysicsWorld,
    bodies: &[RigidBodySpec],
    handles: &[rp::RigidBodyHandle],
    joints: &[JointSpec],
) {
    if joints.is_empty() {
        return;
    }
    let ground = world.insert_body(rp::RigidBodyBuilder::fixed());
    for j in joints {
        let axis = match j.kind {
            JointKind::Revolute { axis, .. } | JointKind::Prismatic { axis, .. } => axis,
            JointKind::Fixed | JointKind::Spherical => glam::Vec3::X,
        };
        let frame = (j.anchor, glam::Quat::from_rotation_arc(glam::Vec3::X, axis));
        let local = |b: Option<usize>| {
            let (p, q) = b.map_or((glam::Vec3::ZERO, glam::Quat::IDENTITY), |b| {
                (bodies[b].position, bodies[b].rotation)
            });
            pose(q.inverse() * (frame.0 - p), q.inverse() * frame.1)
        };
        let (locked, limits) = match j.kind {
            JointKind::Fixed => (rp::JointAxesMask::LOCKED_FIXED_AXES, None),
            JointKind::Spherical => (rp::JointAxesMask::LOCKED_SPHERICAL_AXES, None),
            JointKind::Revolute { limits, .. } => (
                rp::JointAxesMask::LOCKED_REVOLUTE_AXES,
                limits.map(|l| (rp::JointAxis::AngX, l)),
            ),
            JointKind::Prismatic { limits, .. } => (
                rp::JointAxesMask::LOCKED_PRISMATIC_AXES,
                limits.map(|l| (rp::JointAxis::LinX, l)),
            ),
        };
        let mut builder = rp::GenericJointBuilder::new(locked)
            .local_frame1(local(j.to))
            .local_frame2(local(Some(j.body)));
        if let Some((axis, l)) = limits {
            builder = builder.limits(axis, l);
        }
        let h1 = j.to.map_or(ground, |b| handles[b]);
        world.insert_impulse_joint(h1, handles[j.body], builder.build());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Quat, Vec3};
    use rtmpm_geometry::shape::Cuboid;
    use rtmpm_physics::boundary::Condition;

    fn body(name: &str, kind: RigidKind, position: Vec3, velocity: Vec3) -> RigidBodySpec {
        RigidBodySpec {
            name: name.into(),
            shape: Shape::Box(Cuboid::centred(Vec3::ZERO, Vec3::splat(0.05))),
            kind,
            mass: 1.0,
            position,
            rotation: Quat::IDENTITY,
            velocity,
            angular_velocity: Vec3::ZERO,
            condition: Condition::Slip,
            friction: 0.0,
        }
    }

    /// A world of a kinematic tool, a dynamic box falling onto the floor and a fixed block.
    fn world() -> RigidWorld {
        let bodies = [
            body(
                "tool",
                RigidKind::Kinematic,
                Vec3::new(0.5, 0.7, 0.5),
                Vec3::new(0.0, -0.2, 0.0),
            ),
            body(
                "box",
                RigidKind::Dynamic,
                Vec3::new(0.3, 0.07, 0.3),
                Vec3::new(0.1, 0.0, 0.0),
            ),
            body(
                "block",
                RigidKind::Fixed,
                Vec3::new(0.8, 0.2, 0.8),
                Vec3::ZERO,
            ),
        ];
        let interior = (Vec3::ZERO, Vec3::ONE);
        RigidWorld::new(&bodies, &[], Vec3::new(0.0, -9.81, 0.0), interior)
            .expect("world")
            .expect("bodies")
    }

    fn bits(w: &RigidWorld) -> Vec<u32> {
        let mut out = Vec::new();
        for p in w.poses() {
            out.extend(p.position.to_array().map(f32::to_bits));
            out.extend(p.rotation.to_array().map(f32::to_bits));
            out.extend(p.velocity.to_array().map(f32::to_bits));
            out.extend(p.angular_velocity.to_array().map(f32::to_bits));
        }
        for s in w.states() {
            out.extend(s.rotation.to_cols_array().map(f32::to_bits));
            out.extend(s.center.to_array().map(f32::to_bits));
            out.extend(s.velocity.to_array().map(f32::to_bits));
            out.extend(s.angular_velocity.to_array().map(f32::to_bits));
        }
        out
    }

    /// One body posed with `set_pose` gives bit for bit what `set_poses` of every body's pose with
    /// its row replaced gives, then and over the steps after (the dynamic box posed onto the floor
    /// at 0.3 m/s down, in contact with it); `pose(i)` is row `i` of `poses()`, `poses_into` is
    /// `poses()`.
    #[test]
    fn setting_one_body_is_setting_every_pose_with_its_row_replaced() {
        let (mut a, mut b) = (world(), world());
        let none = vec![Exchange::default(); 3];
        for step in 0..40 {
            if step % 7 == 3 {
                let i = (step / 7) % 3;
                let mut pose = a.pose(i).expect("body i");
                pose.position += Vec3::new(0.01, -0.02, 0.005);
                pose.rotation = Quat::from_rotation_y(0.1 * step as f32);
                if i != 2 {
                    pose.velocity = Vec3::new(0.0, -0.3, 0.05 * step as f32);
                    pose.angular_velocity = Vec3::new(0.0, 1.0, 0.0);
                }
                let mut all = a.poses();
                all[i] = pose;
                a.set_poses(&all).expect("set_poses");
                b.set_pose(i, &pose).expect("set_pose");
                assert_eq!(bits(&a), bits(&b), "step {step}: after posing body {i}");
            }
            a.advance(&none, 1e-3);
            b.advance(&none, 1e-3);
            assert_eq!(bits(&a), bits(&b), "step {step}");
        }
        let all = a.poses();
        // The floor held the box (posed 2 cm into it at 0.3 m/s down at steps 10 and 31, free
        // fall would leave its centre near 0.021 m): the steps compared had contacts.
        assert!(all[1].position.y > 0.028, "box at {}", all[1].position);
        for (i, p) in all.iter().enumerate() {
            assert_eq!(a.pose(i).as_ref(), Some(p));
        }
        assert!(a.pose(3).is_none());
        let mut into = vec![all[0]; 7];
        a.poses_into(&mut into);
        assert_eq!(into, all);
        let err = b.set_pose(3, &all[0]).expect_err("no body 3");
        assert!(err.contains("rigid body 3: the scene has 3"), "{err}");
    }

    /// Where body `i`'s collider is in rapier's collider set (moved only by rapier's step).
    fn collider_at(w: &RigidWorld, i: usize) -> Vec3 {
        let b = &w.world.bodies[w.handles[i]];
        gv(w.world.colliders[b.colliders()[0]].position().translation)
    }

    /// Bodies of the kinematic-only worlds: a translating kinematic box, a turned one that
    /// turns about an axis off its own while it translates, a fixed block and a kinematic box
    /// standing still.
    fn tools() -> Vec<RigidBodySpec> {
        let mut spin = body(
            "spin",
            RigidKind::Kinematic,
            Vec3::new(0.4, 0.5, 0.6),
            Vec3::new(0.05, 0.0, -0.02),
        );
        spin.rotation = Quat::from_rotation_x(0.4);
        spin.angular_velocity = Vec3::new(0.5, 3.0, 1.0);
        vec![
            body(
                "slide",
                RigidKind::Kinematic,
                Vec3::new(0.5, 0.7, 0.5),
                Vec3::new(0.3, -0.2, 0.1),
            ),
            spin,
            body(
                "block",
                RigidKind::Fixed,
                Vec3::new(0.8, 0.2, 0.8),
                Vec3::ZERO,
            ),
            body(
                "still",
                RigidKind::Kinematic,
                Vec3::new(0.2, 0.3, 0.2),
                Vec3::ZERO,
            ),
        ]
    }

    fn tool_world() -> RigidWorld {
        let interior = (Vec3::ZERO, Vec3::ONE);
        RigidWorld::new(&tools(), &[], Vec3::new(0.0, -9.81, 0.0), interior)
            .expect("world")
            .expect("bodies")
    }

    /// A world of kinematic and fixed bodies advanced by its own integration follows rapier's
    /// step of the same world over 100 steps of 1 ms: a translating box, a box turning 3.2
    /// rad/s about an axis off its own while translating, a pose given to one body between
    /// steps (`set_pose`) and to every body (`set_poses`, the turning box given another angular
    /// velocity); the velocities stay bit for bit, the fixed block and the box standing still
    /// do not move by a bit, and rapier's colliders stay where they were (its step never ran).
    /// Not bit for bit: rapier integrates in 4 substeps with a linearised rotation. Its
    /// linearisation (a substep's turn 2 atan(w h / 2) for w h, h = dt / 4) errs by
    /// (w h)^3 / 12 = 4e-14 rad a substep, nothing in f32; what differs is rounding: 4
    /// additions of v h a step against one of v dt (each rounding at most half an ulp of a
    /// coordinate below 1 m, 3e-8 m: 1.5e-7 m a step, 1.5e-5 m over 100 steps at worst), and
    /// 4 quaternion products and normalisations against one (a few ulps of a unit quaternion,
    /// 2.4e-7 each: 1.2e-6 rad a step, 1.2e-4 rad over 100 steps at worst); the bounds below
    /// are those worst cases. Against the exact motion: the sliding box at its start plus
    /// `v t` to 1e-5 m.
    #[test]
    fn the_fast_path_follows_rapiers_step() {
        let (mut a, mut b) = (tool_world(), tool_world().with_rapier_steps());
        assert!(a.kinematic_only() || kinematic_through_rapier());
        assert!(!b.kinematic_only());
        let none = vec![Exchange::default(); 4];
        let dt = 1e-3;
        let start = a.poses();
        let colliders: Vec<Vec3> = (0..4).map(|i| collider_at(&a, i)).collect();
        let (mut max_dx, mut max_da) = (0.0f32, 0.0f32);
        let mut posed_at = (0, start[0].position, start[0].velocity);
        for step in 0..100 {
            if step == 50 {
                let mut p = a.pose(0).expect("slide");
                p.position += Vec3::new(-0.1, 0.05, 0.0);
                p.velocity = Vec3::new(-0.2, 0.0, 0.25);
                a.set_pose(0, &p).expect("pose");
                b.set_pose(0, &p).expect("pose");
                posed_at = (step, p.position, p.velocity);
            }
            if step == 70 {
                let mut all = a.poses();
                all[1].rotation = Quat::from_rotation_z(-0.7);
                all[1].angular_velocity = Vec3::new(-2.0, 0.0, 1.5);
                a.set_poses(&all).expect("poses");
                b.set_poses(&all).expect("poses");
            }
            a.advance(&none, dt);
            b.advance(&none, dt);
            for (i, (p, q)) in a.poses().iter().zip(b.poses()).enumerate() {
                max_dx = max_dx.max((p.position - q.position).abs().max_element());
                max_da = max_da.max(turn(p.rotation, q.rotation));
                assert_eq!(p.velocity, q.velocity, "step {step}: body {i}");
                assert_eq!(
                    p.angular_velocity, q.angular_velocity,
                    "step {step}: body {i}"
                );
                assert!(p.rotation.is_normalized(), "step {step}: body {i}");
            }
            for (i, s) in a.states().iter().enumerate() {
                let p = a.pose(i).expect("body");
                assert_eq!(s.center, p.position, "step {step}: body {i}'s centre");
                let r = glam::Mat3::from_quat(p.rotation);
                assert_eq!(s.rotation, r, "step {step}: body {i}'s rotation");
            }
            let p = a.pose(0).expect("slide");
            let t = (step + 1 - posed_at.0) as f32 * dt;
            let exact = posed_at.1 + posed_at.2 * t;
            assert!(
                (p.position - exact).abs().max_element() < 1e-5,
                "step {step}: the sliding box at {} for {exact}",
                p.position
            );
        }
        println!("fast path against rapier's step: {max_dx:e} m, {max_da:e} rad at most");
        assert!(max_dx <= 1.5e-5, "positions apart by {max_dx} m");
        assert!(max_da <= 1.2e-4, "rotations apart by {max_da} rad");
        // The turning box turned (0.3 rad before step 70 at 3.2 rad/s): compared at all.
        assert!(start[1].rotation.angle_between(a.poses()[1].rotation) > 0.5);
        let end = a.poses();
        for i in [2, 3] {
            assert_eq!(bits_of(&end[i]), bits_of(&start[i]), "body {i} moved");
        }
        for (i, c) in colliders.iter().enumerate() {
            if a.kinematic_only() {
                assert_eq!(collider_at(&a, i), *c, "collider {i}: rapier stepped");
            }
        }
        assert_ne!(
            collider_at(&b, 0),
            colliders[0],
            "rapier's step moves colliders"
        );
    }

    /// The angle of the turn from `a` to `b` (rad), precise for small turns (glam's
    /// `angle_between`, an arc cosine of their dot product, reads one ulp of it as 5e-4 rad).
    fn turn(a: Quat, b: Quat) -> f32 {
        2.0 * (a.inverse() * b).xyz().length().min(1.0).asin()
    }

    fn bits_of(p: &BodyPose) -> Vec<u32> {
        let all = p.position.to_array().into_iter();
        let all = all
            .chain(p.rotation.to_array())
            .chain(p.velocity.to_array());
        all.chain(p.angular_velocity.to_array())
            .map(f32::to_bits)
            .collect()
    }

    /// A world with a dynamic body is stepped through rapier: its box, dropped from 0.4 m,
    /// falls under gravity and comes to rest on the floor slab (its centre at its half size,
    /// 0.05 m), while the kinematic tool in it moves by its velocity.
    #[test]
    fn a_world_with_a_dynamic_body_steps_through_rapier() {
        let mut bodies = tools();
        bodies.push(body(
            "box",
            RigidKind::Dynamic,
            Vec3::new(0.2, 0.4, 0.8),
            Vec3::ZERO,
        ));
        let interior = (Vec3::ZERO, Vec3::ONE);
        let mut w = RigidWorld::new(&bodies, &[], Vec3::new(0.0, -9.81, 0.0), interior)
            .expect("world")
            .expect("bodies");
        assert!(!w.kinematic_only());
        let none = vec![Exchange::default(); bodies.len()];
        let tool = collider_at(&w, 0);
        let mut lowest = f32::MAX;
        for _ in 0..600 {
            w.advance(&none, 1e-3);
            lowest = lowest.min(w.pose(4).expect("box").position.y);
        }
        let p = w.pose(4).expect("box");
        assert!(lowest > 0.045, "the box went through the floor: {lowest}");
        assert!((p.position.y - 0.05).abs() < 2e-3, "box at {}", p.position);
        assert!(p.velocity.length() < 0.05, "box moving at {}", p.velocity);
        let slide = w.pose(0).expect("slide").position;
        let exact = bodies[0].position + bodies[0].velocity * 0.6;
        assert!(
            (slide - exact).abs().max_element() < 1e-4,
            "tool at {slide}"
        );
        assert_ne!(collider_at(&w, 0), tool, "rapier's step moves colliders");
    }
}
