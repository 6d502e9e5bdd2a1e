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

/// `RTMPM_KINEMATIC=eager`: a kinematic-only world's advance moves rapier's bodies at every step
/// as before their rows ([`Ahead`]) went ahead of them (the same state bit for bit; for
/// comparing the two in one binary). Read once.
fn old_kinematic_rows() -> bool {
    static EAGER: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *EAGER.get_or_init(|| std::env::var("RTMPM_KINEMATIC").is_ok_and(|v| v.trim() == "eager"))
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
    /// A kinematic-only world's kinematic bodies as its advance moves them, ahead of rapier's
    /// (empty in other worlds; see [`Ahead`]).
    ahead: Vec<Option<Ahead>>,
    /// rapier's bodies are behind `ahead` (an advance moved it since they were last put in).
    behind: bool,
}

/// A kinematic body of a kinematic-only world as [`RigidWorld::advance`] moves it, kept beside
/// rapier's body (compact: one small row a body, where rapier's bodies lie in their set's
/// storage, hundreds of bytes each): its pose, velocities and centre of mass in its own frame.
/// The advance moves these and rewrites the body's state from them; rapier's body is given the
/// pose only when something reads or sets rapier's bodies ([`RigidWorld::catch_up`]), with the
/// same `set_position` the advance gave it at every step before: rapier keeps nothing of the
/// poses between (the setter overwrites the pose and derives the world mass properties from it;
/// the body's velocities and its own frame's mass properties do not change), so the world is
/// the same bit for bit. Reads of the poses come from these rows.
#[derive(Clone, Copy, Debug)]
struct Ahead {
    pos: rp::Pose,
    vels: rp::RigidBodyVelocity<f32>,
    local_com: rp::Vector,
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
            ahead: Vec::new(),
            behind: false,
        };
        w.reload_ahead();
        w.refresh();
        Ok(Some(w))
    }

    /// The bodies' states for the grid from rapier's bodies (in place once they exist).
    fn refresh(&mut self) {
        debug_assert!(!self.behind, "rapier's bodies behind their rows");
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

    /// The rows of the kinematic bodies (a kinematic-only world's; none otherwise) taken anew
    /// from rapier's bodies (which are not behind: at the world's making, after a setter).
    fn reload_ahead(&mut self) {
        debug_assert!(!self.behind, "rapier's bodies behind their rows");
        self.ahead.clear();
        if !self.kinematic_only {
            return;
        }
        let bodies = &self.world.bodies;
        self.ahead
            .extend(self.handles.iter().zip(&self.specs).map(|(&h, s)| {
                (s.kind == RigidKind::Kinematic).then(|| Ahead {
                    pos: *bodies[h].position(),
                    vels: *bodies[h].vels(),
                    local_com: bodies[h].local_center_of_mass(),
                })
            }));
    }

    /// rapier's bodies given the poses the advance moved their rows to (each moved body
    /// `set_position` as the advance did before at every step: see [`Ahead`]).
    fn catch_up(&mut self) {
        if !self.behind {
            return;
        }
        for (&h, a) in self.handles.iter().zip(&self.ahead) {
            if let Some(a) = a {
                // Moves the body's pose (and its world centre of mass), keeps its velocities.
                self.world.bodies[h].set_position(a.pos, false);
            }
        }
        self.behind = false;
    }

    /// Body `i`'s pose and velocities: its row where it has one (a kinematic body of a
    /// kinematic-only world), else rapier's.
    fn pose_at(&self, i: usize, h: rp::RigidBodyHandle) -> BodyPose {
        match self.ahead.get(i) {
            Some(Some(a)) => BodyPose {
                position: gv(a.pos.translation),
                rotation: glam::Quat::from_array(a.pos.rotation.to_array()),
                velocity: gv(a.vels.linvel),
                angular_velocity: gv(a.vels.angvel),
            },
            _ => pose_of(&self.world.bodies[h]),
        }
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
        self.catch_up();
        for (&h, p) in self.handles.iter().zip(poses) {
            put_pose(&mut self.world.bodies[h], p);
        }
        self.reload_ahead();
        self.refresh();
        Ok(())
    }

    /// Body `i`'s pose and velocities as rapier holds them (one of [`RigidWorld::poses`],
    /// without building the others); `None` past the last body.
    pub fn pose(&self, i: usize) -> Option<BodyPose> {
        let &h = self.handles.get(i)?;
        Some(self.pose_at(i, h))
    }

    /// Every body's pose and velocities into `out` (emptied first): [`RigidWorld::poses`]
    /// without a new vector.
    pub fn poses_into(&self, out: &mut Vec<BodyPose>) {
        out.clear();
        let all = self.handles.iter().enumerate();
        out.extend(all.map(|(i, &h)| self.pose_at(i, h)));
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
        self.catch_up();
        for (j, &h) in self.handles.iter().enumerate() {
            let b = &mut self.world.bodies[h];
            let p = if j == i { *pose } else { pose_of(b) };
            put_pose(b, &p);
        }
        self.reload_ahead();
        self.refresh();
        Ok(())
    }

    /// Every advance of this world through rapier's step, also without a dynamic body (what
    /// `RTMPM_KINEMATIC=rapier` does for every world; for comparisons in one binary).
    pub fn with_rapier_steps(mut self) -> RigidWorld {
        self.catch_up();
        self.kinematic_only = false;
        self.reload_ahead();
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
    /// differ in the last bits (tested: `the_fast_path_follows_rapiers_step`). The integration
    /// moves each kinematic body's row ([`Ahead`]: pose, velocities, centre of mass in its frame,
    /// beside rapier's body) and rapier's body is given that pose only when something reads or
    /// sets rapier's bodies, with the `set_position` each step gave it before: the same world bit
    /// for bit (`rows_ahead_of_rapier_are_rapiers_bodies_bit_for_bit`), without a look at
    /// rapier's bodies a step; `RTMPM_KINEMATIC=eager` moves rapier's bodies at every step as
    /// before (the A/B). rapier's speed
    /// caps (400 m/s, a turn of pi/4 a step) are not applied. The colliders are not moved with
    /// their bodies (nothing here reads them: no scene queries, no contacts). Every consumer
    /// (single runs on the CPU and GPU, the CPU and GPU batches) advances through here, so a
    /// batch's worlds stay bit for bit their separate runs. `RTMPM_KINEMATIC=rapier` steps
    /// such worlds through rapier as before.
    pub fn advance(&mut self, exchange: &[Exchange], dt: f32) {
        self.world.integration_parameters.dt = dt;
        if self.kinematic_only {
            self.advance_own(dt, !old_kinematic_rows());
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

impl RigidWorld {
    /// A kinematic-only world's advance by its own integration: on the kinematic bodies' rows,
    /// rapier's bodies left behind (`rows`), or on rapier's bodies as before
    /// (`RTMPM_KINEMATIC=eager`); the same state bit for bit.
    fn advance_own(&mut self, dt: f32, rows: bool) {
        if rows {
            self.advance_rows(dt);
        } else {
            self.catch_up();
            advance_kinematic(&mut self.world.bodies, &self.handles, &self.specs, dt);
            self.reload_ahead();
            self.refresh();
        }
    }

    /// [`advance_kinematic`] of a kinematic-only world on its rows ([`Ahead`]), rapier's bodies
    /// left behind: each moving kinematic body's row moved by the same integration, its state's
    /// rotation and centre rewritten as [`RigidWorld::refresh`] derives them from rapier's body
    /// after that `set_position` (the rotation matrix of the pose's rotation; the centre of mass
    /// `pose * local_com`, parry's `MassProperties::world_com`); velocities, fixed bodies and
    /// bodies standing still unchanged, as there.
    fn advance_rows(&mut self, dt: f32) {
        for (a, state) in self.ahead.iter_mut().zip(&mut self.states) {
            let Some(a) = a else { continue };
            let vels = a.vels;
            if dt == 0.0 || (vels.linvel == rp::Vector::ZERO && vels.angvel == rp::Vector::ZERO) {
                continue;
            }
            let mut pose = vels.integrate(dt, &a.pos, &a.local_com);
            pose.rotation = if vels.angvel == rp::Vector::ZERO {
                a.pos.rotation
            } else {
                pose.rotation.normalize()
            };
            a.pos = pose;
            self.behind = true;
            state.rotation =
                glam::Mat3::from_quat(glam::Quat::from_array(pose.rotation.to_array()));
            state.center = gv(world_com(&pose, a.local_com));
        }
    }
}

/// The world centre of mass of a body at `pos` whose centre of mass in its own frame is
/// `local_com`: parry's `MassProperties::world_com`, the same expression.
fn world_com(pos: &rp::Pose, local_com: rp::Vector) -> rp::Vector {
    pos * local_com
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
mod tests;
