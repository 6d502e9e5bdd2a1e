//! Batches of worlds on the CPU backend: every world gives, bit for bit, the particles of its
//! own separate run, and a world that blows up is frozen while the others go on unchanged.

use rtmpm_sim::Particles;
mod common;

use common::bits;
use common::cpu::CpuBackend;
use rtmpm_driver::Simulation;
use rtmpm_driver::batch::{BatchOptions, BatchRun, WorldStatus};
use rtmpm_scene::{BatchScene, Scene};
use rtmpm_sim::Backend;

/// A small slump: a column of Herschel-Bulkley mud on a sticky floor.
const SLUMP: &str = r#"name = "slump"
[domain]
min = [0.0, 0.0, 0.0]
max = [0.5, 0.5, 0.5]
dx = 0.03125
[time]
duration = 0.15
fps = 20
TIME
[walls]
thickness = 3
faces.y_min = { condition = "sticky" }
[[material]]
name = "mud"
type = "herschel_bulkley"
density = 1600.0
bulk_modulus = 1e5
shear_modulus = 1e4
yield_stress = 250.0
consistency = 10.0
[[body]]
material = "mud"
shape = "box"
min = [0.2, 0.1, 0.2]
max = [0.3, 0.25, 0.3]
particles_per_cell = 8
"#;

fn backend(scene: &Scene) -> anyhow::Result<Box<dyn Backend>> {
    let p = scene.sample_particles()?;
    Ok(Box::new(CpuBackend::new(scene, p, None)?))
}

/// World `scene` run alone for `frames` frames.
fn alone(scene: &Scene, frames: u64) -> Particles {
    let mut sim = Simulation::new(scene.clone(), backend(scene).expect("backend"));
    for _ in 0..frames {
        sim.advance_frame().expect("stable");
    }
    let mut p = Particles::default();
    sim.backend.read_particles(&mut p).expect("read");
    p
}

fn run(text: &str, frames: u64) -> (BatchScene, BatchRun) {
    let b = BatchScene::from_toml(text, "wedge.toml").unwrap_or_else(|e| panic!("{e}"));
    let options = BatchOptions {
        frames: Some(frames),
        ..BatchOptions::default()
    };
    let mut r = BatchRun::new(&b, text, |s, _| backend(s), &options).expect("batch");
    r.execute(|_, _| {}).expect("run");
    (b, r)
}

#[test]
fn every_world_is_its_separate_run_bit_for_bit() {
    let text = SLUMP.replace("TIME", "cfl = 0.4")
        + "[batch]\ncount = 3\n[batch.sweep]\n\"material[0].yield_stress\" = [20, 150, 600]\n\"gravity[1]\" = [-9.81, -5, -9.81]\n";
    let (b, r) = run(&text, 3);
    let mut seen = Vec::new();
    for (w, world) in r.worlds.iter().enumerate() {
        assert_eq!(world.status, WorldStatus::Running);
        assert_eq!(world.sim.frame, 3);
        let separate = alone(&b.worlds[w], 3);
        assert!(separate.len() > 300);
        assert_eq!(
            bits(world.particles()),
            bits(&separate),
            "world {w} differs from its separate run"
        );
        seen.push(bits(&separate));
    }
    // The sweeps matter: the worlds are not all one.
    assert_ne!(seen[0], seen[1]);
    assert_ne!(seen[0], seen[2]);
}

#[test]
fn a_world_that_blows_up_is_frozen_and_the_others_go_on_unchanged() {
    // A fixed step: world 1's body starts far too fast and blows up in its first frame.
    let text = SLUMP.replace("TIME", "dt = 1e-3")
        + "[batch]\ncount = 3\n[batch.sweep]\n\"body[0].velocity\" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]\n";
    let (b, r) = run(&text, 3);
    match &r.worlds[1].status {
        WorldStatus::Frozen { frame, reason } => {
            assert_eq!(*frame, 0);
            assert!(
                reason.contains("blew up") || reason.contains("speed"),
                "{reason}"
            );
        }
        other => panic!("world 1 should be frozen: {other:?}"),
    }
    // Frozen at its frame 0: the particles kept are its initial ones.
    let initial = b.worlds[1].sample_particles().expect("sample");
    assert_eq!(r.worlds[1].particles().x, initial.x);
    for w in [0, 2] {
        assert_eq!(r.worlds[w].status, WorldStatus::Running);
        assert_eq!(
            bits(r.worlds[w].particles()),
            bits(&alone(&b.worlds[w], 3)),
            "world {w} differs from its separate run"
        );
    }
}

#[test]
fn progress_inside_a_frame_counts_the_running_worlds() {
    // World 1 blows up in the first frame: that frame reports 3 worlds, the next two report 2.
    let text = SLUMP.replace("TIME", "dt = 1e-3")
        + "[batch]\ncount = 3\n[batch.sweep]\n\"body[0].velocity\" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]\n";
    let b = BatchScene::from_toml(&text, "wedge.toml").unwrap_or_else(|e| panic!("{e}"));
    let options = BatchOptions {
        frames: Some(3),
        ..BatchOptions::default()
    };
    let mut r = BatchRun::new(&b, &text, |s, _| backend(s), &options).expect("batch");
    let seen = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let log = seen.clone();
    r.on_world_done(move |done, of| log.lock().expect("log").push((done, of)));
    r.execute(|_, _| {}).expect("run");
    let seen = seen.lock().expect("log").clone();
    assert_eq!(
        seen,
        [(1, 3), (2, 3), (3, 3), (1, 2), (2, 2), (1, 2), (2, 2)]
    );
}

#[test]
fn a_world_reset_starts_again_and_the_others_go_on_unchanged() {
    let text = SLUMP.replace("TIME", "cfl = 0.4")
        + "[batch]\ncount = 3\n[batch.sweep]\n\"material[0].yield_stress\" = [20, 150, 600]\n";
    let b = BatchScene::from_toml(&text, "wedge.toml").unwrap_or_else(|e| panic!("{e}"));
    let mut r =
        BatchRun::new(&b, &text, |s, _| backend(s), &BatchOptions::default()).expect("batch");
    r.write_first_frame().expect("frame 0");
    for _ in 0..2 {
        assert!(r.advance_frame().expect("frame").is_empty());
    }
    r.reset_world(1, backend).expect("reset");
    assert_eq!(r.worlds[1].sim.frame, 0);
    assert_eq!(
        r.worlds[1].particles().x,
        b.worlds[1].sample_particles().expect("sample").x
    );
    for _ in 0..2 {
        r.advance_frame().expect("frame");
    }
    // World 1 is two frames into its run again; the others four, as if nothing happened.
    assert_eq!(bits(r.worlds[1].particles()), bits(&alone(&b.worlds[1], 2)));
    for w in [0, 2] {
        assert_eq!(r.worlds[w].sim.frame, 4);
        assert_eq!(
            bits(r.worlds[w].particles()),
            bits(&alone(&b.worlds[w], 4)),
            "world {w}"
        );
    }
    assert!(r.reset_world(3, backend).is_err());
}

#[test]
#[cfg_attr(
    feature = "f64",
    ignore = "a checkpoint holds the particles' f32 interface state: an f64 run resumes from it \
              rounded, not bit for bit"
)]
fn a_resumed_batch_goes_on_bit_for_bit_as_the_run_that_saved_it() {
    // A CFL step (the clock matters) and a world that blows up: its frozen state and status
    // are saved and resumed too.
    let text = SLUMP.replace("TIME", "cfl = 0.4\nmax_dt = 1e-3")
        + "[batch]\ncount = 3\n[batch.sweep]\n\"material[0].yield_stress\" = [20, 150, 600]\n\
           \"body[0].velocity\" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]\n";
    let b = BatchScene::from_toml(&text, "wedge.toml").unwrap_or_else(|e| panic!("{e}"));
    let options = BatchOptions::default();
    let mut r = BatchRun::new(&b, &text, |s, _| backend(s), &options).expect("batch");
    r.write_first_frame().expect("frame 0");
    for _ in 0..2 {
        r.advance_frame().expect("frame");
    }
    r.advance_steps(7).expect("steps");
    assert!(matches!(r.worlds[1].status, WorldStatus::Frozen { .. }));
    let dir = std::env::temp_dir().join(format!("rtmpm-batch-ckpt-{}", std::process::id()));
    r.checkpoint(&dir, &text, "wedge.toml").expect("checkpoint");
    for _ in 0..2 {
        r.advance_frame().expect("frame");
    }
    let cpu = |s: &Scene, _: usize, p: Particles| -> anyhow::Result<Box<dyn Backend>> {
        Ok(Box::new(CpuBackend::new(s, p, None)?))
    };
    let mut resumed = BatchRun::resume(&b, &text, &dir, cpu, &options).expect("resume");
    for _ in 0..2 {
        resumed.advance_frame().expect("frame");
    }
    for (w, (a, c)) in r.worlds.iter().zip(&resumed.worlds).enumerate() {
        assert_eq!(a.status, c.status, "world {w}");
        assert_eq!(
            (a.sim.step, a.sim.frame),
            (c.sim.step, c.sim.frame),
            "world {w}"
        );
        assert_eq!(a.sim.time.to_bits(), c.sim.time.to_bits(), "world {w}");
        assert!(a.particles().len() > 300);
        assert_eq!(bits(a.particles()), bits(c.particles()), "world {w}");
    }
    assert_eq!(r.worlds[0].sim.frame, 4);
    // Another scene text, or another batch, is refused with the reason.
    let other = text.replace("consistency = 10.0", "consistency = 11.0");
    let ob = BatchScene::from_toml(&other, "wedge.toml").unwrap_or_else(|e| panic!("{e}"));
    let e = BatchRun::resume(&ob, &other, &dir, cpu, &options)
        .err()
        .expect("refused");
    assert!(format!("{e:#}").contains("another scene text"), "{e:#}");
    let e = BatchRun::resume(&b, &text, &dir.join("missing"), cpu, &options)
        .err()
        .expect("refused");
    assert!(format!("{e:#}").contains("no batch checkpoint"), "{e:#}");
    std::fs::remove_dir_all(&dir).expect("remove the checkpoint this test wrote");
}
