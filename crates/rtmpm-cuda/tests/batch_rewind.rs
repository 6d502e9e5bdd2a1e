//! The rewind point of a GPU batch kept on the device (`rtmpm_cuda::batch::CudaBatch` under the
//! lockstep driver's step calls, what Python's `BatchSimulation` runs): calls of one step equal
//! one call of as many, and a blown-up world rewinds to the device point as to the host's copy
//! (needs a GPU; skips with a message otherwise):
//! `cargo test --release -p rtmpm-cuda --test batch_rewind -- --include-ignored --nocapture`.

mod common;

use common::batch::{DT, agrees, bit_identical, max_diff, precise, wedge_path, wedge_worlds};
use common::gpu;
use rtmpm_cuda::batch::CudaBatch;
use rtmpm_physics::Particles;
use rtmpm_physics::math::Vec3;
use rtmpm_scene::BatchScene;
use std::time::Instant;

/// A lockstep run without files (what Python's `BatchSimulation` drives) of the first four
/// wedge worlds at the fixed step `DT`, each world's own gravity, from `p0`; with
/// `device_point` its rewind point is kept on the device (the default), else on the host (read
/// after every call, as before the device point).
fn lockstep_steps(
    p0: &[Particles],
    device_point: bool,
) -> rtmpm_driver::batch::lockstep::LockstepRun<CudaBatch> {
    use rtmpm_driver::batch::BatchOptions;
    use rtmpm_driver::batch::lockstep::LockstepRun;
    let path = wedge_path();
    let mut b = BatchScene::from_file(&path).expect("wedge_slump.toml");
    b.worlds = wedge_worlds(4)
        .into_iter()
        .map(|mut s| {
            s.time.step = rtmpm_scene::StepMode::Fixed { dt: DT };
            s
        })
        .collect();
    let mut batch = CudaBatch::new(&b.worlds, p0, precise()).expect("batch");
    batch.set_device_point(device_point);
    let scene = batch.scene().clone();
    let options = BatchOptions::default();
    let mut r =
        LockstepRun::new(&b, "wedge", scene, Box::new(batch), &options).expect("lockstep run");
    r.write_first_frame().expect("first read");
    r
}

/// Every world of `a` against `b`: bit for bit (x and v) where `exact`, else within the
/// agreement test's aggregate tolerances; the failures.
fn same_worlds(
    what: &str,
    a: &rtmpm_driver::batch::lockstep::LockstepRun<CudaBatch>,
    b: &rtmpm_driver::batch::lockstep::LockstepRun<CudaBatch>,
    worlds: &[usize],
    exact: bool,
) -> Vec<String> {
    let mut failures = Vec::new();
    for &w in worlds {
        let (pa, pb) = (a.worlds[w].particles(), b.worlds[w].particles());
        if exact {
            if !bit_identical(pa, pb) {
                let (dx, dv) = max_diff(pa, pb);
                failures.push(format!(
                    "{what}: world {w} not bit for bit (max |dx| {dx:.3e}, |dv| {dv:.3e})"
                ));
            }
        } else {
            let dx = a.worlds[w].scene().dx;
            failures.extend(agrees(&format!("{what}: world {w}"), None, pa, pb, dx));
        }
    }
    failures
}

/// Python's step loop on the GPU: 60 calls of one step (a frame end crossed) give the worlds
/// of one call of 60 steps, bit for bit when the GPU repeats itself (two identical runs of 60
/// steps bit-identical: its atomic sums added in the same order; otherwise within the agreement
/// test's aggregate tolerances, said so), and the calls read nothing back: the rewind point is
/// kept on the device. About 10 s on an H200 (mostly building the batches).
#[test]
#[ignore = "needs a CUDA GPU"]
fn many_calls_of_one_step_equal_one_call_of_as_many_steps() {
    if !gpu() {
        return;
    }
    let p0: Vec<Particles> = wedge_worlds(4)
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    let whole = |p0: &[Particles]| {
        let mut r = lockstep_steps(p0, true);
        assert!(r.advance_steps(60).expect("steps").is_empty());
        r.sync().expect("read");
        r
    };
    let (one, again) = (whole(&p0), whole(&p0));
    let mut calls = lockstep_steps(&p0, true);
    let t = Instant::now();
    for _ in 0..60 {
        assert!(calls.advance_steps(1).expect("step").is_empty());
    }
    let took = t.elapsed().as_secs_f64();
    assert!(
        calls.sim.backend.point_bytes() > 0,
        "the rewind point is on the device"
    );
    assert_eq!((calls.sim.step, calls.sim.frame), (60, 1));
    calls.sync().expect("read");
    let repeats = same_worlds("two runs of 60 steps", &one, &again, &[0, 1, 2, 3], true).is_empty();
    println!(
        "60 calls of one step: {:.3} ms a call; two identical runs bit-identical: {repeats}",
        1e3 * took / 60.0
    );
    let failures = same_worlds("60 calls of 1 step", &calls, &one, &[0, 1, 2, 3], repeats);
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The device rewind point against the host's: four wedge worlds stepped in calls of 10 steps
/// without reading them back; world 2 reset to a body at 10^5 m/s between two calls blows up in
/// the next, is frozen with its reset state (read at the device point) and parked, and the call
/// is taken again from the point; world 1 is then reset and the run goes on. The same run with
/// the point kept on the host (read after every call: the driver before the device point) gives
/// the same statuses and worlds, bit for bit when the GPU repeats itself (two identical runs
/// bit-identical), else within the agreement test's aggregate tolerances; the frozen world keeps
/// its reset state bit for bit in both. About 15 s on an H200.
#[test]
#[ignore = "needs a CUDA GPU"]
fn a_blown_up_world_rewinds_to_the_device_point_as_to_the_hosts() {
    use rtmpm_driver::batch::WorldStatus;
    if !gpu() {
        return;
    }
    let worlds = wedge_worlds(4);
    let p0: Vec<Particles> = worlds
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    let mut fast = p0[2].clone();
    fast.v
        .iter_mut()
        .for_each(|v| *v = Vec3::new(1e5, 0.0, 0.0));
    let run = |device_point: bool| {
        let mut r = lockstep_steps(&p0, device_point);
        assert!(r.advance_steps(10).expect("steps").is_empty());
        assert!(r.advance_steps(10).expect("steps").is_empty());
        r.reset_worlds(vec![(2, fast.clone())]).expect("reset");
        assert_eq!(r.advance_steps(10).expect("steps"), [2], "world 2 blows up");
        assert!(r.advance_steps(10).expect("steps").is_empty());
        r.reset_worlds(vec![(1, p0[1].clone())]).expect("reset");
        assert!(r.advance_steps(10).expect("steps").is_empty());
        r.sync().expect("read");
        r
    };
    let device = run(true);
    assert!(device.sim.backend.point_bytes() > 0);
    let host = run(false);
    assert_eq!(host.sim.backend.point_bytes(), 0);
    let repeats =
        same_worlds("two identical runs", &device, &run(true), &[0, 1, 3], true).is_empty();
    println!("two identical runs bit-identical: {repeats}");
    for w in 0..4 {
        let (d, h) = (&device.worlds[w].status, &host.worlds[w].status);
        // A frozen world's reason quotes the bad particle's place and speed after the failed
        // step: word for word only where the GPU repeats itself.
        match (d, h) {
            (WorldStatus::Frozen { frame: a, .. }, WorldStatus::Frozen { frame: b, .. })
                if !repeats =>
            {
                assert_eq!(a, b, "world {w}")
            }
            _ => assert_eq!(d, h, "world {w}"),
        }
        assert_eq!(
            (device.worlds[w].steps(), device.worlds[w].frame()),
            (host.worlds[w].steps(), host.worlds[w].frame()),
            "world {w}"
        );
    }
    match &device.worlds[2].status {
        WorldStatus::Frozen { reason, .. } => assert!(
            reason.contains("blew up") || reason.contains("time step"),
            "{reason}"
        ),
        other => panic!("world 2 should be frozen: {other:?}"),
    }
    assert_eq!(
        device.worlds[1].steps(),
        10,
        "world 1 counts from its reset"
    );
    for r in [&device, &host] {
        assert!(
            bit_identical(r.worlds[2].particles(), &fast),
            "the frozen world keeps its reset state"
        );
    }
    let mut failures = same_worlds("device point vs host", &device, &host, &[0, 1, 3], repeats);
    // World 0 went through the rewind: it agrees with a run that never had a blow-up.
    let mut plain = lockstep_steps(&p0, true);
    for _ in 0..5 {
        assert!(plain.advance_steps(10).expect("steps").is_empty());
    }
    plain.sync().expect("read");
    failures.extend(same_worlds(
        "beside a blow-up vs none",
        &device,
        &plain,
        &[0, 3],
        false,
    ));
    assert!(failures.is_empty(), "{failures:#?}");
}
