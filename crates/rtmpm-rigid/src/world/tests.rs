//! The rigid world's tests: one body posed as every body with its row replaced, a world without a
//! dynamic body advanced outside rapier's pipeline against rapier's own step, a world with one
//! still stepped by rapier.

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

/// A kinematic-only world advanced on its rows, rapier's bodies behind them, is the world whose
/// rapier bodies are moved at every step (`RTMPM_KINEMATIC=eager`, as before the rows) bit for
/// bit: every read (a pose, every pose, the states) at every step, and rapier's every body (all
/// its fields, as Debug prints them) once caught up, here and there over 100 steps of 1 ms of
/// the tool worlds (a translating box, a turning one, a fixed block, a box standing still), with
/// a pose given to one body (steps 30, 50) and to every body (step 70) between steps and reads.
#[test]
fn rows_ahead_of_rapier_are_rapiers_bodies_bit_for_bit() {
    let (mut a, mut b) = (tool_world(), tool_world());
    if !a.kinematic_only() {
        println!("skipped: RTMPM_KINEMATIC=rapier");
        return;
    }
    let dt = 1e-3;
    let state_bits = |w: &RigidWorld| -> Vec<u32> {
        w.states()
            .iter()
            .flat_map(|s| {
                let m = s.rotation.to_cols_array().into_iter();
                m.chain(s.center.to_array())
                    .chain(s.velocity.to_array())
                    .chain(s.angular_velocity.to_array())
            })
            .map(f32::to_bits)
            .collect()
    };
    let rapier = |w: &mut RigidWorld| -> Vec<String> {
        w.catch_up();
        let bodies = &w.world.bodies;
        w.handles
            .iter()
            .map(|&h| format!("{:?}", bodies[h]))
            .collect()
    };
    let mut behind = 0;
    for step in 0..100 {
        if step == 30 || step == 50 {
            let mut p = a.pose(1).expect("spin");
            p.position += Vec3::new(0.01, -0.02, 0.0);
            p.angular_velocity = Vec3::new(0.2 * step as f32, 1.0, 0.0);
            a.set_pose(1, &p).expect("pose");
            b.set_pose(1, &p).expect("pose");
        }
        if step == 70 {
            let mut all = b.poses();
            all[0].velocity = Vec3::new(-0.2, 0.0, 0.25);
            all[3].velocity = Vec3::new(0.0, 0.1, 0.0);
            a.set_poses(&all).expect("poses");
            b.set_poses(&all).expect("poses");
        }
        a.advance_own(dt, true);
        b.advance_own(dt, false);
        behind += usize::from(a.behind);
        assert!(!b.behind, "step {step}: the eager world is never behind");
        for i in 0..4 {
            let (p, q) = (a.pose(i).expect("body"), b.pose(i).expect("body"));
            assert_eq!(bits_of(&p), bits_of(&q), "step {step}: body {i}");
        }
        assert_eq!(
            a.poses().iter().map(bits_of).collect::<Vec<_>>(),
            b.poses().iter().map(bits_of).collect::<Vec<_>>(),
            "step {step}"
        );
        assert_eq!(state_bits(&a), state_bits(&b), "step {step}: the states");
        if step % 17 == 5 || step == 99 {
            assert_eq!(
                rapier(&mut a),
                rapier(&mut b),
                "step {step}: rapier's bodies"
            );
        }
    }
    assert!(
        behind > 50,
        "rapier's bodies behind at {behind} steps of 100"
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
