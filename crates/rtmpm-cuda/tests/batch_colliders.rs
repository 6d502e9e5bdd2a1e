//! Worlds with colliders of their own in a batch on the GPU (`rtmpm_cuda::batch::CudaBatch`:
//! per-world collider tables; static obstacles, and pushers whose motion differs, posed per
//! world each step; needs a GPU, skips with a message otherwise), against the same worlds run
//! one by one on the CUDA backend and on the CPU backend:
//! `cargo test --release -p rtmpm-cuda --test batch_colliders -- --include-ignored --nocapture
//! --test-threads 1`.
//!
//! Both tests run the same two programs (one world's kernels and the batch's, precise math,
//! specialised to the water's model): the first test of a process with a cold kernel cache
//! (`RTMPM_CACHE_DIR`, and the driver's JIT cache) compiles them with NVRTC, side by side on two
//! threads, and the driver turns their PTX into machine code; the second finds them cached.

mod common;

use common::batch::{agrees, precise};
use common::{gpu, read};
use rtmpm_cpu::CpuBackend;
use rtmpm_cuda::batch::CudaBatch;
use rtmpm_cuda::{CudaBackend, CudaOptions};
use rtmpm_physics::Particles;
use rtmpm_scene::{BatchScene, Scene, StepMode};
use rtmpm_sim::Backend;
use std::time::Instant;

/// Precise math (as the agreement tests compare), the kernels specialised to the scenes'
/// models (water only: a smaller program to compile).
fn options() -> CudaOptions {
    CudaOptions {
        specialize: true,
        ..precise()
    }
}

/// A water column (0.1 x 0.2 x 0.28 m at 2 cm cells, 8 particles a cell) in a 0.4 m box with
/// `colliders` (`[[collider]]` tables).
fn water_with(colliders: &str) -> Scene {
    let text = water_text(colliders);
    Scene::from_toml(&text, "obstacle.toml").unwrap_or_else(|e| panic!("{e}"))
}

/// The scene file of [`water_with`], at fixed steps of [`DT`].
fn water_text(colliders: &str) -> String {
    format!(
        r#"name = "obstacle"
[domain]
min = [0.0, 0.0, 0.0]
max = [0.4, 0.4, 0.4]
dx = 0.02
[time]
duration = 0.1
fps = 50
dt = 2e-4
[walls]
thickness = 3
[[material]]
name = "water"
type = "fluid"
density = 1000.0
bulk_modulus = 1e4
[[body]]
material = "water"
shape = "box"
min = [0.06, 0.06, 0.06]
max = [0.16, 0.26, 0.34]
particles_per_cell = 8
{colliders}"#
    )
}

/// A water column collapsing against an obstacle of world `w`'s own: a box 2 cm further along
/// x in each world, a ball in world 2, sticky in world 3 (slip elsewhere). The faces lie 1 mm
/// off the grid's nodes (see [`pusher_world`]).
fn world(w: usize) -> Scene {
    let x = 0.181 + 0.02 * w as f32;
    let obstacle = if w == 2 {
        "shape = \"sphere\"\ncenter = [0.241, 0.061, 0.201]\nradius = 0.06\n".to_string()
    } else {
        format!(
            "shape = \"box\"\nmin = [{x}, 0.0, 0.121]\nmax = [{}, 0.121, 0.281]\n",
            x + 0.04
        )
    };
    let rule = if w == 3 { "sticky" } else { "slip" };
    water_with(&format!("[[collider]]\n{obstacle}condition = \"{rule}\"\n"))
}

const DT: f32 = 2e-4;

/// Every world's particles after the first step and at the end of a run.
struct Ends {
    first: Vec<Particles>,
    last: Vec<Particles>,
}

/// The worlds from `p0` for `steps` steps of [`DT`] in one batch.
fn run_batch(worlds: &[Scene], p0: &[Particles], steps: usize) -> Ends {
    let mut batch = CudaBatch::new(worlds, p0, options()).expect("batch");
    assert!(
        batch.collider_bytes() > 0,
        "the worlds read tables of their own"
    );
    let mut first = Vec::new();
    for s in 0..steps {
        batch.step(DT, s as f32 * DT).expect("batch step");
        if s == 0 {
            first = batch.read_worlds().expect("read");
        }
    }
    assert!(
        batch.bad_world().expect("check").is_none(),
        "a world blew up"
    );
    let last = batch.read_worlds().expect("read");
    Ends { first, last }
}

/// Each of `runs` (one world each) for `steps` steps of [`DT`].
fn run_each<B: Backend>(mut runs: Vec<B>, steps: usize) -> Ends {
    let mut first = Vec::new();
    for s in 0..steps {
        for b in &mut runs {
            b.step(DT, s as f32 * DT).expect("step");
        }
        if s == 0 {
            first = runs.iter_mut().map(|b| read(b)).collect();
        }
    }
    for (w, b) in runs.iter_mut().enumerate() {
        assert!(b.check().expect("check").is_none(), "world {w} blew up");
    }
    let last = runs.iter_mut().map(|b| read(b)).collect();
    Ends { first, last }
}

/// The worlds `worlds` for `steps` steps of [`DT`] in one batch and one by one on the CUDA
/// backend (and on the CPU backend with `cpu`, what a batch on the CPU runs world by world),
/// each world's particles compared with its separate runs after the first step and at the end
/// ([`agrees`]); the batch's worlds at the end, and the failures. The batch runs on a thread of
/// its own beside the separate runs: with a cold kernel cache its program and one world's are
/// compiled side by side.
fn batch_and_separate_runs(
    worlds: &[Scene],
    steps: usize,
    cpu: bool,
) -> (Vec<Particles>, Vec<String>) {
    let start = Instant::now();
    let p0: Vec<Particles> = worlds
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    let (batch, single, on_cpu) = std::thread::scope(|scope| {
        let batch = scope.spawn(|| run_batch(worlds, &p0, steps));
        let single: Vec<CudaBackend> = worlds
            .iter()
            .zip(&p0)
            .map(|(s, p)| CudaBackend::new(s, p, options()).expect("world"))
            .collect();
        let single = run_each(single, steps);
        let on_cpu = cpu.then(|| {
            let runs: Vec<CpuBackend> = worlds
                .iter()
                .zip(&p0)
                .map(|(s, p)| CpuBackend::new(s, p.clone(), None).expect("cpu"))
                .collect();
            run_each(runs, steps)
        });
        (batch.join().expect("the batch's thread"), single, on_cpu)
    });
    let mut failures = Vec::new();
    for (w, world) in worlds.iter().enumerate() {
        let dx = world.dx;
        let what = format!("world {w} after {steps} steps vs its CUDA run");
        let one = (&batch.first[w], &single.first[w]);
        failures.extend(agrees(
            &what,
            Some(one),
            &batch.last[w],
            &single.last[w],
            dx,
        ));
        if let Some(c) = &on_cpu {
            let what = format!("world {w} after {steps} steps vs its CPU run");
            let one = (&c.first[w], &batch.first[w]);
            failures.extend(agrees(&what, Some(one), &c.last[w], &batch.last[w], dx));
        }
    }
    println!(
        "built, {steps} steps and compared in {:.1} s",
        start.elapsed().as_secs_f64()
    );
    (batch.last, failures)
}

/// The worlds `got` differ pairwise (`pairs`) by more than the tolerances: a world reading
/// another's colliders would be seen.
fn assert_the_worlds_differ(got: &[Particles], pairs: &[(usize, usize)], dx: f32) {
    let dx = dx as f64;
    for &(a, b) in pairs {
        let d = got[a].aggregate_difference(&got[b]);
        println!(
            "world {a} vs world {b}: |d com| {:.3} dx, KE {:.2} %, |d bbox| {:.2} dx",
            d.com / dx,
            100.0 * d.kinetic,
            d.bbox / dx
        );
        assert!(
            d.com > 0.1 * dx || d.kinetic > 0.02 || d.bbox > dx,
            "worlds {a} and {b} end alike: the check could not see a mix-up"
        );
    }
}

/// Four worlds whose obstacles differ (place, shape, boundary rule) in one batch give, world by
/// world, the particles of their separate CUDA runs after 500 steps (0.1 s: the water front
/// reaches every obstacle): the agreement test's tolerances ([`agrees`]), while the worlds
/// differ from each other by more than that (the check could see a world reading another's
/// obstacle). About 2 s on an H200 in release with the kernels cached, plus the compilation
/// of the two programs with a cold cache.
#[test]
#[ignore = "needs a CUDA GPU"]
fn worlds_with_their_own_obstacles_agree_with_their_separate_runs() {
    let worlds: Vec<Scene> = (0..4).map(world).collect();
    if !gpu() {
        return;
    }
    let (got, failures) = batch_and_separate_runs(&worlds, 500, false);
    assert_the_worlds_differ(&got, &[(0, 1), (0, 2), (1, 3)], worlds[0].dx);
    assert!(failures.is_empty(), "{failures:#?}");
}

/// World `w` with two colliders: a static block on the far side at its own height (collider 0)
/// and a 4 cm paddle across the tank on the water's near side (collider 1, its face 1 mm short
/// of the column's x = 0.06 m side) that pushes the water along +x each world its own way:
/// world 0 at 0.25 m/s, world 1 at 0.6 m/s, world 2 at 0.4 m/s turning about y at 2 rad/s,
/// world 3 keyframed (still for 20 ms, 1 m/s to 60 ms, then back at 0.5 m/s). No face of a
/// collider lies on the grid's nodes at the start (x and y 1 mm off them): a node exactly on a
/// face is inside or outside by the last bit of the arithmetic, which the CPU comparison
/// would see (the first step's velocities of the CPU's f32 and f64 builds differ by the
/// paddle's speed there).
fn pusher_world(w: usize) -> Scene {
    let motion = match w {
        0 => "velocity = [0.25, 0.0, 0.0]\n".to_string(),
        1 => "velocity = [0.6, 0.0, 0.0]\n".to_string(),
        2 => "velocity = [0.4, 0.0, 0.0]\nangular_velocity = [0.0, 2.0, 0.0]\n".to_string(),
        _ => "keyframes = [{ t = 0.0, position = [0.029, 0.171, 0.2] }, \
              { t = 0.02, position = [0.029, 0.171, 0.2] }, \
              { t = 0.06, position = [0.069, 0.171, 0.2] }, \
              { t = 0.08, position = [0.059, 0.171, 0.2] }]\n"
            .to_string(),
    };
    let top = 0.101 + 0.02 * w as f32;
    water_with(&format!(
        "[[collider]]\nshape = \"box\"\nmin = [0.261, 0.0, 0.101]\nmax = [0.301, {top}, 0.301]\n\
         condition = \"slip\"\n\
         [[collider]]\nshape = \"box\"\nmin = [0.009, 0.041, 0.041]\nmax = [0.049, 0.301, 0.359]\n\
         condition = \"slip\"\n{motion}"
    ))
}

/// Every node of `scene`'s grid that the first step's transfer reaches (the 3 x 3 x 3
/// stencils of the particles' bounding box; positions as the CPU backend computes them, origin
/// plus index times dx) at least `margin` from every collider's surface at the times `ts`.
fn nodes_off_the_faces(scene: &Scene, ts: &[f32], margin: f32) -> Result<(), String> {
    let p = scene.sample_particles().map_err(|e| e.to_string())?;
    let origin = scene.domain_min - glam::Vec3::splat(4.0 * scene.dx);
    let base = |x: glam::Vec3| ((x - origin) / scene.dx - 0.5).floor().as_ivec3();
    let lo = p.x.iter().fold(glam::Vec3::INFINITY, |a, &x| a.min(x));
    let hi = p.x.iter().fold(glam::Vec3::NEG_INFINITY, |a, &x| a.max(x));
    let (lo, hi) = (base(lo), base(hi) + glam::IVec3::splat(2));
    for (k, c) in scene.colliders.iter().enumerate() {
        for &t in ts {
            for i in lo.x..=hi.x {
                for j in lo.y..=hi.y {
                    for l in lo.z..=hi.z {
                        let x = origin + glam::IVec3::new(i, j, l).as_vec3() * scene.dx;
                        let d = c.distance(x, t);
                        if d.abs() < margin {
                            return Err(format!(
                                "collider {k} at t = {t}: node {x} is {d:e} m from its surface"
                            ));
                        }
                    }
                }
            }
        }
    }
    Ok(())
}

/// The scenes of the tests above and below keep every node that the first step's transfer
/// reaches at least 0.5 mm off every collider face during that step, which they compare
/// particle by particle with the CPU backend. A node exactly on a face is inside (distance <= 0) or not by the last bit of its
/// position: with the paddle's face on the x = 0.06 m node plane, the CPU backend places the
/// node at -0.08 + 7 x 0.02 rounded twice (0.060000002, distance +3.7e-9: outside) and the
/// CUDA kernel, whose `origin + index * dx` NVRTC contracts into one fused multiply-add, at
/// 0.059999999 (distance 0: inside), so the plane took the paddle's velocity on the GPU only and
/// the first step differed by 0.75 x the paddle's speed (the quadratic B-spline's central weight
/// of a particle on that plane). Runs without a GPU.
#[test]
fn the_test_scenes_keep_every_node_off_the_collider_faces() {
    for w in 0..4 {
        for (what, scene) in [("obstacle", world(w)), ("pusher", pusher_world(w))] {
            nodes_off_the_faces(&scene, &[0.0, DT], 5e-4)
                .unwrap_or_else(|e| panic!("{what} world {w}: {e}"));
        }
    }
}

/// Four worlds whose paddles move differently (speed, spin, keyframes: the sweep of a pusher's
/// motion), beside a static block of each world's own, in one batch: each world's poses go up
/// every step, and each world gives the particles of its separate CUDA run and of its CPU run
/// (the CPU backend's poses are the reference) after the first step and after 400 steps (80 ms:
/// the paddles are 2 to 5 cm into the water), within the agreement test's tolerances, while the
/// worlds differ from each other by more than that. About 3 s on an H200 in release with the
/// kernels cached (those of the test above; the CPU runs take most of it).
#[test]
#[ignore = "needs a CUDA GPU"]
fn worlds_whose_pushers_move_differently_agree_with_their_cuda_and_cpu_runs() {
    let worlds: Vec<Scene> = (0..4).map(pusher_world).collect();
    assert!(
        rtmpm_cuda::batch::unsupported(&worlds, &options()).is_none(),
        "the GPU batch runs these worlds"
    );
    if !gpu() {
        return;
    }
    let (got, failures) = batch_and_separate_runs(&worlds, 400, true);
    assert_the_worlds_differ(&got, &[(0, 1), (1, 2), (0, 3), (2, 3)], worlds[0].dx);
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The driver's shared clock counts every world's colliders: two worlds whose paddle is swept
/// over its speed (`[batch.sweep]` of `collider[1].velocity`: 0.25 and 2.5 m/s) at CFL steps,
/// one frame (20 ms) through the lockstep driver (what `rtmpm run --backend cuda` and Python's
/// GPU batch drive). Every step is at most the CFL step of world 1's paddle (`cfl dx` over its
/// speed plus the sound speed; world 0's alone would allow 1.7 times longer ones), the worlds
/// stay healthy and differ. Under a second on an H200 in release with the kernels of the tests above
/// cached.
#[test]
#[ignore = "needs a CUDA GPU"]
fn the_shared_time_step_follows_the_fastest_worlds_paddle() {
    use rtmpm_driver::batch::BatchOptions;
    use rtmpm_driver::batch::lockstep::LockstepRun;
    let paddle = "[[collider]]\nshape = \"box\"\nmin = [0.26, 0.0, 0.1]\nmax = [0.3, 0.1, 0.3]\n\
                  [[collider]]\nshape = \"box\"\nmin = [0.0, 0.04, 0.04]\n\
                  max = [0.06, 0.3, 0.36]\nvelocity = [0.25, 0.0, 0.0]\n\
                  [batch]\ncount = 2\n[batch.sweep]\n\
                  \"collider[1].velocity\" = [[0.25, 0.0, 0.0], [2.5, 0.0, 0.0]]\n";
    // CFL steps, not capped by max_dt below the paddles' bounds.
    let text = water_text(paddle).replace("dt = 2e-4\n", "max_dt = 0.01\n");
    let b = BatchScene::from_toml(&text, "paddles.toml").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(b.worlds[1].colliders[1].velocity.x, 2.5);
    let StepMode::Cfl { cfl, .. } = b.base.time.step else {
        panic!("CFL steps expected: {:?}", b.base.time.step);
    };
    let m = &b.base.materials[0];
    let sound = m.model.sound_speed(m.density);
    let bound = cfl * b.base.dx / (2.5 + sound);
    let slow = cfl * b.base.dx / (0.25 + sound);
    assert!(bound < slow && slow < 0.01, "{bound} {slow}");
    if !gpu() {
        return;
    }
    let p0: Vec<Particles> = b
        .worlds
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    let batch = CudaBatch::new(&b.worlds, &p0, options()).expect("batch");
    let scene = batch.scene().clone();
    let options = BatchOptions {
        frames: Some(1),
        ..BatchOptions::default()
    };
    let mut r =
        LockstepRun::new(&b, &text, scene, Box::new(batch), &options).expect("lockstep run");
    let mut longest = 0.0f32;
    while r.sim.frame < 1 {
        r.advance_steps(1).expect("a step");
        longest = longest.max(r.sim.last_dt);
    }
    println!(
        "{} steps in the frame, the longest {longest:.3e} s; the fast paddle's CFL step \
         {bound:.3e} s, the slow one's {slow:.3e} s",
        r.sim.step
    );
    assert!(
        longest <= bound * (1.0 + 1e-5),
        "a step of {longest:.3e} s: longer than the fast paddle's CFL step {bound:.3e} s"
    );
    assert!(r.sim.step as f32 >= 0.02 / bound - 1e-3);
    r.sync().expect("read the worlds");
    assert_eq!(r.running(), 2, "both worlds healthy");
    assert_the_worlds_differ(
        &[
            r.worlds[0].particles().clone(),
            r.worlds[1].particles().clone(),
        ],
        &[(0, 1)],
        b.base.dx,
    );
}
