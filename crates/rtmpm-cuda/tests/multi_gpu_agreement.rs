//! Several GPUs vs one GPU on every example scene, in every transport, barrier and exchange,
//! and steering on two GPUs as on one (needs 2 CUDA GPUs, and NCCL for transport=nccl; skips
//! with a message otherwise):
//! `cargo test -p rtmpm-cuda --test multi_gpu_agreement -- --include-ignored --nocapture`.
//! `RTMPM_MULTI_GPU_STEPS` sets the steps (default 300), `RTMPM_MULTI_GPU_COUNTS` the GPU counts
//! compared with one GPU (default "2,4", those above the devices present are skipped),
//! `RTMPM_MULTI_GPU_OPTIONS` the CUDA options (e.g. "graph=off"), `RTMPM_MULTI_GPU_MODES` the
//! transports and barriers compared, separated by `;` (default
//! "transport=p2p,barrier=spin;transport=p2p,barrier=events;transport=nccl").
//! `RTMPM_MULTI_GPU_DEVICES` (e.g. "0,0") puts the ranks on the devices listed (the CUDA option
//! `devices=0:0`), so that the tests of several GPUs run as several ranks on one GPU: the
//! counts are then the list's length, and the modes that cannot share a device (the spin
//! barrier, NCCL, the fused and pushed exchanges) are checked to be refused with a clear error
//! instead of run. The other tests of several GPUs: `tests/multi_gpu_errors.rs` (clear errors,
//! the bad-particle report) and `tests/multi_gpu_rigid.rs` (rigid bodies and their loads).

mod common;

use common::multi::{env_devices, mode_usable, options, ranks_share_a_device, scenes, usable};
use common::read;
use rtmpm_cuda::{CudaBackend, CudaOptions, MultiGpuBackend, Transport, device_count};
use rtmpm_driver::Simulation;
use rtmpm_scene::Scene;
use rtmpm_sim::Backend;
use std::path::Path;

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
    let modes: Vec<String> = std::env::var("RTMPM_MULTI_GPU_MODES")
        .unwrap_or_else(|_| {
            "transport=p2p,barrier=spin;transport=p2p,barrier=events;transport=nccl".into()
        })
        .split(';')
        .map(|m| m.trim().to_string())
        .filter(|m| !m.is_empty())
        .collect();
    let (ran, failures) = agree_on_every_example_scene(&modes);
    assert!(failures.is_empty(), "{failures:#?}");
    println!("{ran} runs of several GPUs compared with one GPU");
}

/// The exchanges of p2p with the spin barrier other than its default (`exchange=push` without
/// the overlap, run by the test above): `exchange=kernels` with the overlap (the default before),
/// `exchange=fused` (the shared list in one cooperative kernel with the inter-GPU barrier
/// inside), `exchange=push` with the overlap (the shared nodes pushed into the holders'
/// inboxes, the barrier inside the push and sum kernels), `exchange=push_update` (the inbox
/// summed inside the grid update's kernel) and `exchange=list_push_update` (that, with the
/// shared list and the push in one kernel after P2G) against one GPU, as the agreement test above: every
/// example
/// scene, 2 GPUs and 4 where present (`RTMPM_MULTI_GPU_COUNTS`, e.g. "2,4,8"), a re-partition
/// halfway.
/// Skips without 2 GPUs; ranks sharing a device (`RTMPM_MULTI_GPU_DEVICES=0,0`) must refuse
/// them all (they need the spin barrier).
#[test]
#[ignore = "needs 2 CUDA GPUs"]
fn the_fused_and_pushed_exchanges_agree_with_one_gpu() {
    if !usable(2) {
        return;
    }
    if ranks_share_a_device() {
        let scene = Scene::from_file(
            &Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/dam_break.toml"),
        )
        .expect("scene");
        let p = scene.sample_particles().expect("particles");
        for mode in [
            "exchange=fused",
            "exchange=push",
            "exchange=push_update",
            "exchange=list_push_update",
        ] {
            let e = MultiGpuBackend::new(&scene, &p, 2, options(2, mode))
                .err()
                .map(|e| e.to_string())
                .unwrap_or_default();
            assert!(e.contains("use exchange=kernels"), "{mode}: {e:?}");
            println!("{mode}: refused with ranks sharing a device, as it must be: {e}");
        }
        return;
    }
    // The default with p2p and the spin barrier is exchange=push without the overlap (run by
    // several_gpus_agree_with_one_on_every_example_scene); here the others.
    let modes = [
        "transport=p2p,barrier=spin,exchange=kernels,overlap=on".to_string(),
        "transport=p2p,barrier=spin,exchange=fused".to_string(),
        "transport=p2p,barrier=spin,exchange=push,overlap=on".to_string(),
        "transport=p2p,barrier=spin,exchange=push_update".to_string(),
        "transport=p2p,barrier=spin,exchange=list_push_update".to_string(),
    ];
    let (ran, failures) = agree_on_every_example_scene(&modes);
    assert!(failures.is_empty(), "{failures:#?}");
    assert!(ran > 0, "no run of several GPUs");
    println!("{ran} runs of the fused and pushed exchanges compared with one GPU");
}

/// Every example scene on several GPUs in each of `modes` against one GPU (the tolerances of
/// [`several_gpus_agree_with_one_on_every_example_scene`]); `RTMPM_MULTI_GPU_STEPS`,
/// `RTMPM_MULTI_GPU_COUNTS` and `RTMPM_MULTI_GPU_OPTIONS` as documented at the top. Returns the
/// runs made and the failures.
fn agree_on_every_example_scene(modes: &[String]) -> (usize, Vec<String>) {
    let steps: usize = std::env::var("RTMPM_MULTI_GPU_STEPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(300);
    let counts: Vec<usize> = match env_devices() {
        Some(d) => vec![d.len()],
        None => std::env::var("RTMPM_MULTI_GPU_COUNTS")
            .unwrap_or_else(|_| "2,4".into())
            .split(',')
            .filter_map(|s| s.trim().parse().ok())
            .filter(|&n| n >= 2 && n <= device_count())
            .collect(),
    };
    let mut failures = Vec::new();
    let mut ran = 0;
    for path in scenes() {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let scene = Scene::from_file(&path).expect("scene");
        let p0 = scene.sample_particles().expect("particles");
        if !scene.emitters.is_empty() {
            // Several GPUs refuse [[emitter]] tables (multi/plan.rs: the partition is fixed at
            // the start): a clear error before any GPU work, not a run to compare.
            match MultiGpuBackend::new(&scene, &p0, 2, options(2, "")) {
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
            if !mode_usable(mode, gpus, &scene, &p0) {
                continue;
            }
            let mopts = options(gpus, &format!("{base},{mode}"));
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
    (ran, failures)
}

/// Steering on two GPUs (transport chosen by default): gravity changed mid-run on a falling
/// jelly block gives the summed mean velocity to 1e-4 m/s, as on one GPU and the CPU
/// (tests/steer.rs); a ball swept through a block of sand moves the material as on one GPU
/// (centre of mass within 0.1 cell); a ball held in the sand, set once, still keeps the sand out
/// of its core after a rebalance rebuilt the GPUs' ranks.
#[test]
#[ignore = "needs 2 CUDA GPUs"]
fn steering_on_two_gpus_is_steering_on_one() {
    use rtmpm_geometry::{Tool, ToolShape};
    use rtmpm_physics::math::Vec3;
    if !usable(2) {
        return;
    }
    let jelly = Scene::from_toml(
        "gravity = [0.0, -9.8, 0.0]\n[domain]\nmin = [0,0,0]\nmax = [1,1,1]\ndx = 0.03125\n\
         [time]\nduration = 1.0\ndt = 1e-3\n[[material]]\nname = \"jelly\"\ntype = \"fixed_corotated\"\n\
         density = 1000.0\nyoungs_modulus = 1e5\npoisson_ratio = 0.3\n[[body]]\nmaterial = \"jelly\"\n\
         shape = \"box\"\nmin = [0.4, 0.6, 0.4]\nmax = [0.5, 0.7, 0.5]\n",
        "<jelly>",
    )
    .expect("scene");
    let p = jelly.sample_particles().expect("particles");
    let mut m = MultiGpuBackend::new(&jelly, &p, 2, options(2, "")).expect("2 GPUs");
    let dt = 1e-3;
    for s in 0..100 {
        if s == 50 {
            m.set_gravity(Vec3::new(2.0, 0.0, 0.0)).expect("gravity");
        }
        m.step(dt, s as f32 * dt).expect("step");
    }
    let q = read(&mut m);
    let v = q.v.iter().copied().sum::<Vec3>() / q.len() as f32;
    let expect = Vec3::new(0.1, -0.49, 0.0);
    println!("2 GPUs, gravity changed: mean velocity {v} (expected {expect})");
    assert!((v - expect).length() < 1e-4, "{v}");

    let sand = Scene::from_toml(
        "gravity = [0.0, -9.8, 0.0]\n[domain]\nmin = [0,0,0]\nmax = [1,1,1]\ndx = 0.03125\n\
         [time]\nduration = 1.0\ndt = 2e-4\n[walls]\nthickness = 3\n[[material]]\nname = \"sand\"\n\
         type = \"drucker_prager\"\ndensity = 1600.0\nyoungs_modulus = 3.5e5\npoisson_ratio = 0.3\n\
         friction_angle = 35.0\n[[body]]\nmaterial = \"sand\"\nshape = \"box\"\n\
         min = [0.35, 0.1, 0.35]\nmax = [0.65, 0.25, 0.65]\n",
        "<sand>",
    )
    .expect("scene");
    let p = sand.sample_particles().expect("particles");
    let ball = |center: Vec3, velocity: Vec3| Tool {
        shape: ToolShape::Sphere { radius: 0.06 },
        center,
        velocity,
    };
    let sweep = |b: &mut dyn Backend| {
        let (v, mut c) = (Vec3::new(3.0, 0.0, 0.0), Vec3::new(0.28, 0.17, 0.5));
        for s in 0..300 {
            b.set_tool(Some(ball(c, v))).expect("tool");
            b.step(2e-4, s as f32 * 2e-4).expect("step");
            c += v * 2e-4;
        }
        read(b)
    };
    let mut one = CudaBackend::new(&sand, &p, CudaOptions::default()).expect("1 GPU");
    let a = sweep(&mut one);
    let mut two = MultiGpuBackend::new(&sand, &p, 2, options(2, "")).expect("2 GPUs");
    let b = sweep(&mut two);
    let d = a.aggregate_difference(&b);
    println!("tool swept, 2 GPUs vs 1: |d com| {:.3e} m", d.com);
    assert!(d.com < 0.1 * sand.dx as f64, "{}", d.com);
    // A ball held under the falling jelly block, set once before the first step; the ranks are
    // rebuilt at step 100, before the block reaches it (about step 170): the block comes to rest
    // on the ball (its lowest particle above the ball's centre), or falls past it without (CPU,
    // one GPU's scene: lowest particle at y 0.485 with the ball, 0.158 without).
    let center = Vec3::new(0.45, 0.4, 0.45);
    let held = |tool: bool| {
        let p = jelly.sample_particles().expect("particles");
        let mut m = MultiGpuBackend::new(&jelly, &p, 2, options(2, "")).expect("2 GPUs");
        if tool {
            m.set_tool(Some(ball(center, Vec3::ZERO))).expect("tool");
        }
        for s in 0..300 {
            m.step(1e-3, s as f32 * 1e-3).expect("step");
            if s == 100 {
                m.rebalance_now().expect("rebalance");
            }
        }
        let q = read(&mut m);
        q.x.iter().map(|x| x.y).fold(f32::INFINITY, f32::min)
    };
    let (with, without) = (held(true), held(false));
    println!(
        "ball held through a rebalance: the block's lowest particle at y {with}, {without} without it"
    );
    assert!(
        with > center.y && without < center.y - 0.06,
        "{with} vs {without}"
    );
}
