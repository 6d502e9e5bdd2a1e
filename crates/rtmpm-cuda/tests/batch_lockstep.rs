//! The frame-by-frame lockstep driver over a GPU batch (`rtmpm_driver::batch::lockstep` over
//! `rtmpm_cuda::batch::CudaBatch`: `rtmpm run --backend cuda` of a batch): each world its
//! separate CUDA run, a blown-up world frozen beside the others, and a checkpointed batch
//! resumed as the uninterrupted one (needs a GPU; skips with a message otherwise):
//! `cargo test --release -p rtmpm-cuda --test batch_lockstep -- --include-ignored --nocapture`.

mod common;

use common::batch::{DT, agrees, bit_identical, precise, wedge_path, wedge_worlds};
use common::{gpu, read};
use rtmpm_cuda::CudaBackend;
use rtmpm_cuda::batch::CudaBatch;
use rtmpm_physics::Particles;
use rtmpm_physics::math::Vec3;
use rtmpm_scene::{BatchScene, Scene};

/// The frame-by-frame driver of a GPU batch (`rtmpm run --backend cuda` of a batch:
/// `rtmpm_driver::batch::lockstep`): four wedge worlds at a fixed step, each with its own
/// gravity, give world by world their separate CUDA runs (the agreement test's aggregate
/// tolerances) after 3 frames; then a world given a body speed of 10^5 m/s is frozen at frame 0
/// with a blow-up, the frame is stepped again without it, and the others still agree.
#[test]
#[ignore = "needs a CUDA GPU"]
fn the_lockstep_driver_runs_a_gpu_batch_and_freezes_a_blown_up_world() {
    use rtmpm_driver::Simulation;
    use rtmpm_driver::batch::lockstep::LockstepRun;
    use rtmpm_driver::batch::{BatchOptions, WorldStatus};
    if !gpu() {
        return;
    }
    let fixed = |mut s: Scene| {
        s.time.step = rtmpm_scene::StepMode::Fixed { dt: DT };
        s
    };
    let lockstep = |blow_up: Option<usize>| {
        let path = wedge_path();
        let mut b = BatchScene::from_file(&path).expect("wedge_slump.toml");
        b.worlds = wedge_worlds(4).into_iter().map(fixed).collect();
        let p0: Vec<Particles> = b
            .worlds
            .iter()
            .enumerate()
            .map(|(w, s)| {
                let mut p = s.sample_particles().expect("particles");
                if Some(w) == blow_up {
                    p.v.iter_mut().for_each(|v| *v = Vec3::new(1e5, 0.0, 0.0));
                }
                p
            })
            .collect();
        let batch = CudaBatch::new(&b.worlds, &p0, precise()).expect("batch");
        let scene = batch.scene().clone();
        let options = BatchOptions {
            frames: Some(3),
            ..BatchOptions::default()
        };
        let mut r =
            LockstepRun::new(&b, "wedge", scene, Box::new(batch), &options).expect("lockstep run");
        r.execute(|_, _| {}).expect("run");
        (b, r)
    };
    let alone = |s: &Scene| {
        let p = s.sample_particles().expect("particles");
        let b = CudaBackend::new(s, &p, precise()).expect("world");
        let mut sim = Simulation::with_backend(s.clone(), Box::new(b));
        for _ in 0..3 {
            sim.advance_frame().expect("stable");
        }
        read(sim.backend.as_mut())
    };
    let mut failures = Vec::new();
    let (b, r) = lockstep(None);
    assert_eq!((r.sim.frame, r.running()), (3, 4));
    let separate: Vec<Particles> = b.worlds.iter().map(alone).collect();
    for (w, want) in separate.iter().enumerate() {
        failures.extend(agrees(
            &format!("lockstep world {w} after 3 frames"),
            None,
            r.worlds[w].particles(),
            want,
            b.worlds[w].dx,
        ));
    }
    let (_, r) = lockstep(Some(2));
    match &r.worlds[2].status {
        WorldStatus::Frozen { frame, reason } => {
            assert_eq!(*frame, 0, "{reason}");
            assert!(
                reason.contains("blew up") || reason.contains("time step"),
                "{reason}"
            );
        }
        other => panic!("world 2 should be frozen: {other:?}"),
    }
    for w in [0, 1, 3] {
        assert_eq!(r.worlds[w].status, WorldStatus::Running);
        failures.extend(agrees(
            &format!("lockstep world {w} beside a frozen one"),
            None,
            r.worlds[w].particles(),
            &separate[w],
            b.worlds[w].dx,
        ));
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Checkpoints of a GPU batch (`rtmpm run --backend cuda --checkpoint-every`, `--resume`:
/// `LockstepRun::checkpoint` / `resume` over `CudaBatch`): four wedge worlds at a fixed step,
/// one of them blown up and frozen in frame 1, run to frame 4 with a checkpoint every 2
/// frames, against a run cut at frame 2 and resumed from its `checkpoint_00002/`. The same
/// files in both folders; the frozen world stays frozen; every running world of the resumed
/// run agrees with the uninterrupted one within the agreement test's aggregate tolerances (the
/// resumed batch starts from the saved particles in their original order, so its atomic sums
/// add in another order: not bit for bit; bit for bit on the CPU,
/// `crates/rtmpm-cpu/tests/lockstep_files.rs`).
#[test]
#[ignore = "needs a CUDA GPU"]
fn a_resumed_gpu_batch_goes_on_as_the_uninterrupted_one() {
    use rtmpm_driver::batch::lockstep::LockstepRun;
    use rtmpm_driver::batch::{BatchOptions, WorldStatus};
    if !gpu() {
        return;
    }
    let path = wedge_path();
    let mut b = BatchScene::from_file(&path).expect("wedge_slump.toml");
    b.worlds = wedge_worlds(4)
        .into_iter()
        .enumerate()
        .map(|(w, mut s)| {
            s.time.step = rtmpm_scene::StepMode::Fixed { dt: DT };
            if w == 2 {
                s.bodies[0].velocity = Vec3::new(1e5, 0.0, 0.0);
            }
            s
        })
        .collect();
    let top = std::env::temp_dir().join(format!("rtmpm-gpu-batch-ckpt-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&top);
    let options = |dir: &str, frames: u64| BatchOptions {
        frames: Some(frames),
        out_dir: Some(top.join(dir)),
        overwrite: false,
    };
    let make = |p: &[Particles]| {
        let batch = CudaBatch::new(&b.worlds, p, precise())?;
        Ok::<_, rtmpm_sim::SimError>((batch.scene().clone(), Box::new(batch)))
    };
    let every = Some((2, "wedge", "wedge.toml"));
    let fresh = |dir: &str, frames: u64| {
        let p0: Vec<Particles> = b
            .worlds
            .iter()
            .map(|s| s.sample_particles().expect("particles"))
            .collect();
        let (scene, batch) = make(&p0).expect("batch");
        let mut r = LockstepRun::new(&b, "wedge", scene, batch, &options(dir, frames))
            .expect("lockstep run");
        r.execute_checkpointed(every, |_, _| {}).expect("run");
        r
    };
    let whole = fresh("whole", 4);
    assert_eq!((whole.sim.frame, whole.running()), (4, 3));
    drop(fresh("cut", 2));
    let ckpt = top.join("cut").join("checkpoint_00002");
    let mut again = LockstepRun::resume(&b, "wedge", &ckpt, |p| Ok(make(p)?), &options("cut", 4))
        .expect("resume");
    assert_eq!((again.sim.frame, again.sim.step), (2, whole.sim.step / 2));
    again
        .execute_checkpointed(every, |_, _| {})
        .expect("run on");
    assert!(matches!(
        again.worlds[2].status,
        WorldStatus::Frozen { frame: 0, .. }
    ));
    let names = |dir: &str| {
        let mut n = Vec::new();
        let mut stack = vec![top.join(dir)];
        while let Some(d) = stack.pop() {
            for e in std::fs::read_dir(&d).expect("folder").flatten() {
                let p = e.path();
                if p.is_dir() {
                    stack.push(p);
                } else {
                    n.push(
                        p.strip_prefix(top.join(dir))
                            .expect("under")
                            .display()
                            .to_string(),
                    );
                }
            }
        }
        n.sort();
        n
    };
    assert_eq!(names("whole"), names("cut"));
    assert!(names("cut").contains(&"checkpoint_00004/world_003.ckpt".to_string()));
    let mut failures = Vec::new();
    for w in [0, 1, 3] {
        failures.extend(agrees(
            &format!("resumed world {w} at frame 4"),
            None,
            again.worlds[w].particles(),
            whole.worlds[w].particles(),
            b.worlds[w].dx,
        ));
    }
    assert!(
        bit_identical(again.worlds[2].particles(), whole.worlds[2].particles()),
        "the frozen world keeps its frame-0 state"
    );
    std::fs::remove_dir_all(&top).expect("clean up");
    assert!(failures.is_empty(), "{failures:#?}");
}
