//! Rigid bodies coupled on the GPU (cargo feature `rigid`; needs a GPU, skips with a message
//! otherwise): the scenes and measurements of the `archimedes` and `rigid_momentum` validation
//! cases (`validation/*.toml`, `rtmpm_driver::checks`, as the CPU's `rtmpm-cpu/tests/rigid.rs`)
//! on CUDA (and the Archimedes box as a mesh body), and the load on a kinematic tool pushed into
//! sand (`tests/loads/mod.rs`), against the CPU backend in the same run:
//! `cargo test --release -p rtmpm-cuda --features rigid --test rigid -- --include-ignored --nocapture`.
#![cfg(feature = "rigid")]

use rtmpm_cpu::CpuBackend;
use rtmpm_cuda::{CudaBackend, CudaOptions, probe};
use rtmpm_driver::{Simulation, checks};
use rtmpm_scene::Scene;

mod loads;

/// A 0.12 x 0.1 x 0.12 m box of density 500 dropped onto 0.2 m of water (dx = 0.02 m).
const ARCHIMEDES: &str = include_str!("../../../validation/archimedes.toml");
/// Zero gravity: a jelly ball thrown at 2 m/s at a free box of twice its mass.
const MOMENTUM: &str = include_str!("../../../validation/rigid_momentum.toml");

fn gpu() -> bool {
    match probe() {
        Ok(_) => true,
        Err(e) => {
            eprintln!("no usable GPU, skipping: {e}");
            false
        }
    }
}

/// Archimedes on the GPU: the box of density 500 floats with the submerged fraction of its
/// height within 5 % of 0.5, and its floating height within 2 mm (a tenth of a
/// cell) of the CPU backend's on the same scene.
#[test]
#[ignore = "needs a GPU"]
fn a_box_of_half_the_density_of_water_floats_half_submerged_on_the_gpu() {
    if !gpu() {
        return;
    }
    let scene = Scene::from_toml(ARCHIMEDES, "archimedes").unwrap_or_else(|e| panic!("{e}"));
    assert!(
        (scene.rigid_bodies[0].mass - 0.72).abs() < 1e-4,
        "a box of density 500"
    );
    let p0 = scene.sample_particles().expect("particles");
    let cpu = CpuBackend::new(&scene, p0.clone(), None).expect("cpu");
    let cuda = CudaBackend::new(&scene, &p0, CudaOptions::default()).expect("cuda");
    let float = |sim: &mut Simulation| checks::float(sim, |_, _| {}).expect("floats");
    let a = float(&mut Simulation::new(scene.clone(), Box::new(cpu)));
    let b = float(&mut Simulation::new(scene.clone(), Box::new(cuda)));
    println!("cpu: {a:?}\ncuda: {b:?}");
    assert!((b.fraction / 0.5 - 1.0).abs() < 0.05, "{b:?}");
    assert!(
        (b.centre - a.centre).abs() < 0.002,
        "cuda {b:?} vs cpu {a:?}"
    );
}

/// Zero gravity: a jelly ball thrown at a free box on the GPU. Material plus box momentum is
/// conserved within 1 % and the box moves at the elastic estimate within 10 %, with
/// G2P2G (default) and with the separate kernels, the graph on and off, the bodies moved while
/// the next step runs (default) and after every step (`rigid_overlap=off`), f32 and f64.
#[test]
#[ignore = "needs a GPU"]
fn momentum_of_material_plus_body_is_conserved_on_the_gpu() {
    if !gpu() {
        return;
    }
    let scene = Scene::from_toml(MOMENTUM, "rigid_momentum").unwrap_or_else(|e| panic!("{e}"));
    let p0 = scene.sample_particles().expect("particles");
    for options in [
        "",
        "rigid_overlap=off",
        "g2p2g=off",
        "g2p2g=off,graph=off",
        "f64=on",
    ] {
        let o: CudaOptions = options.parse().expect("options");
        let cuda = CudaBackend::new(&scene, &p0, o).expect("cuda");
        let mut sim = Simulation::new(scene.clone(), Box::new(cuda));
        let c = checks::collide(&mut sim).expect("collision");
        let ratio = c.body_speed / c.elastic;
        println!(
            "[{options}] momentum error {:.2e}, box speed {:.4} m/s ({ratio:.3} of the elastic \
             estimate {:.4})",
            c.momentum_error(),
            c.body_speed,
            c.elastic
        );
        assert!((ratio - 1.0).abs() < 0.1, "[{options}] box speed {ratio}");
        assert!(c.momentum_error() < 0.01, "[{options}] {c:?}");
    }
}

/// A script that reads the bodies and puts them back after every step (what Python's
/// `Simulation.set_rigid_body` does to the body it moves) keeps the momentum of material plus
/// body, in zero gravity through the jelly ball's collision with the box: with the bodies moved
/// a step late (`rigid_overlap`, the default) `flush_rigid` first gives them the impulses of the
/// step queued last, which `set_rigid_poses` would otherwise drop. The run without the flush is
/// printed for contrast, and must lose momentum, or this test could not see a missing flush.
#[test]
#[ignore = "needs a GPU"]
fn bodies_read_and_put_back_after_every_step_keep_the_momentum_on_the_gpu() {
    if !gpu() {
        return;
    }
    let scene = Scene::from_toml(MOMENTUM, "rigid_momentum").unwrap_or_else(|e| panic!("{e}"));
    let p0 = scene.sample_particles().expect("particles");
    let start = checks::momentum(&p0);
    let mass = scene.rigid_bodies[0].mass as f64;
    let mut errors = Vec::new();
    for flush in [true, false] {
        let cuda = CudaBackend::new(&scene, &p0, CudaOptions::default()).expect("cuda");
        let mut sim = Simulation::new(scene.clone(), Box::new(cuda));
        for _ in 0..scene.time.frames() {
            while !sim.advance(1).expect("step") {
                if flush {
                    sim.backend.flush_rigid().expect("flush");
                }
                let poses = sim.backend.rigid_poses();
                sim.backend.set_rigid_poses(&poses).expect("set");
            }
        }
        let mut p = rtmpm_physics::Particles::default();
        sim.backend.read_particles(&mut p).expect("read");
        let body = sim.backend.rigid_poses()[0].velocity.as_dvec3() * mass;
        let error = (checks::momentum(&p) + body - start).length() / start.length();
        println!("flush {flush}: momentum error {error:.2e}");
        errors.push(error);
    }
    assert!(errors[0] < 0.01, "with the flush: {errors:?}");
    assert!(errors[1] > 0.01, "without the flush: {errors:?}");
}

/// The Archimedes box as a mesh body on the GPU: the cube OBJ (written here) scaled and
/// translated onto the box of `validation/archimedes.toml`, density 500, convex. Its floating
/// height on CUDA is within 2 mm (a tenth of a cell) of the CPU backend's on the same scene,
/// and its submerged fraction within 5 % of 0.5: the GPU evaluates the body's distance grid
/// with the mesh colliders' `mesh_distance`, the CPU with `MeshSdf::distance`.
#[test]
#[ignore = "needs a GPU"]
fn a_cube_mesh_body_floats_on_the_gpu_as_on_the_cpu() {
    if !gpu() {
        return;
    }
    let dir = std::env::temp_dir().join(format!("rtmpm-gpu-mesh-body-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let obj = dir.join("cube.obj");
    std::fs::write(
        &obj,
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
         f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n",
    )
    .expect("write the cube");
    let block = "shape = \"box\"\nmin = [0.24, 0.27, 0.24]\nmax = [0.36, 0.37, 0.36]";
    assert!(ARCHIMEDES.contains(block));
    let text = ARCHIMEDES.replacen(
        block,
        &format!(
            "shape = \"mesh\"\nfile = \"{}\"\nscale = [0.12, 0.1, 0.12]\n\
             translate = [0.24, 0.27, 0.24]\nconvex = true",
            obj.display()
        ),
        1,
    );
    let scene = Scene::from_toml(&text, "archimedes_mesh").unwrap_or_else(|e| panic!("{e}"));
    assert!((scene.rigid_bodies[0].mass - 0.72).abs() < 1e-4);
    let p0 = scene.sample_particles().expect("particles");
    let cpu = CpuBackend::new(&scene, p0.clone(), None).expect("cpu");
    let cuda = CudaBackend::new(&scene, &p0, CudaOptions::default()).expect("cuda");
    let float = |sim: &mut Simulation| checks::float(sim, |_, _| {}).expect("floats");
    let a = float(&mut Simulation::new(scene.clone(), Box::new(cpu)));
    let b = float(&mut Simulation::new(scene.clone(), Box::new(cuda)));
    println!("mesh body: cpu: {a:?}\ncuda: {b:?}");
    std::fs::remove_dir_all(&dir).ok();
    assert!((b.fraction / 0.5 - 1.0).abs() < 0.05, "{b:?}");
    assert!(
        (b.centre - a.centre).abs() < 0.002,
        "cuda {b:?} vs cpu {a:?}"
    );
}

/// A kinematic tool (a 6 cm box) pressed into sand at 0.25 m/s and dragged sideways at 0.1 m/s
/// on one GPU reports the load the CPU backend reports on the same scene: the mean force and
/// torque over the last 200 of 800 steps (`tests/loads/mod.rs`) within the tolerance of the GPU
/// batch's loads against the CPU's (`tests/batch_rigid.rs`: the force within 5 % of its size,
/// the torque within 5 % of its size plus 1e-4 N m), with the bodies moved a step late (the
/// default; the load read after `flush_rigid`, as Python reads it) and after every step with
/// precise math; zero before the first step. About 5 s on an H200 in release.
#[test]
#[ignore = "needs a GPU"]
fn a_kinematic_tool_pushed_into_sand_feels_the_cpus_load_on_the_gpu() {
    if !gpu() {
        return;
    }
    let scene = loads::sand_and_tool(0.25);
    let p0 = scene.sample_particles().expect("particles");
    let mut cpu = CpuBackend::new(&scene, p0.clone(), None).expect("cpu");
    let want = loads::push(&mut cpu);
    loads::assert_the_sand_pushes_back(&want);
    let mut failures = Vec::new();
    for options in ["", "rigid_overlap=off,fast_math=off"] {
        let o: CudaOptions = options.parse().expect("options");
        let mut cuda = CudaBackend::new(&scene, &p0, o).expect("cuda");
        let got = loads::push(&mut cuda);
        failures.extend(loads::differ(&format!("cuda [{options}]"), &got, &want));
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
