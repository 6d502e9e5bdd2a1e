//! Batches of worlds in the same CUDA kernels (`rtmpm_cuda::batch::CudaBatch`) against the
//! same worlds run one by one on the CUDA backend (needs a GPU; skips with a message otherwise):
//! `cargo test --release -p rtmpm-cuda --test batch -- --include-ignored --nocapture`.
//! The benchmark (`batch_benchmark`, ignored) prints particle-steps/s of a batch of sand beds,
//! of one scene with as many particles and of the worlds one after another (their steps only,
//! and with each world's set-up: its backend built in the same process), and a final table of
//! the ratios.

use rtmpm_cuda::batch::CudaBatch;
use rtmpm_cuda::{CudaBackend, CudaOptions, probe};
use rtmpm_physics::Particles;
use rtmpm_physics::math::Vec3;
use rtmpm_scene::{BatchScene, Scene};
use rtmpm_sim::Backend;
use std::path::Path;
use std::time::Instant;

fn gpu() -> bool {
    match probe() {
        Ok(_) => true,
        Err(e) => {
            println!("skipped: no usable CUDA GPU ({e})");
            false
        }
    }
}

/// Precise math, as the agreement tests compare.
fn precise() -> CudaOptions {
    CudaOptions {
        fast_math: false,
        ..CudaOptions::default()
    }
}

/// The wedge example's 16 worlds (yield stress 25..1600 Pa), each with its own gravity too
/// (strength 0.6..1.35 g, and a sideways pull of -1, 0 or +1 m/s^2 along x).
fn wedge_worlds(count: usize) -> Vec<Scene> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/wedge_slump.toml");
    let b = BatchScene::from_file(&path).expect("wedge_slump.toml");
    b.worlds
        .into_iter()
        .take(count)
        .enumerate()
        .map(|(w, mut s)| {
            s.gravity = Vec3::new((w % 3) as f32 - 1.0, -9.81 * (0.6 + 0.05 * w as f32), 0.0);
            s
        })
        .collect()
}

fn read(b: &mut dyn Backend) -> Particles {
    let mut p = Particles::default();
    b.read_particles(&mut p).expect("read particles");
    p
}

fn max_diff(a: &Particles, b: &Particles) -> (f32, f32) {
    assert_eq!(a.len(), b.len());
    let mut dx = 0.0f32;
    let mut dv = 0.0f32;
    for i in 0..a.len() {
        dx = dx.max((a.x[i] - b.x[i]).length());
        dv = dv.max((a.v[i] - b.v[i]).length());
    }
    (dx, dv)
}

fn bit_identical(a: &Particles, b: &Particles) -> bool {
    let bits = |p: &Particles| {
        p.x.iter()
            .chain(&p.v)
            .flat_map(|v| v.to_array())
            .map(f32::to_bits)
            .collect::<Vec<_>>()
    };
    bits(a) == bits(b)
}

/// The agreement test's tolerances (tests/agreement.rs) between a world of the batch and its
/// separate run: after one step every particle (|dx| <= 1e-5 dx + 1e-6, |dv| <= 1e-3 of the
/// speed scale); after `steps` the centre of mass within 0.1 cell, kinetic energy within 2 %,
/// bounding box within a cell.
fn agrees(
    what: &str,
    one_step: Option<(&Particles, &Particles)>,
    a: &Particles,
    b: &Particles,
    dx: f32,
) -> Vec<String> {
    let mut failures = Vec::new();
    if let Some((a1, b1)) = one_step {
        let vscale = a1.v.iter().map(|v| v.length()).fold(1e-3f32, f32::max);
        let (wx, wv) = max_diff(a1, b1);
        if wx > 1e-5 * dx.max(1e-3) + 1e-6 || wv > 1e-3 * vscale {
            failures.push(format!(
                "{what}: first step differs: |dx| {wx:.3e}, |dv| {wv:.3e}"
            ));
        }
    }
    let d = a.aggregate_difference(b);
    let (wx, wv) = max_diff(a, b);
    let dxd = dx as f64;
    println!(
        "{what}: |d com| {:.3e} m ({:.4} dx), KE {:.4e} vs {:.4e} ({:.3} %), |d bbox| {:.2} dx, max particle |dx| {wx:.3e} m |dv| {wv:.3e} m/s",
        d.com,
        d.com / dxd,
        a.kinetic_energy(),
        b.kinetic_energy(),
        100.0 * d.kinetic,
        d.bbox / dxd
    );
    if d.com > 0.1 * dxd || d.kinetic > 0.02 || d.bbox > dxd {
        failures.push(format!("{what}: aggregates differ"));
    }
    failures
}

const DT: f32 = 1e-3;

/// Isolation: 16 worlds with different yield stress and gravity in one batch give, world by
/// world, the particles of 16 separate CUDA runs (the agreement test's tolerances), while the
/// worlds differ from each other by far more than that.
#[test]
#[ignore = "needs a CUDA GPU"]
fn a_batch_gives_each_world_its_separate_run() {
    if !gpu() {
        return;
    }
    let steps: usize = std::env::var("BATCH_TEST_STEPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(200);
    let worlds = wedge_worlds(16);
    let p0: Vec<Particles> = worlds
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    let mut batch = CudaBatch::new(&worlds, &p0, precise()).expect("batch");
    let mut single: Vec<CudaBackend> = worlds
        .iter()
        .zip(&p0)
        .map(|(s, p)| CudaBackend::new(s, p, precise()).expect("world"))
        .collect();
    batch.step(DT, 0.0).expect("batch step");
    for b in &mut single {
        b.step(DT, 0.0).expect("step");
    }
    let first_batch = batch.read_worlds().expect("read");
    let first_single: Vec<Particles> = single.iter_mut().map(|b| read(b)).collect();
    for s in 1..steps {
        let t = s as f32 * DT;
        batch.step(DT, t).expect("batch step");
        for b in &mut single {
            b.step(DT, t).expect("step");
        }
    }
    assert!(
        batch.bad_world().expect("check").is_none(),
        "a world blew up"
    );
    let got = batch.read_worlds().expect("read");
    let mut failures = Vec::new();
    for w in 0..worlds.len() {
        let want = read(&mut single[w]);
        failures.extend(agrees(
            &format!("world {w:2} after {steps} steps"),
            Some((&first_batch[w], &first_single[w])),
            &got[w],
            &want,
            worlds[w].dx,
        ));
    }
    // The test can tell worlds apart: the first and last world end far apart.
    let d = got[0].aggregate_difference(&got[15]);
    println!(
        "world 0 vs world 15: |d com| {:.3e} m ({:.2} dx)",
        d.com,
        d.com / worlds[0].dx as f64
    );
    assert!(
        d.com > worlds[0].dx as f64,
        "the worlds do not differ: the check could not see a mix-up"
    );
    assert!(failures.is_empty(), "{failures:#?}");
}

/// A reset world (put back to its initial particles mid-run) goes on as a fresh run of its own,
/// and the other worlds as in the same batch without the reset; a world that blows up (gravity
/// of 10^7 m/s^2) is reported as that world, and the others still agree with their separate runs.
#[test]
#[ignore = "needs a CUDA GPU"]
fn a_reset_or_blown_up_world_leaves_the_others_as_they_were() {
    if !gpu() {
        return;
    }
    let worlds = wedge_worlds(4);
    let p0: Vec<Particles> = worlds
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    let run = |reset_at: Option<usize>, steps: usize| {
        let mut b = CudaBatch::new(&worlds, &p0, precise()).expect("batch");
        for s in 0..steps {
            if reset_at == Some(s) {
                b.put_world(1, &p0[1]).expect("reset world 1");
            }
            b.step(DT, s as f32 * DT).expect("step");
        }
        b.read_worlds().expect("read")
    };
    let plain = run(None, 100);
    let again = run(None, 100);
    let reset = run(Some(50), 100);
    let alone_50 = {
        let mut b = CudaBackend::new(&worlds[1], &p0[1], precise()).expect("world 1");
        for s in 0..50 {
            b.step(DT, s as f32 * DT).expect("step");
        }
        read(&mut b)
    };
    let mut failures = Vec::new();
    let dx = worlds[0].dx;
    for w in [0, 2, 3] {
        println!(
            "world {w}: bit-identical to the batch without the reset: {}; two runs of the same batch bit-identical: {}",
            bit_identical(&reset[w], &plain[w]),
            bit_identical(&again[w], &plain[w])
        );
        failures.extend(agrees(
            &format!("world {w} beside a reset"),
            None,
            &reset[w],
            &plain[w],
            dx,
        ));
    }
    // World 1 after its reset at step 50 and 50 more steps: a 50-step run of its own.
    failures.extend(agrees(
        "world 1 reset at 50, 50 steps on",
        None,
        &reset[1],
        &alone_50,
        dx,
    ));
    let d = reset[1].aggregate_difference(&plain[1]);
    assert!(
        d.com > 0.1 * dx as f64,
        "the reset changed nothing: |d com| {:.3e}",
        d.com
    );

    // Blow-up: world 2's gravity 10^7 m/s^2.
    let mut bad = worlds.clone();
    bad[2].gravity = Vec3::new(0.0, -1e7, 0.0);
    let mut b = CudaBatch::new(&bad, &p0, precise()).expect("batch");
    let mut reported = None;
    for s in 0..100 {
        b.step(DT, s as f32 * DT).expect("step");
        if let Some((w, p)) = b.bad_world().expect("check") {
            reported.get_or_insert((s, w, p.index));
            assert_eq!(
                w, 2,
                "the blow-up reported in world {w}, particle {}",
                p.index
            );
        }
    }
    let (s, w, i) = reported.expect("world 2 blew up and was reported");
    println!("blow-up: world {w} particle {i} reported at step {s}");
    let got = b.read_worlds().expect("read");
    for w in [0, 1, 3] {
        failures.extend(agrees(
            &format!("world {w} beside a blow-up"),
            None,
            &got[w],
            &plain[w],
            dx,
        ));
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Worlds put at once (`CudaBatch::put_worlds`: runs of consecutive worlds packed as one, one
/// upload) hold what one `put_world` a world leaves, bit for bit, the worlds not listed
/// untouched; a world listed twice ends with its last; a list with one bad entry is refused
/// before any world changes.
#[test]
#[ignore = "needs a CUDA GPU"]
fn worlds_put_at_once_hold_what_one_put_a_world_leaves() {
    if !gpu() {
        return;
    }
    let worlds = wedge_worlds(5);
    let p0: Vec<Particles> = worlds
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    let mut b = CudaBatch::new(&worlds, &p0, precise()).expect("batch");
    for s in 0..20 {
        b.step(DT, s as f32 * DT).expect("step");
    }
    let before = b.read_worlds().expect("read");
    // World w's new state: its initial particles, moving at (w + 1) m/s along x.
    let moving = |w: usize, speed: f32| {
        let mut p = p0[w].clone();
        p.v.iter_mut().for_each(|v| *v = Vec3::new(speed, 0.0, 0.0));
        p
    };
    let list = vec![
        (3, moving(3, 9.0)),
        (0, moving(0, 1.0)),
        (1, moving(1, 2.0)),
        (3, moving(3, 4.0)),
    ];
    let mut short = p0[4].clone();
    short.x.pop();
    let refused = b.put_worlds(&[(0, moving(0, 7.0)), (4, short)]);
    assert!(
        refused.is_err(),
        "a world given too few particles is refused"
    );
    let untouched = b.read_worlds().expect("read");
    for w in 0..5 {
        assert!(
            bit_identical(&untouched[w], &before[w]),
            "world {w} changed by a refused put"
        );
    }
    b.put_worlds(&list).expect("put worlds at once");
    let at_once = b.read_worlds().expect("read");
    for (w, p) in &list {
        b.put_world(*w, p).expect("put one world");
    }
    let one_each = b.read_worlds().expect("read");
    for w in 0..5 {
        assert!(
            bit_identical(&at_once[w], &one_each[w]),
            "world {w}: put at once differs from one put a world"
        );
    }
    for w in [2, 4] {
        assert!(bit_identical(&at_once[w], &before[w]), "world {w} touched");
    }
    for (w, speed) in [(0, 1.0), (1, 2.0), (3, 4.0)] {
        let p = &at_once[w];
        assert!(
            p.v.iter().all(|v| *v == Vec3::new(speed, 0.0, 0.0)),
            "world {w}'s v"
        );
        assert!(
            p.x.iter()
                .zip(&p0[w].x)
                .all(|(a, b)| (*a - *b).length() < 1e-6),
            "world {w}'s x"
        );
    }
    assert!(b.put_bytes() > 0);
    // Steps go on from the worlds put (the next step rebuilds the mapping).
    for s in 0..5 {
        b.step(DT, s as f32 * DT).expect("step after the put");
    }
    assert!(b.bad_world().expect("check").is_none());
}

/// A put rebuilds the particle-to-block mapping only where a particle put leaves the free zone
/// of the gblock its slot is sorted into (`kernels/batch.cu`): four sand beds after 10 steps
/// (settled by a few thousandths of a cell), world 1 put back as it is, world 2 reset to its
/// start and world 0 put at its start moved one cell along x and one back along z (still in
/// every zone: a base may go 4 cells below its block and 5 above its block's first) cost no
/// rebuild, and all three go on as their separate runs from those states (every particle after
/// one step within the agreement test's first-step tolerance, the aggregates after 20): the
/// mapping they kept holds them. World 3 put 3 cells along x (the particles of each block's
/// last cell column leave its zone) asks for a rebuild at the next step, and goes on as its
/// separate run from there too. About 10 s on an H200 (most of it the programs' compiles on a
/// cold cache).
#[test]
#[ignore = "needs a CUDA GPU"]
fn a_put_rebuilds_the_mapping_only_where_a_particle_leaves_its_zone() {
    if !gpu() {
        return;
    }
    let dt = 2.5e-4;
    let world = Scene::from_toml(&sand_bed(0.109375), "sand_bed").expect("scene");
    let worlds = vec![world.clone(); 4];
    let p0: Vec<Particles> = worlds
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    let mut b = CudaBatch::new(&worlds, &p0, precise()).expect("batch");
    let mut t = 0.0f32;
    for _ in 0..10 {
        b.step(dt, t).expect("step");
        t += dt;
    }
    let now = b.read_worlds().expect("read");
    let rebuilds = |b: &mut CudaBatch| b.backend().rebuild_count().expect("control words");
    let before = rebuilds(&mut b);
    let moved = |p: &Particles, by: Vec3| {
        let mut q = p.clone();
        q.x.iter_mut().for_each(|x| *x += by * world.dx);
        q
    };
    let shifted = moved(&p0[3], Vec3::new(3.0, 0.0, 0.0));
    // The separate runs from the states put, and the batch's worlds after the same steps.
    let starts = [
        (0, moved(&p0[0], Vec3::new(1.0, 0.0, -1.0))),
        (1, now[1].clone()),
        (2, p0[2].clone()),
    ];
    b.put_worlds(&starts).expect("put worlds 0, 1 and 2");
    b.step(dt, t).expect("step after the put");
    assert_eq!(
        rebuilds(&mut b),
        before,
        "worlds put within their blocks' free zones rebuilt the mapping"
    );
    let one_step = b.read_worlds().expect("read");
    b.put_world(3, &shifted)
        .expect("put world 3 three cells along x");
    b.step(dt, t + dt).expect("step after the shifted put");
    assert_eq!(
        rebuilds(&mut b),
        before + 1,
        "a world put three cells away did not rebuild the mapping"
    );
    let shifted_one = b.read_worlds().expect("read");
    for s in 2..21 {
        b.step(dt, t + s as f32 * dt).expect("step");
    }
    let got = b.read_worlds().expect("read");
    let alone = |p: &Particles, steps: usize| {
        let mut one = CudaBackend::new(&world, p, precise()).expect("world alone");
        let mut out = Vec::new();
        for s in 0..steps {
            one.step(dt, s as f32 * dt).expect("step");
            if s == 0 || s + 1 == steps {
                out.push(read(&mut one));
            }
        }
        out
    };
    let mut failures = Vec::new();
    let dx = world.dx;
    for (w, p) in &starts {
        let runs = alone(p, 21);
        failures.extend(agrees(
            &format!("world {w} put without a rebuild"),
            Some((&one_step[*w], &runs[0])),
            &got[*w],
            &runs[1],
            dx,
        ));
    }
    let runs = alone(&shifted, 20);
    failures.extend(agrees(
        "world 3 put three cells along x",
        Some((&shifted_one[3], &runs[0])),
        &got[3],
        &runs[1],
        dx,
    ));
    for (w, cells) in [(3, 2.0), (0, 1.0)] {
        let d = got[w].aggregate_difference(&got[2]);
        assert!(
            d.com > cells * dx as f64,
            "world {w} is not where it was put, more than {cells} cells from world 2: |d com| \
             {:.3e}",
            d.com
        );
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Worlds that cannot share the arrays, and a batch larger than the GPU, are refused before
/// anything is allocated, with the numbers.
#[test]
#[ignore = "needs a CUDA GPU"]
fn a_batch_the_gpu_cannot_hold_is_refused_with_the_numbers() {
    if !gpu() {
        return;
    }
    let mut worlds = wedge_worlds(2);
    let p0: Vec<Particles> = worlds
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    worlds[1].dx *= 0.5;
    let e = CudaBatch::new(&worlds, &p0, precise())
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("world 1 differs"), "{e}");
    // 8,000 worlds of a 4 m x 4 m floor (160 x 160 cells of grid each): far past the GPU's memory.
    let text = r#"
name = "wide"
[time]
duration = 0.1
fps = 10
dt = 1e-3
[domain]
min = [0.0, 0.0, 0.0]
max = [4.0, 0.3, 4.0]
dx = 0.025
[[material]]
name = "sand"
type = "drucker_prager"
density = 1600.0
youngs_modulus = 3.5e5
poisson_ratio = 0.3
friction_angle = 35.0
[[body]]
material = "sand"
shape = "box"
min = [1.9, 0.1, 1.9]
max = [2.0, 0.15, 2.0]
particles_per_cell = 1
"#;
    let one = Scene::from_toml(text, "wide").expect("scene");
    let p = one.sample_particles().expect("particles");
    let n = 8000;
    let t = Instant::now();
    let e = CudaBatch::new(&vec![one; n], &vec![p; n], CudaOptions::default())
        .err()
        .expect("refused")
        .to_string();
    println!("refused in {:.1} s: {e}", t.elapsed().as_secs_f64());
    assert!(
        e.contains("CUDA batch of 8000 worlds") && e.contains("GiB") && e.contains("free"),
        "{e}"
    );
}

// ---------------------------------------------------------------------------------------------
// Benchmark.

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
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/wedge_slump.toml");
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
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/wedge_slump.toml");
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

/// Checkpoints of a GPU batch (`rtmpm run --backend cuda --checkpoint-every`, `--resume`:
/// `LockstepRun::checkpoint` / `resume` over `CudaBatch`): four wedge worlds at a fixed step,
/// one of them blown up and frozen in frame 1, run to frame 4 with a checkpoint every 2
/// frames, against a run cut at frame 2 and resumed from its `checkpoint_00002/`. The same
/// files in both folders; the frozen world stays frozen; every running world of the resumed
/// run agrees with the uninterrupted one within the agreement test's aggregate tolerances (the
/// resumed batch starts from the saved particles in their original order, so its atomic sums
/// add in another order: not bit for bit; bit for bit on the CPU,
/// `crates/rtmpm-cpu/tests/lockstep.rs`).
#[test]
#[ignore = "needs a CUDA GPU"]
fn a_resumed_gpu_batch_goes_on_as_the_uninterrupted_one() {
    use rtmpm_driver::batch::lockstep::LockstepRun;
    use rtmpm_driver::batch::{BatchOptions, WorldStatus};
    if !gpu() {
        return;
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/wedge_slump.toml");
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

/// A small sand bed: 14 x 6 x 14 cells of sand at 8 particles a cell (9,408 particles) dropped
/// 3 cells onto a sticky floor in a 32 x 20 x 32-cell box (dx = 1/64 m), fixed dt.
fn sand_bed(half: f32) -> String {
    let lo = 0.25 - half;
    let hi = 0.25 + half;
    let (dmin, dmax) = (0.0, 0.5 + 2.0 * (half - 0.109375).max(0.0));
    let shift = (dmax - 0.5) / 2.0;
    format!(
        r#"
name = "sand_bed"
seed = 1
[domain]
min = [{dmin}, 0.0, {dmin}]
max = [{dmax}, 0.3125, {dmax}]
dx = 0.015625
[time]
duration = 1.0
fps = 50
dt = 2.5e-4
[walls]
condition = "slip"
faces.y_min = {{ condition = "sticky" }}
[[material]]
name = "sand"
type = "drucker_prager"
density = 1600.0
youngs_modulus = 3.5e5
poisson_ratio = 0.3
friction_angle = 35.0
[[body]]
material = "sand"
shape = "box"
min = [{a}, 0.09375, {a}]
max = [{b}, 0.1875, {b}]
particles_per_cell = 8
sampling = "regular"
"#,
        a = lo + shift,
        b = hi + shift
    )
}

/// Seconds of `steps` steps of `b` after 20 steps of warm-up, the GPU's work included (the
/// control words read back at the end wait for it).
fn time_steps(b: &mut dyn Backend, steps: usize) -> f64 {
    let dt = 2.5e-4;
    for s in 0..20 {
        b.step(dt, s as f32 * dt).expect("step");
    }
    b.max_speed().expect("sync");
    let t = Instant::now();
    for s in 20..20 + steps {
        b.step(dt, s as f32 * dt).expect("step");
    }
    b.max_speed().expect("sync");
    t.elapsed().as_secs_f64()
}

/// One world run as a user running the worlds one by one in one process pays it: its backend
/// built (checks, plan, the program from the kernel cache, the particles packed and uploaded)
/// and `steps` steps from its start (no warm-up: the first steps' graph capture is part of the
/// run), the GPU's work included. Returns (set-up seconds, whole-run seconds).
fn time_world_run(world: &Scene, p: &Particles, steps: usize) -> (f64, f64) {
    let dt = 2.5e-4;
    let t = Instant::now();
    let mut b = CudaBackend::new(world, p, CudaOptions::default()).expect("world");
    let setup = t.elapsed().as_secs_f64();
    for s in 0..steps {
        b.step(dt, s as f32 * dt).expect("step");
    }
    b.max_speed().expect("sync");
    let whole = t.elapsed().as_secs_f64();
    drop(b);
    (setup, whole)
}

/// `BATCH_WORLDS` (1024) sand beds of 9,408 particles: particle-steps/s batched, as one scene
/// of as many particles, and one after another (`BATCH_ALONE` worlds, 16, extrapolated).
#[test]
#[ignore = "needs a CUDA GPU; a benchmark"]
fn batch_benchmark() {
    if !gpu() {
        return;
    }
    let env = |k: &str, d: usize| {
        std::env::var(k)
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(d)
    };
    let (n_worlds, steps, alone) = (
        env("BATCH_WORLDS", 1024),
        env("BATCH_STEPS", 200),
        env("BATCH_ALONE", 16),
    );
    let world = Scene::from_toml(&sand_bed(0.109375), "sand_bed").expect("sand bed");
    let p = world.sample_particles().expect("particles");
    let per = p.len();
    let t = Instant::now();
    let mut batch = CudaBatch::new(
        &vec![world.clone(); n_worlds],
        &vec![p.clone(); n_worlds],
        CudaOptions::default(),
    )
    .expect("batch");
    let setup = t.elapsed().as_secs_f64();
    let secs = time_steps(batch.backend(), steps);
    let total = (n_worlds * per) as f64;
    let batched = total * steps as f64 / secs;
    assert!(batch.bad_world().expect("check").is_none());
    drop(batch);

    // One scene of as many particles: a bed sqrt(n_worlds) times as wide each way.
    let half = 0.109375 * (n_worlds as f32).sqrt();
    let big = Scene::from_toml(&sand_bed(half), "sand_bed_big").expect("big bed");
    let bp = big.sample_particles().expect("particles");
    let mut one = CudaBackend::new(&big, &bp, CudaOptions::default()).expect("big scene");
    let big_secs = time_steps(&mut one, steps);
    let big_rate = bp.len() as f64 * steps as f64 / big_secs;
    drop(one);

    // One after another: `alone` worlds, each its own backend (its set-up not counted).
    let mut alone_secs = 0.0;
    for _ in 0..alone {
        let mut b = CudaBackend::new(&world, &p, CudaOptions::default()).expect("world");
        alone_secs += time_steps(&mut b, steps);
    }
    let alone_rate = (alone * per) as f64 * steps as f64 / alone_secs;

    // One after another with each world's set-up counted: built and run in turn (one world
    // built first, untimed, so that its program is in the kernel cache, as after a process's
    // first world).
    let _ = time_world_run(&world, &p, 1);
    let (mut alone_setup, mut alone_whole) = (0.0, 0.0);
    for _ in 0..alone {
        let (s, w) = time_world_run(&world, &p, steps);
        alone_setup += s;
        alone_whole += w;
    }
    let alone_setup_rate = (alone * per) as f64 * steps as f64 / alone_whole;
    println!("BENCH worlds {n_worlds} x {per} particles, {steps} steps, batch set-up {setup:.1} s");
    println!(
        "BENCH batched        {:>8.1} M particle-steps/s ({:.3} ms/step)",
        batched / 1e6,
        1e3 * secs / steps as f64
    );
    println!(
        "BENCH one big scene  {:>8.1} M particle-steps/s ({} particles, {:.3} ms/step)",
        big_rate / 1e6,
        bp.len(),
        1e3 * big_secs / steps as f64
    );
    println!(
        "BENCH one by one     {:>8.1} M particle-steps/s ({alone} worlds timed, extrapolated to {n_worlds}: {:.1} s a world-run of {steps} steps x {n_worlds})",
        alone_rate / 1e6,
        alone_secs / alone as f64 * n_worlds as f64
    );
    println!(
        "BENCH one by one with set-up {:>8.1} M particle-steps/s ({alone} worlds timed: {:.2} ms set-up + {:.2} ms for {steps} steps a world, extrapolated to {n_worlds}: {:.1} s)",
        alone_setup_rate / 1e6,
        1e3 * alone_setup / alone as f64,
        1e3 * (alone_whole - alone_setup) / alone as f64,
        alone_whole / alone as f64 * n_worlds as f64
    );
    println!(
        "BENCH batched / big scene {:.1} % (target >= 60 %), batched / one by one {:.1}x (target >= 20x)",
        100.0 * batched / big_rate,
        batched / alone_rate
    );
    // The ratios: the batch's steps against the worlds' steps, then against the worlds' set-up
    // and steps (what the target's rationale counts: N runs pay N set-ups), then whole runs of
    // `steps` steps with the batch's own set-up counted too.
    let batch_whole_rate = total * steps as f64 / (setup + secs);
    println!("BENCH table (target: batched at least 20x the worlds one after another)");
    println!(
        "BENCH | counted | batched M particle-steps/s | one after another | batched / one after another |"
    );
    for (what, a, b) in [
        ("steps only (both)", batched, alone_rate),
        (
            "one after another: each world's set-up and steps; batched: steps",
            batched,
            alone_setup_rate,
        ),
        (
            "set-up and steps (both: whole runs)",
            batch_whole_rate,
            alone_setup_rate,
        ),
    ] {
        println!(
            "BENCH | {what} | {:.1} | {:.1} | {:.1}x |",
            a / 1e6,
            b / 1e6,
            a / b
        );
    }
}
