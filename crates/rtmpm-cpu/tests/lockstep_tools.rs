//! Rigid bodies in a lockstep batch on CPU worlds side by side (`lockstep_support`; cargo
//! feature `rigid`): each world's tool goes with its particles through a rewind, a checkpoint
//! and a reset, and through a rewind found by a deferred check with the next call's bodies and
//! rewind point kept ahead of that check.
#![cfg(feature = "rigid")]

mod common;
mod lockstep_support;

use common::bits;
use common::cpu::CpuBackend;
use lockstep_support::{SLUMP, SideBySide, unwritten, unwritten_keeping};
use rtmpm_driver::Simulation;
use rtmpm_driver::batch::BatchOptions;
use rtmpm_driver::batch::lockstep::LockstepRun;
use rtmpm_scene::Scene;
use rtmpm_sim::{Particles, Worlds};

/// The slump's worlds with a kinematic tool (a 6 cm box above the mud).
fn with_tool(text: &str) -> String {
    text.replace(
        "[batch]",
        "[[rigid_body]]\nname = \"tool\"\nshape = \"box\"\nmin = [0.22, 0.27, 0.22]\n\
         max = [0.28, 0.33, 0.22]\ntype = \"kinematic\"\ndensity = 1000.0\n\
         condition = \"sticky\"\n[batch]",
    )
    .replace("max = [0.28, 0.33, 0.22]", "max = [0.28, 0.33, 0.28]")
}

/// World `scene` run alone for `steps` steps with its tool set to `velocity` first; its
/// particles, tool pose and load.
fn alone_with_tool(
    scene: &Scene,
    velocity: glam::Vec3,
    steps: u64,
) -> (Particles, rtmpm_rigid::BodyPose, rtmpm_rigid::BodyLoad) {
    let p = scene.sample_particles().expect("sample");
    let b = CpuBackend::new(scene, p, None).expect("cpu");
    let mut sim = Simulation::new(scene.clone(), Box::new(b));
    let mut poses = sim.backend.rigid_poses();
    poses[0].velocity = velocity;
    sim.backend.set_rigid_poses(&poses).expect("pose");
    while sim.step < steps {
        sim.advance(steps - sim.step).expect("stable");
    }
    let mut p = Particles::default();
    sim.backend.read_particles(&mut p).expect("read");
    let pose = sim.backend.rigid_poses()[0];
    let load = sim.backend.rigid_loads().expect("loads")[0];
    (p, pose, load)
}

/// Each world's tool posed before a call is kept with the world through a rewind: world 1 blows
/// up in the call, every world is put back and the steps taken again, and worlds 0 and 2 still
/// end (particles, tool pose, load on the tool) bit for bit as their separate runs with their
/// tools set the same way; the frozen world's tool is parked at rest; a reset world's tool goes
/// back to its pose at time 0 while the others' stay.
#[test]
fn each_worlds_tool_goes_with_its_particles_through_a_rewind_and_a_reset() {
    let text = with_tool(&SLUMP.replace(
        "\"material[0].yield_stress\" = [20, 150, 600]",
        "\"body[0].velocity\" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]",
    ));
    let (b, mut r) = unwritten(&text);
    let start: Vec<_> = (0..3).map(|w| r.worlds[w].bodies()[0]).collect();
    let speeds = [-0.5f32, -1.0, -1.5];
    for (w, s) in speeds.iter().enumerate() {
        let mut p = r.sim.backend.world_rigid_poses(w);
        p[0].velocity = glam::Vec3::new(0.0, *s, 0.0);
        r.sim.backend.set_world_rigid_poses(w, &p).expect("pose");
    }
    assert_eq!(r.advance_steps(60).expect("steps"), [1]);
    let parked = r.sim.backend.world_rigid_poses(1)[0];
    assert_eq!(
        parked.velocity,
        glam::Vec3::ZERO,
        "the frozen world's tool is parked"
    );
    assert_eq!(parked.position, start[1].position);
    for w in [0, 2] {
        let v = glam::Vec3::new(0.0, speeds[w], 0.0);
        let (p, pose, load) = alone_with_tool(&b.worlds[w], v, 60);
        assert_eq!(bits(r.worlds[w].particles()), bits(&p), "world {w}");
        assert_eq!(
            r.sim.backend.world_rigid_poses(w)[0],
            pose,
            "world {w}'s tool"
        );
        assert_eq!(r.worlds[w].bodies()[0], pose, "world {w}'s kept tool");
        let mine = r
            .sim
            .backend
            .world_rigid_loads(w)
            .expect("loads")
            .expect("some")[0];
        assert_eq!(mine, load, "world {w}'s load");
        assert!(load.force[1] > 0.0, "the mud pushes the tool up: {load:?}");
    }
    // A frozen world's tool stays parked although a script poses every world's.
    for w in 0..3 {
        let mut p = r.sim.backend.world_rigid_poses(w);
        p[0].velocity = glam::Vec3::new(0.0, -1.0, 0.0);
        r.sim.backend.set_world_rigid_poses(w, &p).expect("pose");
    }
    assert!(r.advance_steps(5).expect("steps").is_empty());
    assert_eq!(
        r.sim.backend.world_rigid_poses(1)[0].position,
        start[1].position
    );
    // A checkpoint holds each world's tool: the resumed batch goes on bit for bit.
    let dir = std::env::temp_dir().join(format!("rtmpm-lockstep-tools-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    r.checkpoint(&dir, &text, "tools.toml").expect("checkpoint");
    let side = |p: &[Particles]| {
        Ok((
            b.worlds[0].clone(),
            Box::new(SideBySide::from_particles(&b.worlds, p)),
        ))
    };
    let mut again =
        LockstepRun::resume(&b, &text, &dir, side, &BatchOptions::default()).expect("resume");
    std::fs::remove_dir_all(&dir).expect("clean up");
    for w in 0..3 {
        let want = r.sim.backend.world_rigid_poses(w);
        assert_eq!(again.sim.backend.world_rigid_poses(w), want, "world {w}");
    }
    assert!(r.advance_steps(10).expect("steps").is_empty());
    assert!(again.advance_steps(10).expect("steps").is_empty());
    for w in [0, 2] {
        // As for a_resumed_lockstep_batch_equals_the_uninterrupted_one_bit_for_bit: a checkpoint
        // holds the particles' f32 interface state, so an f64 run resumes from it rounded; its
        // particles are compared bit for bit in f32 builds only (the tools' poses in both).
        if cfg!(not(feature = "f64")) {
            assert_eq!(
                bits(again.worlds[w].particles()),
                bits(r.worlds[w].particles())
            );
        }
        let want = r.sim.backend.world_rigid_poses(w);
        assert_eq!(again.sim.backend.world_rigid_poses(w), want, "world {w}");
    }
    // A reset puts world 2's tool back to its start; world 0's stays where it went.
    let moved = r.sim.backend.world_rigid_poses(0)[0];
    let p2 = b.worlds[2].sample_particles().expect("sample");
    r.reset_worlds(vec![(2, p2)]).expect("reset");
    assert_eq!(r.sim.backend.world_rigid_poses(2)[0], start[2]);
    assert_eq!(r.worlds[2].bodies()[0], start[2]);
    assert_eq!(r.sim.backend.world_rigid_poses(0)[0], moved);
}

/// Four calls of 5 steps on the tool slump, each world's tool posed before every call (back at
/// its start, with a new velocity), world 1 made to blow up in the second call; checks made at
/// once, or deferred (`defer`), the backend keeping the next call's point in a second slot
/// (`two`: kept, with every world's bodies, before the last call's check), and with `pipelined`
/// queueing its checks' reads and each call queueing its steps before the last call's check
/// ([`LockstepRun::set_pipelined`]). The worlds each call
/// returned frozen with every world's tool as the backend held it after the call, and the run,
/// synced.
type Calls = Vec<(Vec<usize>, Vec<Vec<rtmpm_rigid::BodyPose>>)>;
fn posed_calls(defer: bool, two: bool, pipelined: bool) -> (Calls, LockstepRun<SideBySide>) {
    let (_, mut r) = unwritten_keeping(&with_tool(SLUMP), true);
    r.sim.backend.checks_late = true;
    r.sim.backend.two_points = two;
    r.sim.backend.queues = pipelined;
    r.set_pipelined(pipelined);
    r.set_deferred_checks(defer).expect("defer");
    r.sim.backend.poison = Some((1, 7));
    let start: Vec<_> = (0..3).map(|w| r.worlds[w].bodies()[0]).collect();
    let mut calls = Vec::new();
    for k in 0..4 {
        let poses = (0..3)
            .map(|w| {
                let v = glam::Vec3::new(0.1 * w as f32, -0.2 * (k + w + 1) as f32, 0.0);
                (
                    w,
                    rtmpm_rigid::BodyPose {
                        velocity: v,
                        ..start[w]
                    },
                )
            })
            .collect();
        r.set_body_poses(0, poses).expect("pose");
        let frozen = r.advance_steps(5).expect("steps");
        let held = (0..3).map(|w| r.sim.backend.world_rigid_poses(w)).collect();
        calls.push((frozen, held));
    }
    r.sync().expect("sync");
    (calls, r)
}

/// A blow-up found by a deferred check after the next call kept every world's tool and its
/// rewind point ahead of that check ends bit for bit as found at once: the worlds' particles,
/// statuses, kept and held tools (the frozen world's parked), the frozen lists a call later.
#[test]
fn a_late_blow_up_with_the_next_calls_tools_kept_ahead_ends_as_found_at_once() {
    let (at_once, a) = posed_calls(false, false, false);
    let frozen = |calls: &Calls| calls.iter().map(|c| c.0.clone()).collect::<Vec<_>>();
    assert_eq!(frozen(&at_once), [vec![], vec![1], vec![], vec![]]);
    for (two, pipelined) in [(false, false), (true, false), (true, true)] {
        let (deferred, d) = posed_calls(true, two, pipelined);
        let slots = two;
        let two = format!("{two}, pipelined {pipelined}");
        assert_eq!(
            frozen(&deferred),
            [vec![], vec![], vec![1], vec![]],
            "two {two}"
        );
        // The tools held after each call: the same, but for the frozen world's after the call
        // whose check is still pending (stepped on as if it ran); parked from the next on,
        // although the script posed it (the pose made again after the rewind, then parked).
        for (k, (x, y)) in at_once.iter().zip(&deferred).enumerate() {
            for w in 0..3 {
                if (k, w) != (1, 1) {
                    assert_eq!(y.1[w], x.1[w], "two {two}: call {k}, world {w}'s tool");
                }
            }
        }
        for w in 0..3 {
            let (x, y) = (&a.worlds[w], &d.worlds[w]);
            assert_eq!(y.status, x.status, "two {two}: world {w}");
            assert_eq!(
                bits(y.particles()),
                bits(x.particles()),
                "two {two}: world {w}"
            );
            assert_eq!(y.bodies(), x.bodies(), "two {two}: world {w}'s kept tool");
            assert_eq!(
                d.sim.backend.world_rigid_poses(w),
                a.sim.backend.world_rigid_poses(w),
                "two {two}: world {w}'s tool"
            );
            assert_eq!(y.steps(), x.steps(), "two {two}: world {w}");
        }
        assert_eq!(
            d.sim.backend.world_rigid_poses(1)[0].velocity,
            glam::Vec3::ZERO,
            "the frozen world's tool is parked"
        );
        // Kept ahead by calls 2 to 4; taken up by 2 and 4 (3's check rewound; pipelined, its
        // steps dropped then).
        let b = &d.sim.backend;
        assert_eq!(b.drops, usize::from(pipelined), "{two}");
        assert_eq!(
            (b.next_saves, b.next_uses),
            if slots { (3, 2) } else { (0, 0) }
        );
    }
}
