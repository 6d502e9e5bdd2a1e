//! What several GPUs refuse or report as one GPU does: options that cannot work and more GPUs
//! than present are clear errors, and a bad particle on any GPU is reported as on one (needs 1
//! or 2 CUDA GPUs, or `RTMPM_MULTI_GPU_DEVICES=0,0` for two ranks on one GPU as in
//! `tests/multi_gpu_agreement.rs`; skips with a message otherwise):
//! `cargo test -p rtmpm-cuda --test multi_gpu_errors -- --include-ignored --nocapture`.

mod common;

use common::multi::{MODES, mode_usable, options, ranks, usable};
use rtmpm_cuda::{CudaBackend, CudaOptions, MultiGpuBackend, device_count};
use rtmpm_driver::Simulation;
use rtmpm_scene::Scene;
use rtmpm_sim::Backend;
use std::path::Path;

/// barrier= with transport=nccl, and an unknown transport: clear errors, no panic.
#[test]
#[ignore = "needs 2 CUDA GPUs"]
fn barrier_with_nccl_is_a_clear_error() {
    if !usable(2) {
        return;
    }
    let scene = Scene::from_file(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/dam_break.toml"),
    )
    .unwrap();
    let p = scene.sample_particles().unwrap();
    let o = options(2, "transport=nccl,barrier=spin");
    let e = MultiGpuBackend::new(&scene, &p, 2, o)
        .err()
        .expect("an error")
        .to_string();
    println!("{e}");
    assert!(e.contains("barrier= applies to transport=p2p"), "{e}");
    assert!("transport=shm".parse::<CudaOptions>().is_err());
}

/// Too many GPUs asked: a clear error, no panic.
#[test]
#[ignore = "needs a CUDA GPU"]
fn asking_for_more_gpus_than_present_is_a_clear_error() {
    let found = device_count();
    if found == 0 {
        println!("skipped: no CUDA GPU");
        return;
    }
    let scene = Scene::from_file(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/dam_break.toml"),
    )
    .unwrap();
    let p = scene.sample_particles().unwrap();
    let e = MultiGpuBackend::new(&scene, &p, found + 1, CudaOptions::default())
        .err()
        .expect("an error");
    let msg = e.to_string();
    println!("{msg}");
    assert!(msg.contains(&format!("{found} CUDA device")), "{msg}");
}

/// The health check on several GPUs reports a bad particle as one GPU does (the blow-up error
/// of `rtmpm_driver::Simulation::check`: particle, reason, material, position, velocity), on
/// the dam break: a NaN velocity given to the last GPU's particle farthest from the first cut
/// (reported from that GPU: every particle it spoils is that GPU's); then also an absurd
/// speed (1e6 m/s) given to the first GPU's particle farthest from it (two GPUs each report
/// their first bad particle; the merge keeps the lowest index, with its own reason, as the one
/// GPU's single report does).
#[test]
#[ignore = "needs 2 CUDA GPUs (or RTMPM_MULTI_GPU_DEVICES=0,0)"]
fn a_bad_particle_on_any_gpu_is_reported_as_on_one() {
    use rtmpm_physics::math::Vec3;
    use rtmpm_sim::{Blowup, SimError};
    if !usable(2) {
        return;
    }
    let gpus = ranks();
    let scene = Scene::from_file(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/dam_break.toml"),
    )
    .expect("scene");
    let p0 = scene.sample_particles().expect("particles");
    let part = rtmpm_cuda::multi::partition::slabs(&p0.x, gpus);
    let along = |i: &&u32| p0.x[**i as usize][part.axis];
    let last = *part.parts[gpus - 1]
        .iter()
        .max_by(|a, b| along(a).total_cmp(&along(b)))
        .expect("particles on the last GPU");
    let first = *part.parts[0]
        .iter()
        .min_by(|a, b| along(a).total_cmp(&along(b)))
        .expect("particles on the first GPU");
    let dt = {
        let one = CudaBackend::new(&scene, &p0, CudaOptions::default()).expect("1 GPU");
        Simulation::new(scene.clone(), Box::new(one))
            .next_dt()
            .expect("dt")
    };
    let nan = Vec3::splat(f32::NAN);
    let cases = [
        ("NaN on the last GPU", vec![(last, nan)]),
        (
            "NaN on the last GPU, too fast on the first",
            vec![(last, nan), (first, Vec3::new(1e6, 0.0, 0.0))],
        ),
    ];
    let report = |b: Box<dyn Backend>| -> Blowup {
        let mut sim = Simulation::new(scene.clone(), b);
        sim.backend.step(dt, 0.0).expect("step");
        match sim.check() {
            Err(SimError::Blowup(b)) => *b,
            other => panic!("a blow-up expected, got {other:?}"),
        }
    };
    let same = |a: Vec3, b: Vec3| {
        (0..3).all(|k| {
            (a[k].is_nan() && b[k].is_nan()) || (a[k] - b[k]).abs() <= 1e-3 * a[k].abs().max(1.0)
        })
    };
    for mode in MODES {
        if !mode_usable(mode, gpus, &scene, &p0) {
            continue;
        }
        for (what, edits) in &cases {
            let mut p = p0.clone();
            for &(i, v) in edits {
                p.v[i as usize] = v;
            }
            let a = report(Box::new(
                CudaBackend::new(&scene, &p, CudaOptions::default()).expect("1 GPU"),
            ));
            let b = report(Box::new(
                MultiGpuBackend::new(&scene, &p, gpus, options(gpus, mode)).expect("N GPUs"),
            ));
            let on = part
                .parts
                .iter()
                .position(|q| q.contains(&(b.particle as u32)));
            println!(
                "{what} [{mode}] x{gpus}: 1 GPU: particle {} ({}); {gpus} GPUs: particle {} on GPU \
                 {on:?} ({})",
                a.particle, a.reason, b.particle, b.reason
            );
            assert_eq!(a.particle, b.particle, "{what} [{mode}]");
            assert_eq!(a.reason, b.reason, "{what} [{mode}]");
            assert_eq!(a.material, b.material, "{what} [{mode}]");
            assert!(same(a.position, b.position), "{what}: {a:?} vs {b:?}");
            assert!(same(a.velocity, b.velocity), "{what}: {a:?} vs {b:?}");
            if edits.len() == 1 {
                assert_eq!(on, Some(gpus - 1), "{what}: reported from the last GPU");
            }
        }
    }
}
