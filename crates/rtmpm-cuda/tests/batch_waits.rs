//! The host's waits for the GPU in a batch's step loop (`rtmpm_cuda::waits`, counted by reason)
//! under the lockstep driver with deferred checks (what Python's `BatchSimulation.overlap`
//! runs): a loop of tool poses, resets and step calls waits only for each check's copy of the
//! control words, and the checks queued behind a frame end inside a call and behind the call's
//! end find a blow-up as the checks made at once do (needs the feature `rigid` and a GPU; skips
//! with a message otherwise):
//! `cargo test --release -p rtmpm-cuda --features rigid --test batch_waits -- --include-ignored --nocapture`.
#![cfg(feature = "rigid")]

mod common;

use common::batch::agrees;
use common::gpu;
use rtmpm_cuda::batch::CudaBatch;
use rtmpm_cuda::{CudaOptions, WaitCounts, WaitReason};
use rtmpm_driver::batch::lockstep::LockstepRun;
use rtmpm_driver::batch::{BatchOptions, WorldStatus};
use rtmpm_physics::Particles;
use rtmpm_physics::math::Vec3;
use rtmpm_rigid::BodyPose;
use rtmpm_scene::Scene;

/// A block of jelly (0.2 x 0.12 x 0.2 m, 8 particles a cell of 2 cm, 4,800 particles) on a
/// sticky floor under a kinematic tool (a 6 cm box 1 cm above it at its own place along x),
/// fixed dt = 2e-4 s, 100 steps a frame.
fn tool_world(w: usize) -> Scene {
    let x = 0.16 + 0.005 * (w % 8) as f32;
    let text = format!(
        r#"name = "press"
[domain]
min = [0.0, 0.0, 0.0]
max = [0.4, 0.4, 0.4]
dx = 0.02
[time]
duration = 1.0
fps = 50
dt = 2e-4
[walls]
thickness = 3
faces.y_min = {{ condition = "sticky" }}
[[material]]
name = "jelly"
type = "fixed_corotated"
density = 1000.0
youngs_modulus = 1e5
poisson_ratio = 0.3
[[body]]
material = "jelly"
shape = "box"
min = [0.1, 0.06, 0.1]
max = [0.3, 0.18, 0.3]
particles_per_cell = 8
[[rigid_body]]
name = "tool"
shape = "box"
min = [{}, 0.19, 0.17]
max = [{}, 0.25, 0.23]
type = "kinematic"
density = 1000.0
condition = "sticky"
"#,
        x - 0.03,
        x + 0.03
    );
    Scene::from_toml(&text, "press.toml").unwrap_or_else(|e| panic!("{e}"))
}

/// `count` tool worlds and their initial particles.
fn tool_worlds(count: usize) -> (Vec<Scene>, Vec<Particles>) {
    let worlds: Vec<Scene> = (0..count).map(tool_world).collect();
    let p0 = worlds
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    (worlds, p0)
}

/// The lockstep run without files (Python's `BatchSimulation` on the GPU) of `worlds` from
/// `p0`, its checks deferred with `deferred`.
fn lockstep(worlds: &[Scene], p0: &[Particles], deferred: bool) -> LockstepRun<CudaBatch> {
    let options = CudaOptions {
        fast_math: false,
        ..CudaOptions::default()
    };
    let batch = CudaBatch::new(worlds, p0, options).expect("batch");
    let scene = batch.scene().clone();
    let mut bs = rtmpm_scene::BatchScene::single(worlds[0].clone());
    bs.worlds = worlds.to_vec();
    let mut run =
        LockstepRun::new(&bs, "", scene, Box::new(batch), &BatchOptions::default()).expect("run");
    run.write_first_frame().expect("first frame");
    run.set_deferred_checks(deferred).expect("deferred checks");
    run
}

/// One call of the issue's loop: every world's tool posed moving down (0.2 m/s, 0.1 mm lower
/// each call), worlds `2c` and `2c + 1` (mod the count) put back to their start, 10 steps;
/// no world may blow up.
fn loop_call(run: &mut LockstepRun<CudaBatch>, p0: &[Particles], c: usize) {
    let n = p0.len();
    let poses: Vec<(usize, BodyPose)> = (0..n)
        .map(|w| {
            let mut p = run.sim.backend.world_body_pose(w, 0).expect("tool");
            p.velocity = Vec3::new(0.0, -0.2, 0.0);
            p.position.y -= 1e-4;
            (w, p)
        })
        .collect();
    run.set_body_poses(0, poses).expect("poses");
    let starts = [(2 * c) % n, (2 * c + 1) % n]
        .into_iter()
        .map(|w| (w, p0[w].clone()))
        .collect();
    run.reset_worlds(starts).expect("resets");
    let frozen = run.advance_steps(10).expect("steps");
    assert!(frozen.is_empty(), "call {c}: worlds {frozen:?} blew up");
}

/// The waits of `calls` loop calls (after 10 calls that warm the rings and pools up and cross a
/// frame end, the first step call one step long, so that frame ends fall inside calls), each
/// call's checks made before the counts are read: (the waits, the frame ends crossed inside the
/// calls).
fn loop_waits(deferred: bool, pipelined: bool, calls: usize) -> (WaitCounts, u64) {
    let (worlds, p0) = tool_worlds(16);
    let mut run = lockstep(&worlds, &p0, deferred);
    run.set_pipelined(pipelined);
    assert!(run.advance_steps(1).expect("one step").is_empty());
    for c in 0..10 {
        loop_call(&mut run, &p0, c);
    }
    run.settle().expect("settle");
    let (before, frame0) = (run.sim.backend.host_waits(), run.sim.frame);
    for c in 10..10 + calls {
        loop_call(&mut run, &p0, c);
    }
    run.settle().expect("settle");
    let waits = run.sim.backend.host_waits().since(&before);
    (waits, run.sim.frame - frame0)
}

/// The issue's loop (16 worlds; every call poses every world's tool, resets 2 worlds, takes 10
/// steps) with deferred checks waits only for the checks' copies of the control words: one a
/// call and one a frame end inside a call, nothing else (no read of control words or sums, no
/// copy from pageable memory, no synchronisation, no wait for page-locked memory in use), and
/// allocates at most 4 buffers after the warm-up (the rings grow only when the host gets further
/// ahead than before: 2 on an H200, session 13); pipelined or not (`LockstepRun::set_pipelined`).
/// The same loop checking each call at once waits as often for its checks
/// (a frame end's check inside a call made at once too). With `RTMPM_BATCH_WAITS=old` this test
/// fails (the old paths count pageable copies and wait on the upload buffers in turn). A few
/// seconds on an H200.
#[test]
#[ignore = "needs a CUDA GPU"]
fn a_loop_with_deferred_checks_waits_only_for_its_checks() {
    if !gpu() {
        return;
    }
    if rtmpm_cuda::waits::old_waits() {
        println!("skipped: RTMPM_BATCH_WAITS=old (the waits this test counts are the new paths')");
        return;
    }
    let calls = 20;
    for (deferred, pipelined) in [(true, true), (true, false), (false, false)] {
        let (w, frames) = loop_waits(deferred, pipelined, calls);
        println!(
            "deferred checks {deferred} (pipelined {pipelined}): {calls} calls, {frames} frame \
             ends inside them: waits {w}"
        );
        assert_eq!(
            w.get(WaitReason::Check),
            calls as u64 + frames,
            "one check a call and one a frame end inside a call: {w}"
        );
        for why in [
            WaitReason::Control,
            WaitReason::Read,
            WaitReason::Sums,
            WaitReason::Staging,
            WaitReason::Pageable,
            WaitReason::Sync,
        ] {
            assert_eq!(
                w.get(why),
                0,
                "deferred {deferred}: {} waits: {w}",
                why.name()
            );
        }
        assert!(
            w.get(WaitReason::Alloc) <= 4,
            "deferred {deferred}: buffers allocated in the loop: {w}"
        );
        assert!(frames >= 1, "no frame end inside a call was crossed");
    }
}

/// Calls with deferred checks find a blow-up as calls checking at once do, a call later: world 1
/// put to 10^5 m/s at step 95 blows up in the next call (steps 96-105), before the frame end at
/// step 100 inside it, whose check is queued and made (at that frame end's clock) as the call
/// after begins, after a reset of world 2 made meanwhile (made again after the rewind). The
/// worlds frozen per call are a call late, the statuses (frame, steps, that a reason is given),
/// clocks and the other worlds' particles (within the agreement test's tolerances: the rewind's
/// steps are taken again, and CUDA's atomic sums are not bit-reproducible) end as with checks
/// made at once; deferred calls pipelined or not (`LockstepRun::set_pipelined`: pipelined, the
/// call after the blow-up queues its steps before the check that finds it, which drops them and
/// advances again after the rewind). A few seconds on an H200.
#[test]
#[ignore = "needs a CUDA GPU"]
fn deferred_checks_queued_at_a_frame_end_find_a_blow_up_a_call_late() {
    if !gpu() {
        return;
    }
    let (worlds, p0) = tool_worlds(4);
    let mut fast = p0[1].clone();
    fast.v
        .iter_mut()
        .for_each(|v| *v = Vec3::new(1e5, 0.0, 0.0));
    let run = |deferred: bool, pipelined: bool| {
        let mut r = lockstep(&worlds, &p0, deferred);
        r.set_pipelined(pipelined);
        let mut calls = vec![r.advance_steps(95).expect("95 steps")];
        r.reset_worlds(vec![(1, fast.clone())])
            .expect("world 1 fast");
        calls.push(r.advance_steps(10).expect("the call that blows up"));
        r.reset_worlds(vec![(2, p0[2].clone())])
            .expect("reset world 2");
        calls.push(r.advance_steps(10).expect("next call"));
        calls.push(r.advance_steps(5).expect("last call"));
        r.settle().expect("settle");
        r.sync().expect("read the worlds");
        (r, calls)
    };
    let (eager, eager_calls) = run(false, false);
    for pipelined in [false, true] {
        let (late, late_calls) = run(true, pipelined);
        ends_alike(&worlds, (&eager, &eager_calls), (&late, &late_calls));
        assert!(
            late.sim.backend.point_bytes() > eager.sim.backend.point_bytes(),
            "pipelined {pipelined}: the next call's point kept in a second buffer"
        );
    }
}

/// The run `late` (deferred checks) ends as `eager` (checks at once), its frozen worlds a call
/// late (`deferred_checks_queued_at_a_frame_end_find_a_blow_up_a_call_late`).
fn ends_alike(
    worlds: &[Scene],
    (eager, eager_calls): (&LockstepRun<CudaBatch>, &[Vec<usize>]),
    (late, late_calls): (&LockstepRun<CudaBatch>, &[Vec<usize>]),
) {
    println!("frozen per call: at once {eager_calls:?}, deferred {late_calls:?}");
    let empty: Vec<usize> = Vec::new();
    assert_eq!(
        eager_calls,
        [empty.clone(), vec![1], empty.clone(), empty.clone()]
    );
    assert_eq!(late_calls, [empty.clone(), empty.clone(), vec![1], empty]);
    let brief = |r: &LockstepRun<CudaBatch>| -> Vec<(bool, u64, u64, u64)> {
        r.worlds
            .iter()
            .map(|w| {
                let frame = match &w.status {
                    WorldStatus::Running => None,
                    WorldStatus::Frozen { frame, .. } => Some(*frame),
                };
                (frame.is_some(), frame.unwrap_or(0), w.steps(), w.frame())
            })
            .collect()
    };
    assert_eq!(brief(late), brief(eager));
    assert!(matches!(late.worlds[1].status, WorldStatus::Frozen { .. }));
    let times = |r: &LockstepRun<CudaBatch>| -> Vec<u64> {
        r.worlds.iter().map(|w| w.time().to_bits()).collect()
    };
    assert_eq!(times(late), times(eager));
    assert_eq!(late.sim.step, eager.sim.step);
    let mut failures = Vec::new();
    for w in [0, 2, 3] {
        failures.extend(agrees(
            &format!("world {w}, deferred against at once"),
            None,
            late.worlds[w].particles(),
            eager.worlds[w].particles(),
            worlds[0].dx,
        ));
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
