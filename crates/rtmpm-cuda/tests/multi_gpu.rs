//! Several GPUs vs one GPU on every example scene (needs 2 CUDA GPUs, and NCCL for
//! transport=nccl; skips with a message otherwise):
//! `cargo test -p rtmpm-cuda --test multi_gpu -- --include-ignored --nocapture`.
//! `RTMPM_MULTI_GPU_STEPS` sets the steps (default 300), `RTMPM_MULTI_GPU_COUNTS` the GPU counts
//! compared with one GPU (default "2,4", those above the devices present are skipped),
//! `RTMPM_MULTI_GPU_OPTIONS` the CUDA options (e.g. "graph=off"), `RTMPM_MULTI_GPU_MODES` the
//! transports and barriers compared, separated by `;` (default
//! "transport=p2p,barrier=spin;transport=p2p,barrier=events;transport=nccl").

use rtmpm_core::sim::{Backend, Simulation};
use rtmpm_core::{Particles, Scene};
use rtmpm_cuda::{CudaBackend, CudaOptions, MultiGpuBackend, Transport, device_count, nccl, peer};
use std::path::Path;

fn scenes() -> Vec<std::path::PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .expect("scenes/")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    v
}

fn read(b: &mut dyn Backend) -> Particles {
    let mut p = Particles::default();
    b.read_particles(&mut p).expect("read particles");
    p
}

fn usable(gpus: usize) -> bool {
    let found = device_count();
    if found < gpus {
        println!("skipped: {gpus} CUDA GPUs needed, {found} found");
        return false;
    }
    true
}

/// Whether `mode` (e.g. "transport=nccl") can run on `gpus` GPUs here; prints why not.
fn mode_usable(mode: &str, gpus: usize) -> bool {
    if mode.contains("transport=nccl") {
        if let Err(e) = nccl::library() {
            println!("skipped {mode}: NCCL not usable ({e})");
            return false;
        }
    } else if mode.contains("transport=p2p") {
        match peer::first_pair_without_access(gpus) {
            Ok(None) => {}
            Ok(Some((i, j))) => {
                println!("skipped {mode} x{gpus}: GPU {i} has no peer access to GPU {j}");
                return false;
            }
            Err(e) => {
                println!("skipped {mode} x{gpus}: {e}");
                return false;
            }
        }
    }
    true
}

/// The tolerances of the CPU/GPU agreement test (tests/agreement.rs): after `steps` steps the
/// centre of mass within 0.1 cell, the kinetic energy within 2 %, the bounding box within 1 cell;
/// after one step every particle within float tolerance. Halfway, the particles are re-partitioned
/// (rebalancing) and the run goes on.
#[test]
#[ignore = "needs 2 CUDA GPUs and NCCL"]
fn several_gpus_agree_with_one_on_every_example_scene() {
    if !usable(2) {
        return;
    }
    let steps: usize = std::env::var("RTMPM_MULTI_GPU_STEPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(300);
    let counts: Vec<usize> = std::env::var("RTMPM_MULTI_GPU_COUNTS")
        .unwrap_or_else(|_| "2,4".into())
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .filter(|&n| n >= 2 && n <= device_count())
        .collect();
    let modes: Vec<String> = std::env::var("RTMPM_MULTI_GPU_MODES")
        .unwrap_or_else(|_| {
            "transport=p2p,barrier=spin;transport=p2p,barrier=events;transport=nccl".into()
        })
        .split(';')
        .map(|m| m.trim().to_string())
        .filter(|m| !m.is_empty())
        .collect();
    let mut failures = Vec::new();
    let mut ran = 0;
    for path in scenes() {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let scene = Scene::from_file(&path).expect("scene");
        let p0 = scene.sample_particles().expect("particles");
        if !scene.emitters.is_empty() {
            // Several GPUs refuse [[emitter]] tables (multi/plan.rs: the partition is fixed at
            // the start): a clear error before any GPU work, not a run to compare.
            match MultiGpuBackend::new(&scene, &p0, 2, CudaOptions::default()) {
                Ok(_) => failures.push(format!("{name}: several GPUs took a scene with emitters")),
                Err(e) => {
                    assert!(e.to_string().contains("[[emitter]]"), "{name}: {e}");
                    println!("{name}: refused on several GPUs, as documented: {e}");
                }
            }
            continue;
        }
        // RTMPM_MULTI_GPU_OPTIONS: CUDA options of every backend, e.g. "graph=off".
        let base = std::env::var("RTMPM_MULTI_GPU_OPTIONS").unwrap_or_default();
        let opts: CudaOptions = base.parse().expect("RTMPM_MULTI_GPU_OPTIONS");
        let dt = {
            let mut sim = Simulation::new(
                scene.clone(),
                Box::new(CudaBackend::new(&scene, &p0, opts.clone()).expect("1 GPU")),
            );
            sim.next_dt().expect("dt")
        };
        let dx = scene.dx;
        for (&gpus, mode) in counts
            .iter()
            .flat_map(|g| modes.iter().map(move |m| (g, m)))
        {
            if !mode_usable(mode, gpus) {
                continue;
            }
            let mopts: CudaOptions = format!("{base},{mode}").parse().expect("mode");
            let mut many = MultiGpuBackend::new(&scene, &p0, gpus, mopts.clone()).expect("N GPUs");
            // The backend runs the transport asked for.
            let want = if mode.contains("transport=nccl") {
                Transport::Nccl
            } else {
                Transport::P2p
            };
            assert_eq!(many.transport(), want, "{mode}: {}", many.name());
            ran += 1;
            let name = format!("{name} [{mode}]");
            let mut first = CudaBackend::new(&scene, &p0, opts.clone()).expect("1 GPU");
            first.step(dt, 0.0).expect("step");
            many.step(dt, 0.0).expect("step");
            let (a, b) = (read(&mut first), read(&mut many));
            let vscale = a.v.iter().map(|v| v.length()).fold(1e-3f32, f32::max);
            let (mut wx, mut wv) = (0f32, 0f32);
            for i in 0..a.len() {
                wx = wx.max((a.x[i] - b.x[i]).length());
                wv = wv.max((a.v[i] - b.v[i]).length());
            }
            println!(
                "{name} x{gpus}: 1 step: max |dx| {wx:.3e} m, max |dv| {wv:.3e} m/s (v scale {vscale:.3e}); {} shared blocks, {:?} particles per GPU",
                many.shared_blocks().unwrap(),
                many.counts().unwrap()
            );
            if wx > 1e-5 * dx.max(1e-3) + 1e-6 || wv > 1e-3 * vscale {
                failures.push(format!("{name} x{gpus}: first step differs"));
            }
            for s in 1..steps {
                if s == steps / 2 {
                    many.rebalance_now().expect("rebalance");
                }
                first.step(dt, s as f32 * dt).expect("step");
                many.step(dt, s as f32 * dt).expect("step");
            }
            assert!(many.check().expect("check").is_none(), "{name}: blow-up");
            let (a, b) = (read(&mut first), read(&mut many));
            let d = a.aggregate_difference(&b);
            let dx = dx as f64;
            println!(
                "{name} x{gpus}: {steps} steps: |d com| {:.3e} m ({:.4} dx), d KE {:.3} %, |d bbox| {:.3e} m ({:.3} dx), {} rebalance(s)",
                d.com,
                d.com / dx,
                100.0 * d.kinetic,
                d.bbox,
                d.bbox / dx,
                many.rebalances
            );
            if d.com > 0.1 * dx || d.kinetic > 0.02 || d.bbox > dx {
                failures.push(format!(
                    "{name} x{gpus}: aggregates differ after {steps} steps"
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
    println!("{ran} runs of several GPUs compared with one GPU");
}

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
    let o: CudaOptions = "transport=nccl,barrier=spin".parse().unwrap();
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
