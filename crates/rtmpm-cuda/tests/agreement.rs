//! CPU reference vs CUDA backend on every example scene (needs a GPU; skips with a message
//! otherwise): `cargo test -p rtmpm-cuda --test agreement -- --include-ignored --nocapture`.

use rtmpm_cpu::CpuBackend;
use rtmpm_cuda::{CudaBackend, CudaOptions, probe};
use rtmpm_driver::Simulation;
use rtmpm_physics::Particles;
use rtmpm_physics::transfer::{SolverSettings, Transfer, Update};
use rtmpm_scene::Scene;
use rtmpm_sim::Backend;
use std::path::Path;

fn scenes() -> Vec<std::path::PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .expect("scenes/")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        // A batch of worlds ([batch]) is many scenes, not one: its worlds against separate
        // CUDA runs are the tests/batch_*.rs.
        .filter(|p| !rtmpm_scene::BatchScene::from_file(p).is_ok_and(|b| b.batch.is_some()))
        .collect();
    v.sort();
    v
}

fn read(b: &mut dyn Backend) -> Particles {
    let mut p = Particles::default();
    b.read_particles(&mut p).expect("read particles");
    p
}

/// After one step every particle agrees within float tolerance; after `steps` steps the aggregate
/// quantities agree within the stated tolerances. Returns the failures. The CUDA options are
/// [`extra_options`].
fn compare(name: &str, scene: &Scene, steps: usize) -> Vec<String> {
    compare_with(name, scene, steps, &extra_options())
}

/// CUDA options (`--cuda-options` syntax) for the tests of every example scene, f32 and f64:
/// `RTMPM_AGREEMENT_OPTIONS`, e.g. `g2p2g=off` for the separate G2P and P2G kernels; none by
/// default.
fn extra_options() -> String {
    let o = std::env::var("RTMPM_AGREEMENT_OPTIONS").unwrap_or_default();
    if !o.trim().is_empty() {
        println!("CUDA options of the comparison: {o}");
    }
    o
}

/// The CUDA options of a comparison: precise math (for the per-particle comparison) and `extra`
/// (`--cuda-options` syntax).
fn options(extra: &str) -> CudaOptions {
    format!("fast_math=off,{extra}")
        .parse()
        .unwrap_or_else(|e| panic!("CUDA options `{extra}`: {e}"))
}

/// [`compare`] with the CUDA options `extra` (`--cuda-options` syntax) beside precise math.
fn compare_with(name: &str, scene: &Scene, steps: usize, extra: &str) -> Vec<String> {
    let mut failures = Vec::new();
    let p0 = scene.sample_particles().expect("particles");
    let mut cpu = CpuBackend::new(scene, p0.clone(), None).expect("cpu");
    let opts = options(extra);
    let fused_ck = opts.ck_p2g == rtmpm_cuda::CkP2g::Fused;
    let mut gpu = CudaBackend::new(scene, &p0, opts).expect("cuda backend");
    if fused_ck {
        assert!(gpu.g2p2g(), "{name}: ck_p2g=fused without G2P2G");
    }
    // One dt for both (the CFL step of the initial state), so that they see the same steps.
    let mut sim = Simulation::new(
        scene.clone(),
        Box::new(CpuBackend::new(scene, p0.clone(), Some(1)).expect("cpu")),
    );
    let dt = sim.next_dt().expect("dt");
    let dx = scene.dx;
    cpu.step(dt, 0.0).expect("cpu step");
    gpu.step(dt, 0.0).expect("gpu step");
    let (a, b) = (read(&mut cpu), read(&mut gpu));
    let vscale = a.v.iter().map(|v| v.length()).fold(1e-3f32, f32::max);
    let mut worst_x = 0.0f32;
    let mut worst_v = 0.0f32;
    for i in 0..a.len() {
        worst_x = worst_x.max((a.x[i] - b.x[i]).length());
        worst_v = worst_v.max((a.v[i] - b.v[i]).length());
    }
    println!(
        "{name}: 1 step, dt {dt:.3e}: max |dx| {worst_x:.3e} m, max |dv| {worst_v:.3e} m/s (v scale {vscale:.3e})"
    );
    if worst_x > 1e-5 * dx.max(1e-3) + 1e-6 || worst_v > 1e-3 * vscale {
        failures.push(format!(
            "{name}: first step differs: |dx| {worst_x:.3e}, |dv| {worst_v:.3e}"
        ));
    }
    for s in 1..steps {
        cpu.step(dt, s as f32 * dt).expect("cpu step");
        gpu.step(dt, s as f32 * dt).expect("gpu step");
    }
    assert!(gpu.check().expect("check").is_none(), "{name}: GPU blow-up");
    let (a, b) = (read(&mut cpu), read(&mut gpu));
    let d = a.aggregate_difference(&b);
    let dx = dx as f64;
    println!(
        "{name}: {steps} steps: |d com| {:.3e} m ({:.3} dx), KE cpu {:.4e} gpu {:.4e} ({:.2} %), |d bbox| {:.3e} m ({:.2} dx)",
        d.com,
        d.com / dx,
        a.kinetic_energy(),
        b.kinetic_energy(),
        100.0 * d.kinetic,
        d.bbox,
        d.bbox / dx
    );
    // Tolerances: centre of mass within 0.1 cell, kinetic energy within 2 %, bounding box
    // within 1 cell (splashes separate single particles chaotically).
    if d.com > 0.1 * dx || d.kinetic > 0.02 || d.bbox > dx {
        failures.push(format!("{name}: aggregates differ after {steps} steps"));
    }
    failures
}

fn steps() -> usize {
    std::env::var("RTMPM_AGREEMENT_STEPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(300)
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn cuda_agrees_with_cpu_on_every_example_scene() {
    if let Err(e) = probe() {
        println!("skipped: no usable CUDA GPU ({e})");
        return;
    }
    let mut failures = Vec::new();
    for path in scenes() {
        let scene = Scene::from_file(&path).expect("scene");
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        failures.extend(compare(&name, &scene, steps()));
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The classic MPM transfers (`[solver]`): GIMP + USL (PIC), GIMP + MUSL + FLIP and linear-hat
/// MPM (MUSL, PIC/FLIP blend) on an elastic and a fluid example scene.
#[test]
#[ignore = "needs a CUDA GPU"]
fn cuda_agrees_with_cpu_with_the_classic_transfers() {
    if let Err(e) = probe() {
        println!("skipped: no usable CUDA GPU ({e})");
        return;
    }
    let solvers = [
        (Transfer::Gimp, Update::Usl, 0.0),
        (Transfer::Gimp, Update::Musl, 1.0),
        (Transfer::MpmLinear, Update::Musl, 0.9),
    ];
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let mut failures = Vec::new();
    for file in ["elastic_cubes.toml", "dam_break.toml"] {
        for (transfer, update, flip) in solvers {
            let mut scene = Scene::from_file(&dir.join(file)).expect("scene");
            scene.solver = SolverSettings {
                transfer,
                update,
                flip,
            };
            let name = format!("{file} ({})", scene.solver.describe());
            failures.extend(compare(&name, &scene, steps()));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Double precision: the CUDA backend with `precision = "f64"` against the f64 CPU backend on
/// every example scene. After one step every particle agrees to f64 rounding (1e-9 of a cell;
/// the atomics sum in another order), except in scenes with colliders, whose geometry the CPU
/// evaluates in f32 (then the f32 tolerance of the test above); after `steps` steps the same
/// aggregate tolerances as in f32.
#[test]
#[ignore = "needs a CUDA GPU"]
fn cuda_f64_agrees_with_cpu_f64_on_every_example_scene() {
    if let Err(e) = probe() {
        println!("skipped: no usable CUDA GPU ({e})");
        return;
    }
    let mut failures = Vec::new();
    for path in scenes() {
        let scene = Scene::from_file(&path).expect("scene");
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        failures.extend(compare_f64(&name, scene, steps()));
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// [`cuda_f64_agrees_with_cpu_f64_on_every_example_scene`] for one scene (run in f64).
fn compare_f64(name: &str, scene: Scene, steps: usize) -> Vec<String> {
    compare_f64_with(name, scene, steps, &extra_options())
}

/// [`compare_f64`] with the CUDA options `extra` (`--cuda-options` syntax) beside precise math.
fn compare_f64_with(name: &str, mut scene: Scene, steps: usize, extra: &str) -> Vec<String> {
    let mut failures = Vec::new();
    scene.precision = rtmpm_scene::Precision::F64;
    let p0 = scene.sample_particles().expect("particles");
    let mut cpu = rtmpm_cpu_f64::CpuBackend::new(&scene, p0.clone(), None).expect("cpu");
    let opts = options(extra);
    let fused_ck = opts.ck_p2g == rtmpm_cuda::CkP2g::Fused;
    let mut gpu = CudaBackend::new(&scene, &p0, opts).expect("cuda backend");
    if fused_ck {
        assert!(gpu.g2p2g(), "{name}: ck_p2g=fused without G2P2G");
    }
    assert!(gpu.name().contains("f64"), "{}", gpu.name());
    let mut sim = Simulation::new(
        scene.clone(),
        Box::new(CpuBackend::new(&scene, p0.clone(), Some(1)).expect("cpu")),
    );
    let dt = sim.next_dt().expect("dt");
    let dx = scene.dx;
    cpu.step(dt, 0.0).expect("cpu step");
    gpu.step(dt, 0.0).expect("gpu step");
    // Compare the f64 states themselves, not through the f32 interface.
    let a = &cpu.particles;
    let b = gpu.read_x_v_f64().expect("read");
    let mut worst_x = 0.0f64;
    let mut worst_v = 0.0f64;
    for (i, &id) in cpu.ids.iter().enumerate() {
        let [bx, bv] = b[id as usize].map(glam::DVec3::from_array);
        worst_x = worst_x.max((a.x[i] - bx).length());
        worst_v = worst_v.max((a.v[i] - bv).length());
    }
    let vscale = a.v.iter().map(|v| v.length()).fold(1e-3, f64::max);
    println!(
        "{name} (f64): 1 step, dt {dt:.3e}: max |dx| {worst_x:.3e} m, max |dv| {worst_v:.3e} m/s (v scale {vscale:.3e})"
    );
    let (tol_x, tol_v) = if scene.colliders.is_empty() {
        (1e-9 * dx as f64, 1e-9 * vscale)
    } else {
        (1e-5 * (dx as f64).max(1e-3) + 1e-6, 1e-3 * vscale)
    };
    if worst_x > tol_x || worst_v > tol_v {
        failures.push(format!(
            "{name}: first step differs: |dx| {worst_x:.3e}, |dv| {worst_v:.3e}"
        ));
    }
    for s in 1..steps {
        cpu.step(dt, s as f32 * dt).expect("cpu step");
        gpu.step(dt, s as f32 * dt).expect("gpu step");
    }
    assert!(gpu.check().expect("check").is_none(), "{name}: GPU blow-up");
    let (a, b) = (read(&mut cpu), read(&mut gpu));
    let d = a.aggregate_difference(&b);
    println!(
        "{name} (f64): {steps} steps: |d com| {:.3e} m ({:.3} dx), KE cpu {:.4e} gpu {:.4e} ({:.2} %)",
        d.com,
        d.com / dx as f64,
        a.kinetic_energy(),
        b.kinetic_energy(),
        100.0 * d.kinetic
    );
    if d.com > 0.1 * dx as f64 || d.kinetic > 0.02 {
        failures.push(format!("{name}: aggregates differ after {steps} steps"));
    }
    failures
}

/// CK-MPM (`[solver] transfer = "ck-mpm"`: the compact kernel on two staggered grids, Liu, Wang &
/// Li 2025) on example scenes without rigid bodies: an elastic one, a fluid one, and two with
/// colliders (a static rough plane under snow, a keyframed paddle in a Herschel-Bulkley fluid),
/// with the tolerances of the tests above: in f32 (the CPU reference in f32) and in f64 (against
/// the f64 CPU backend, to f64 rounding after one step where there is no collider). Every CK-MPM
/// kernel variant of the CUDA backend ([`ck_variants`]) is run.
#[test]
#[ignore = "needs a CUDA GPU"]
fn cuda_agrees_with_cpu_with_ck_mpm() {
    if let Err(e) = probe() {
        println!("skipped: no usable CUDA GPU ({e})");
        return;
    }
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let mut failures = Vec::new();
    for extra in ck_variants() {
        for file in [
            "elastic_cubes.toml",
            "dam_break.toml",
            "snowball_small.toml",
            "paddle.toml",
        ] {
            let mut scene = Scene::from_file(&dir.join(file)).expect("scene");
            assert!(scene.rigid_bodies.is_empty(), "{file}");
            scene.solver = SolverSettings {
                transfer: Transfer::CkMpm,
                update: Update::Usl,
                flip: 0.0,
            };
            let name = format!("{file} ({}) [{extra}]", scene.solver.describe());
            failures.extend(compare_with(&name, &scene, steps(), &extra));
            failures.extend(compare_f64_with(&name, scene, steps(), &extra));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The CUDA options of the CK-MPM kernel variants the agreement test runs: each P2G kernel
/// (`ck_p2g=direct`, direct atomics, `ck_p2g=warp`, the warp reduction, and `ck_p2g=fused`, the
/// G2P2G of CK-MPM and the default, whose backend must then run G2P2G). `RTMPM_CK_AGREEMENT` (option strings
/// separated by `;`) runs those instead, e.g. the GPU suite's `ck_speed` with the new kernels
/// only.
fn ck_variants() -> Vec<String> {
    match std::env::var("RTMPM_CK_AGREEMENT") {
        Ok(v) if !v.trim().is_empty() => v.split(';').map(|s| s.trim().to_string()).collect(),
        _ => vec![
            "ck_p2g=direct".into(),
            "ck_p2g=warp".into(),
            "ck_p2g=fused".into(),
        ],
    }
}

/// The rigid-body example scenes (`scenes/rigid/`, cargo feature `rigid`): the CPU and the CUDA
/// backend each run the scene's first 0.5 s (the drop and the impact, each with its own CFL
/// steps); every frame each body's centre agrees within a quarter cell, and at the end the
/// material's centre of mass within 0.1 cell (the backends agree on every rigid-body example
/// scene). The kinetic energies are printed, not compared: a body's impact splashes.
#[cfg(feature = "rigid")]
#[test]
#[ignore = "needs a CUDA GPU"]
fn cuda_agrees_with_cpu_on_the_rigid_body_scenes() {
    if let Err(e) = probe() {
        println!("skipped: no usable CUDA GPU ({e})");
        return;
    }
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/rigid");
    let mut paths: Vec<_> = std::fs::read_dir(dir)
        .expect("scenes/rigid")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    paths.sort();
    assert!(paths.len() >= 2, "the rigid example scenes: {paths:?}");
    let mut failures = Vec::new();
    for path in paths {
        let scene = Scene::from_file(&path).expect("scene");
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let p0 = scene.sample_particles().expect("particles");
        let cpu = CpuBackend::new(&scene, p0.clone(), None).expect("cpu");
        let gpu = CudaBackend::new(&scene, &p0, CudaOptions::default()).expect("cuda backend");
        let mut a = Simulation::new(scene.clone(), Box::new(cpu));
        let mut b = Simulation::new(scene.clone(), Box::new(gpu));
        let frames = (0.5 * scene.time.fps as f64).ceil() as usize;
        let dx = scene.dx as f64;
        let mut worst = 0.0f64;
        for f in 0..frames {
            a.advance_frame().expect("cpu frame");
            b.advance_frame().expect("gpu frame");
            let (ba, bb) = (a.backend.rigid_bodies(), b.backend.rigid_bodies());
            assert_eq!(ba.len(), bb.len(), "{name}: bodies");
            for (i, (x, y)) in ba.iter().zip(&bb).enumerate() {
                let d = (x.center - y.center).length() as f64;
                if d > worst {
                    worst = d;
                }
                if d > 0.25 * dx {
                    failures.push(format!(
                        "{name}: frame {f}: body {i} at {:?} (cpu) vs {:?} (cuda)",
                        x.center, y.center
                    ));
                }
            }
        }
        let (pa, pb) = (read(a.backend.as_mut()), read(b.backend.as_mut()));
        let d = pa.aggregate_difference(&pb);
        println!(
            "{name}: {frames} frames: bodies within {worst:.3e} m ({:.3} dx), |d com| {:.3e} m ({:.3} dx), KE cpu {:.4e} gpu {:.4e}",
            worst / dx,
            d.com,
            d.com / dx,
            pa.kinetic_energy(),
            pb.kinetic_energy()
        );
        if d.com > 0.1 * dx {
            failures.push(format!("{name}: material centre of mass differs"));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
