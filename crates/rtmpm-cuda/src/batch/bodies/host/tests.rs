//! Tests of the host's rigid worlds of a GPU batch (`HostBodies`): the kept poses, the rows, the
//! worlds at rest, the spread of the advance over the cores; the timings are in [`timing`].

use super::*;
use glam::{Quat, Vec3};
use rtmpm_geometry::Shape;
use rtmpm_geometry::shape::Cuboid;
use rtmpm_physics::boundary::Condition;
use rtmpm_rigid::{RigidBodySpec, RigidKind};

fn body(kind: RigidKind, position: Vec3, velocity: Vec3) -> RigidBodySpec {
    RigidBodySpec {
        name: format!("{kind:?}"),
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

/// World `w` of `n`: a kinematic tool, a dynamic box falling onto the floor and a fixed
/// block (`all`), or the tool alone.
fn world(w: usize, all: bool) -> RigidWorld {
    let x = 0.2 + 0.01 * (w % 7) as f32;
    let mut bodies = vec![body(
        RigidKind::Kinematic,
        Vec3::new(x, 0.7, 0.5),
        Vec3::new(0.0, -0.2, 0.0),
    )];
    if all {
        bodies.push(body(
            RigidKind::Dynamic,
            Vec3::new(0.3, 0.07 + 0.001 * w as f32, 0.3),
            Vec3::new(0.1, 0.0, 0.0),
        ));
        bodies.push(body(RigidKind::Fixed, Vec3::new(0.8, 0.2, 0.8), Vec3::ZERO));
    }
    let interior = (Vec3::ZERO, Vec3::ONE);
    RigidWorld::new(&bodies, &[], Vec3::new(0.0, -9.81, 0.0), interior)
        .expect("world")
        .expect("bodies")
}

fn pose_bits(p: &BodyPose) -> [u32; 13] {
    let mut out = [0; 13];
    let all = p
        .position
        .to_array()
        .into_iter()
        .chain(p.rotation.to_array());
    let all = all
        .chain(p.velocity.to_array())
        .chain(p.angular_velocity.to_array());
    for (o, v) in out.iter_mut().zip(all) {
        *o = v.to_bits();
    }
    out
}

fn state_bits(s: &[BodyState]) -> Vec<u32> {
    s.iter()
        .flat_map(|s| {
            let m = s.rotation.to_cols_array().into_iter();
            m.chain(s.center.to_array())
                .chain(s.velocity.to_array())
                .chain(s.angular_velocity.to_array())
        })
        .map(f32::to_bits)
        .collect()
}

/// The batch's bodies as they were before the rows: the rapier worlds, each pose put at once,
/// the records encoded from the states at the upload.
struct Plain(Vec<RigidWorld>, Vec<u32>);

impl Plain {
    fn records(&self) -> Vec<u8> {
        let recs: Vec<GpuBody> = self
            .0
            .iter()
            .flat_map(|w| w.states().iter().enumerate())
            .map(|(i, b)| crate::step::rigid::encode(b, self.1[i]))
            .collect();
        bytemuck::cast_slice(&recs).to_vec()
    }
}

/// Each world's pose of `body` at a call `c`: a little lower, its velocity from the call
/// (signed zeros and repeats of the pose it has among them).
fn posed(now: BodyPose, w: usize, c: usize) -> BodyPose {
    let mut p = now;
    if !c.is_multiple_of(3) {
        p.position.y -= 1e-4 * (1 + w % 3) as f32;
        p.velocity = Vec3::new(0.01 * (w % 4) as f32, -0.2 - 0.01 * c as f32, -0.0);
    }
    if c % 4 == 1 {
        p.rotation = Quat::from_rotation_y(0.01 * (c + w) as f32);
        p.angular_velocity = Vec3::new(0.0, 0.3, 0.0);
    }
    p
}

/// Kept poses, put in on every core (`body_poses=deferred`) or on one thread
/// (`deferred_serial`), and poses put in at once (`eager`), give every
/// read (a body's pose, a world's poses, the states), every device record and every step's
/// result bit for bit as the rapier worlds posed at once did before the rows: 40 worlds of a
/// kinematic tool, a dynamic box on the floor and a fixed block over 60 steps, posed in every
/// world (the flush on every core), in a few (the flush on one thread), the same body twice
/// before a step with a read between, two bodies before a step, a world's every body put
/// (a reset) over kept poses, reads of other bodies while poses are kept, the box moved by
/// impulses. Records that differ from the last call's have another version (what the device
/// tables' uploads go by).
#[test]
fn kept_poses_read_and_step_as_poses_put_at_once_bit_for_bit() {
    let n = 40;
    let mesh = vec![0, 0, 0];
    let make = |d| HostBodies::new((0..n).map(|w| world(w, true)).collect(), mesh.clone(), d);
    let mut deferred = make(BodyPoses::Deferred);
    let mut serial = make(BodyPoses::DeferredSerial);
    let mut eager = make(BodyPoses::Eager);
    let mut plain = Plain((0..n).map(|w| world(w, true)).collect(), mesh.clone());
    let mut seen: [(u64, Vec<u8>); 3] = Default::default();
    let check = |h: &mut HostBodies, plain: &Plain, what: &str| {
        for w in 0..n {
            for b in 0..3 {
                let want = plain.0[w].pose(b).expect("body");
                let got = h.pose(w, b).expect("body");
                assert_eq!(
                    pose_bits(&got),
                    pose_bits(&want),
                    "{what}: world {w} body {b}"
                );
            }
        }
    };
    for c in 0..60 {
        let mut bodies_posed = Vec::new();
        match c % 5 {
            0 => bodies_posed.push((0, (0..n).collect::<Vec<_>>())),
            1 => bodies_posed.push((0, vec![3, 17, 5])),
            2 => {
                bodies_posed.push((0, (0..n).step_by(2).collect()));
                bodies_posed.push((1, (0..n).step_by(3).collect()));
            }
            3 => {
                bodies_posed.push((0, (0..n).collect()));
                bodies_posed.push((0, vec![4, 9]));
            }
            _ => {}
        }
        for (k, (b, list)) in bodies_posed.iter().enumerate() {
            // Read from the rows (kept poses of other bodies or worlds untouched), then put.
            let poses: Vec<(usize, BodyPose)> = list
                .iter()
                .map(|&w| {
                    let now = deferred.pose(w, *b).expect("body");
                    let want = plain.0[w].pose(*b).expect("body");
                    assert_eq!(pose_bits(&now), pose_bits(&want), "call {c}: world {w}");
                    (w, posed(now, w, c + k))
                })
                .collect();
            for h in [&mut deferred, &mut serial, &mut eager] {
                h.set_body_poses(*b, &poses).expect("poses");
            }
            for (w, p) in &poses {
                plain.0[*w].set_pose(*b, p).expect("pose");
            }
            // Reads of an unposed world's poses and of an unposed body of a posed world while
            // poses are kept (from the rows: nothing put into the worlds yet).
            if let Some(u) = (0..n).find(|w| !list.contains(w)) {
                let mut out = Vec::new();
                deferred.poses_into(u, &mut out);
                assert_eq!(out, plain.0[u].poses(), "call {c}");
            }
            let other = (b + 2) % 3;
            let got = deferred.pose(list[0], other).expect("body");
            let want = plain.0[list[0]].pose(other).expect("body");
            assert_eq!(pose_bits(&got), pose_bits(&want), "call {c}");
        }
        // A body of listed worlds at once (a script's reads before it poses), poses kept or
        // not, a world past the last and a body past the last read as `None`.
        let listed = [(c * 7) % n, 3, n, 3];
        let mut got = Vec::new();
        deferred.body_poses(c % 3, &listed, &mut got);
        for (&w, p) in listed.iter().zip(&got) {
            let want = plain.0.get(w).and_then(|x| x.pose(c % 3));
            assert_eq!(
                p.map(|p| pose_bits(&p)),
                want.map(|p| pose_bits(&p)),
                "call {c}"
            );
        }
        deferred.body_poses(3, &[0], &mut got);
        assert_eq!(got, vec![None]);
        if c % 2 == 0 {
            // Every world's poses at once (the driver's reads of a call), poses kept or not.
            let mut all: Vec<Vec<BodyPose>> = Vec::new();
            deferred.each_poses(&mut |w, p| {
                assert_eq!(w, all.len(), "call {c}: worlds in order");
                all.push(p.to_vec());
            });
            assert_eq!(all.len(), n);
            for (w, got) in all.iter().enumerate() {
                assert_eq!(
                    *got,
                    plain.0[w].poses(),
                    "call {c}: each_poses of world {w}"
                );
            }
        }
        if c % 5 == 4 {
            // The same body of world 7 posed twice with no read between: both kept, put in
            // the order given.
            for k in 0..2 {
                let p = posed(plain.0[7].pose(0).expect("tool"), 7, c + k + 1);
                for h in [&mut deferred, &mut serial, &mut eager] {
                    h.set_body_poses(0, &[(7, p)]).expect("pose");
                }
                plain.0[7].set_pose(0, &p).expect("pose");
            }
        }
        if c % 11 == 7 {
            // A reset of world 5 over the poses kept for it.
            let start = world(5, true).poses();
            for h in [&mut deferred, &mut serial, &mut eager] {
                h.set_poses(5, &start).expect("reset");
            }
            plain.0[5].set_poses(&start).expect("reset");
        }
        if c % 13 == 4 {
            let want = state_bits(
                &plain
                    .0
                    .iter()
                    .flat_map(|w| w.states().to_vec())
                    .collect::<Vec<_>>(),
            );
            assert_eq!(state_bits(&deferred.states()), want, "call {c}: states");
        }
        let want = plain.records();
        for (h, seen) in [&mut deferred, &mut serial, &mut eager]
            .into_iter()
            .zip(&mut seen)
        {
            let version = h.version();
            let got = bytemuck::cast_slice::<GpuBody, u8>(h.records());
            assert!(got == &want[..], "call {c}: the device records differ");
            assert!(
                version != seen.0 || got == &seen.1[..],
                "call {c}: new records at version {version} of the last call's"
            );
            *seen = (version, got.to_vec());
        }
        let each: Vec<Vec<Exchange>> = (0..n)
            .map(|w| {
                let mut e = vec![Exchange::default(); 3];
                e[1].impulse = [1e-3 * (w % 5) as f64, 2e-3, 0.0];
                e[1].torque = [0.0, 1e-5 * (c % 3) as f64, 0.0];
                e
            })
            .collect();
        let ex = (c % 2 == 0).then_some(&each[..]);
        for h in [&mut deferred, &mut serial, &mut eager] {
            h.advance(ex, 1e-3);
        }
        for (w, world) in plain.0.iter_mut().enumerate() {
            let none = vec![Exchange::default(); 3];
            world.advance(ex.map_or(&none, |e| &e[w]), 1e-3);
        }
        check(&mut deferred, &plain, &format!("after step {c}"));
        check(&mut serial, &plain, &format!("after step {c} (serial)"));
        check(&mut eager, &plain, &format!("after step {c} (eager)"));
    }
    // The box rested on the floor (contacts in the steps compared).
    assert!(plain.0[0].pose(1).expect("box").position.y > 0.04);
}

/// Worlds at rest (a kinematic tool and a fixed block, every velocity zero) are not stepped
/// by `advance` (`stepped` counts the others) and every read, record and step stays bit for
/// bit what stepping every world gives (`Plain`): 20 worlds over 80 steps, the even ones put
/// at rest (world 8 turned: its rotation renormalised by its first steps under
/// `RTMPM_KINEMATIC=rapier`, left as it is by the worlds' own integration), the odd ones
/// moving; world 2 posed again at the pose it has (still skipped), world 4 set moving and
/// later at rest again, world 6 put back to its start (moving) by `set_poses`, world 10's
/// tool given an angular velocity alone, and the worlds with a dynamic box never skipped.
/// Unless `RTMPM_BATCH_REST=old` is set (then every world is stepped, as before). The records'
/// version stays while every world rests (no upload of a table that holds them).
#[test]
fn worlds_at_rest_are_skipped_and_step_on_as_before() {
    let n = 20;
    let mesh = vec![0];
    let make = |w: usize| world(w, false);
    let mut h = HostBodies::new(
        (0..n).map(make).collect(),
        mesh.clone(),
        BodyPoses::Deferred,
    );
    let mut plain = Plain((0..n).map(make).collect(), mesh.clone());
    let put = |h: &mut HostBodies, plain: &mut Plain, w: usize, p: BodyPose| {
        h.set_body_poses(0, &[(w, p)]).expect("pose");
        plain.0[w].set_pose(0, &p).expect("pose");
    };
    let still = |mut p: BodyPose| {
        p.velocity = Vec3::ZERO;
        p.angular_velocity = Vec3::ZERO;
        p
    };
    for w in (0..n).step_by(2) {
        let mut p = still(plain.0[w].pose(0).expect("tool"));
        if w == 8 {
            p.rotation = Quat::from_rotation_y(0.3) * Quat::from_rotation_x(0.2);
        }
        put(&mut h, &mut plain, w, p);
    }
    // Worlds with a dynamic box (and their tool still): stepped at every step.
    let mut boxes = HostBodies::new(
        (0..4).map(|w| world(w, true)).collect(),
        vec![0, 0, 0],
        BodyPoses::Deferred,
    );
    let tools: Vec<(usize, BodyPose)> = (0..4)
        .map(|w| (w, still(boxes.pose(w, 0).expect("tool"))))
        .collect();
    boxes.set_body_poses(0, &tools).expect("poses");
    let none = [Exchange::default()];
    for c in 0..80 {
        match c {
            20 => {
                let p = plain.0[2].pose(0).expect("tool");
                put(&mut h, &mut plain, 2, p);
            }
            30 => {
                let mut p = plain.0[4].pose(0).expect("tool");
                p.velocity = Vec3::new(0.05, -0.1, 0.0);
                put(&mut h, &mut plain, 4, p);
            }
            45 => {
                let p = still(plain.0[4].pose(0).expect("tool"));
                put(&mut h, &mut plain, 4, p);
            }
            50 => {
                let start = make(6).poses();
                h.set_poses(6, &start).expect("reset");
                plain.0[6].set_poses(&start).expect("reset");
            }
            60 => {
                let mut p = plain.0[10].pose(0).expect("tool");
                p.angular_velocity = Vec3::new(0.0, 0.5, 0.0);
                put(&mut h, &mut plain, 10, p);
            }
            _ => {}
        }
        h.advance(None, 4e-4);
        boxes.advance(None, 4e-4);
        for world in plain.0.iter_mut() {
            world.advance(&none, 4e-4);
        }
        for w in 0..n {
            let (got, want) = (
                h.pose(w, 0).expect("tool"),
                plain.0[w].pose(0).expect("tool"),
            );
            assert_eq!(pose_bits(&got), pose_bits(&want), "step {c}: world {w}");
        }
        let got: Vec<u8> = bytemuck::cast_slice(h.records()).to_vec();
        assert_eq!(got, plain.records(), "step {c}: the records");
        // The moving worlds: the 10 odd ones, world 4 from its pose at step 30 to the one at
        // 45, world 6 from its reset, world 10 from 60.
        let moving =
            10 + usize::from((30..45).contains(&c)) + usize::from(c >= 50) + usize::from(c >= 60);
        if old_rest() {
            assert_eq!(
                h.stepped(),
                n,
                "step {c}: RTMPM_BATCH_REST=old steps every world"
            );
        } else if c >= 5 && c != 45 {
            assert_eq!(h.stepped(), moving, "step {c}: the worlds stepped");
        }
        assert_eq!(boxes.stepped(), 4, "step {c}: a world with a dynamic body");
    }
    let want = state_bits(
        &plain
            .0
            .iter()
            .flat_map(|w| w.states().to_vec())
            .collect::<Vec<_>>(),
    );
    assert_eq!(state_bits(&h.states()), want, "the states");

    // Every world at rest (the advance returns without a look at the rows), then one set
    // moving by a pose, later at rest again: stepped as `Plain` steps it.
    let mut h = HostBodies::new(
        (0..4).map(make).collect(),
        mesh.clone(),
        BodyPoses::Deferred,
    );
    let mut plain = Plain((0..4).map(make).collect(), mesh.clone());
    for w in 0..4 {
        let p = still(plain.0[w].pose(0).expect("tool"));
        put(&mut h, &mut plain, w, p);
    }
    for c in 0..30 {
        if c == 10 {
            let mut p = plain.0[1].pose(0).expect("tool");
            p.velocity = Vec3::new(0.0, -0.2, 0.0);
            put(&mut h, &mut plain, 1, p);
        }
        if c == 20 {
            let p = still(plain.0[1].pose(0).expect("tool"));
            put(&mut h, &mut plain, 1, p);
        }
        h.advance(None, 4e-4);
        for world in plain.0.iter_mut() {
            world.advance(&none, 4e-4);
        }
        for w in 0..4 {
            let (got, want) = (
                h.pose(w, 0).expect("tool"),
                plain.0[w].pose(0).expect("tool"),
            );
            assert_eq!(
                pose_bits(&got),
                pose_bits(&want),
                "all still, step {c}: world {w}"
            );
        }
        let want = usize::from((10..21).contains(&c));
        if !old_rest() && (2..).contains(&c) {
            assert_eq!(h.stepped(), want, "all still, step {c}: the worlds stepped");
        }
        if !old_rest() && (2..10).contains(&c) {
            let bytes =
                |h: &mut HostBodies| bytemuck::cast_slice::<GpuBody, u8>(h.records()).to_vec();
            let (before, records) = (h.version(), bytes(&mut h));
            h.advance(None, 4e-4);
            assert_eq!(
                h.version(),
                before,
                "all still, step {c}: the version stays"
            );
            assert_eq!(bytes(&mut h), records, "all still, step {c}");
            for world in plain.0.iter_mut() {
                world.advance(&none, 4e-4);
            }
        }
    }
}

/// The world of bench/python_batch_gpu.py's tool: one kinematic box of half size 0.03 m above
/// the sand bed's interior (the timings' world, 256 of them).
fn tool_world() -> RigidWorld {
    let mut b = body(RigidKind::Kinematic, Vec3::new(0.2, 0.22, 0.2), Vec3::ZERO);
    b.shape = Shape::Box(Cuboid::centred(Vec3::ZERO, Vec3::splat(0.03)));
    let interior = (Vec3::splat(0.075), Vec3::new(0.325, 0.275, 0.325));
    RigidWorld::new(&[b], &[], Vec3::new(0.0, -9.81, 0.0), interior)
        .expect("world")
        .expect("bodies")
}

/// Every way of spreading the worlds over the cores ([`Fan`]) steps them alike, bit for bit:
/// 12 worlds of a moving tool, a dynamic box and a fixed block, and 12 whose box is kinematic
/// too (the world not stepped through rapier), 40 steps, the tools posed moving at step 10.
#[test]
fn every_fan_of_the_worlds_steps_them_alike() {
    let make = || {
        let worlds = (0..24)
            .map(|w| {
                let mut bodies = vec![
                    body(RigidKind::Kinematic, Vec3::new(0.2, 0.7, 0.5), Vec3::ZERO),
                    body(RigidKind::Dynamic, Vec3::new(0.3, 0.3, 0.3), Vec3::ZERO),
                    body(RigidKind::Fixed, Vec3::new(0.8, 0.2, 0.8), Vec3::ZERO),
                ];
                if w >= 12 {
                    bodies[1].kind = RigidKind::Kinematic;
                    bodies[1].velocity = Vec3::new(0.1, 0.01 * w as f32, 0.0);
                    bodies[1].angular_velocity = Vec3::new(0.0, 1.0, 0.5);
                }
                let interior = (Vec3::ZERO, Vec3::ONE);
                RigidWorld::new(&bodies, &[], Vec3::new(0.0, -9.81, 0.0), interior)
                    .expect("world")
                    .expect("bodies")
            })
            .collect();
        HostBodies::new(worlds, vec![0, 0, 0], BodyPoses::Deferred)
    };
    let fans = [Fan::Serial, Fan::Cores(1), Fan::Cores(5), Fan::Cores(64)];
    let mut all: Vec<HostBodies> = fans.iter().map(|_| make()).collect();
    for c in 0..40 {
        for (h, &fan) in all.iter_mut().zip(&fans) {
            if c == 10 {
                let poses: Vec<(usize, BodyPose)> = (0..24)
                    .map(|w| (w, posed(h.pose(w, 0).expect("tool"), w, 1)))
                    .collect();
                h.set_body_poses(0, &poses).expect("poses");
            }
            h.advance_fanned(None, 1e-3, true, fan);
        }
        let want = state_bits(&all[0].states());
        for (h, fan) in all.iter_mut().zip(&fans).skip(1) {
            assert_eq!(state_bits(&h.states()), want, "step {c}: {fan:?}");
        }
        assert_eq!(all[0].stepped(), 24, "step {c}: every world moves");
    }
}

/// `advance` spreads the worlds as [`HostBodies::fan`] says: worlds of kinematic and fixed
/// bodies only on the calling thread up to [`SERIAL_ADVANCE`], in tasks of [`CHEAP_MIN_LEN`]
/// past it, worlds that rapier steps (a dynamic body in any) on every core one a task; unless
/// `RTMPM_BATCH_FAN` says otherwise.
#[test]
fn the_fan_follows_what_the_worlds_cost() {
    let tools = |n: usize| {
        HostBodies::new(
            (0..n).map(|_| tool_world()).collect(),
            vec![0],
            BodyPoses::Deferred,
        )
    };
    let boxes = HostBodies::new(
        (0..4).map(|w| world(w, true)).collect(),
        vec![0, 0, 0],
        BodyPoses::Deferred,
    );
    let rapier = HostBodies::new(
        (0..4).map(|_| tool_world().with_rapier_steps()).collect(),
        vec![0],
        BodyPoses::Deferred,
    );
    let got = [
        tools(256).fan(),
        tools(SERIAL_ADVANCE + 1).fan(),
        boxes.fan(),
        rapier.fan(),
    ];
    let want = match fan_switch() {
        Some(fan) => [fan; 4],
        None => [
            Fan::Serial,
            Fan::Cores(CHEAP_MIN_LEN),
            Fan::Cores(1),
            Fan::Cores(1),
        ],
    };
    if tools(1).cheap {
        assert_eq!(got, want);
    } else {
        // RTMPM_KINEMATIC=rapier: every world stepped through rapier.
        assert!(
            got.iter()
                .all(|f| *f == fan_switch().unwrap_or(Fan::Cores(1)))
        );
    }
}

mod timing;
