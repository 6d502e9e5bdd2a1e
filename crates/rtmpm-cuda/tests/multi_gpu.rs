//! Several GPUs vs one GPU on every example scene (needs 2 CUDA GPUs, and NCCL for
//! transport=nccl; skips with a message otherwise):
//! `cargo test -p rtmpm-cuda --test multi_gpu -- --include-ignored --nocapture`.
//! `RTMPM_MULTI_GPU_STEPS` sets the steps (default 300), `RTMPM_MULTI_GPU_COUNTS` the GPU counts
//! compared with one GPU (default "2,4", those above the devices present are skipped),
//! `RTMPM_MULTI_GPU_OPTIONS` the CUDA options (e.g. "graph=off"), `RTMPM_MULTI_GPU_MODES` the
//! transports and barriers compared, separated by `;` (default
//! "transport=p2p,barrier=spin;transport=p2p,barrier=events;transport=nccl").
//! `RTMPM_MULTI_GPU_DEVICES` (e.g. "0,0") puts the ranks on the devices listed (the CUDA option
//! `devices=0:0`), so that the tests of several GPUs run as several ranks on one GPU: the
//! counts are then the list's length, and the modes that cannot share a device (the spin
//! barrier, NCCL) are checked to be refused with a clear error instead of run.

use rtmpm_cuda::{CudaBackend, CudaOptions, MultiGpuBackend, Transport, device_count, nccl, peer};
use rtmpm_driver::Simulation;
use rtmpm_physics::Particles;
use rtmpm_scene::Scene;
use rtmpm_sim::Backend;
use std::path::Path;

#[cfg(feature = "rigid")]
mod loads;

/// `RTMPM_MULTI_GPU_DEVICES`: the device of each rank, when set.
fn env_devices() -> Option<Vec<usize>> {
    let v = std::env::var("RTMPM_MULTI_GPU_DEVICES").ok()?;
    let d: Vec<usize> = v
        .split(',')
        .map(|x| {
            x.trim()
                .parse()
                .expect("RTMPM_MULTI_GPU_DEVICES: ordinals, e.g. 0,0")
        })
        .collect();
    assert!(d.len() >= 2, "RTMPM_MULTI_GPU_DEVICES: at least two ranks");
    Some(d)
}

/// `o` with the ranks of a run of `gpus` on the devices of `RTMPM_MULTI_GPU_DEVICES` (cycled),
/// when set.
fn on_devices(gpus: usize, o: CudaOptions) -> CudaOptions {
    match env_devices() {
        Some(d) => CudaOptions {
            devices: Some((0..gpus).map(|i| d[i % d.len()]).collect()),
            ..o
        },
        None => o,
    }
}

/// Options of `text` for a run of `gpus` ranks (see [`on_devices`]).
fn options(gpus: usize, text: &str) -> CudaOptions {
    on_devices(gpus, text.parse().expect("CUDA options"))
}

/// True when two ranks share a device (`RTMPM_MULTI_GPU_DEVICES`).
fn ranks_share_a_device() -> bool {
    env_devices().is_some_and(|d| (1..d.len()).any(|i| d[..i].contains(&d[i])))
}

fn scenes() -> Vec<std::path::PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .expect("scenes/")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        // A batch of worlds ([batch]) is many scenes, not one: its worlds against separate
        // CUDA runs are tests/batch.rs.
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

fn usable(gpus: usize) -> bool {
    let found = device_count();
    let needed = match env_devices() {
        Some(d) => d.iter().max().map_or(0, |m| m + 1),
        None => gpus,
    };
    if found < needed {
        println!("skipped: {needed} CUDA GPUs needed, {found} found");
        return false;
    }
    true
}

/// Whether `mode` (e.g. "transport=nccl") can run on `gpus` GPUs here; prints why not. Ranks
/// sharing a device: the spin barrier and NCCL must be refused with a clear error (checked
/// here on `scene`), and are not run.
fn mode_usable(mode: &str, gpus: usize, scene: &Scene, p: &Particles) -> bool {
    if ranks_share_a_device() && (mode.contains("barrier=spin") || mode.contains("nccl")) {
        let e = MultiGpuBackend::new(scene, p, gpus, options(gpus, mode))
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        let want = if mode.contains("nccl") {
            "NCCL refuses two ranks on one device"
        } else {
            "use barrier=events"
        };
        assert!(
            e.contains(want),
            "{mode} with ranks sharing a device: {e:?}"
        );
        println!("{mode} x{gpus}: refused with ranks sharing a device, as it must be: {e}");
        return false;
    }
    if mode.contains("transport=nccl") {
        if let Err(e) = nccl::library() {
            println!("skipped {mode}: NCCL not usable ({e})");
            return false;
        }
    } else if mode.contains("transport=p2p") {
        let devices = options(gpus, "")
            .devices
            .unwrap_or_else(|| (0..gpus).collect());
        match peer::first_pair_without_access_among(&devices) {
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

/// `exchange=fused` (the shared list in one cooperative kernel with the inter-GPU barrier
/// inside) and `exchange=push` (the shared nodes pushed into the holders' inboxes, the barrier
/// inside the push and sum kernels) against one GPU, as the agreement test above: every example
/// scene, 2 GPUs and 4 where present (`RTMPM_MULTI_GPU_COUNTS`, e.g. "2,4,8"), a re-partition
/// halfway.
/// Skips without 2 GPUs; ranks sharing a device (`RTMPM_MULTI_GPU_DEVICES=0,0`) must refuse
/// both (they need the spin barrier).
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
        for mode in ["exchange=fused", "exchange=push"] {
            let e = MultiGpuBackend::new(&scene, &p, 2, options(2, mode))
                .err()
                .map(|e| e.to_string())
                .unwrap_or_default();
            assert!(e.contains("use exchange=kernels"), "{mode}: {e:?}");
            println!("{mode}: refused with ranks sharing a device, as it must be: {e}");
        }
        return;
    }
    let modes = [
        "transport=p2p,barrier=spin,exchange=fused".to_string(),
        "transport=p2p,barrier=spin,exchange=push".to_string(),
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

/// The GPU count of the tests below: 2, or the ranks of `RTMPM_MULTI_GPU_DEVICES`.
fn ranks() -> usize {
    env_devices().map_or(2, |d| d.len())
}

/// The modes the tests below compare: the p2p barriers and NCCL (those that cannot share a
/// device are checked to be refused there, [`mode_usable`]).
const MODES: [&str; 3] = [
    "transport=p2p,barrier=spin",
    "transport=p2p,barrier=events",
    "transport=nccl",
];

/// The first GPU's slab of the partition: (axis, the largest coordinate of its particles).
#[cfg(feature = "rigid")]
fn first_cut(p: &Particles, gpus: usize) -> (usize, f32) {
    let part = rtmpm_cuda::multi::partition::slabs(&p.x, gpus);
    let cut = part.parts[0]
        .iter()
        .map(|&i| p.x[i as usize][part.axis])
        .fold(f32::NEG_INFINITY, f32::max);
    (part.axis, cut)
}

/// The scenes of `scenes/rigid/`, sorted.
#[cfg(feature = "rigid")]
fn rigid_scenes() -> Vec<std::path::PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/rigid");
    let mut paths: Vec<_> = std::fs::read_dir(dir)
        .expect("scenes/rigid/")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    paths.sort();
    paths
}

/// `RTMPM_MULTI_GPU_RIGID_SECONDS`: simulated seconds of the rigid-body comparisons (0.5).
#[cfg(feature = "rigid")]
fn rigid_seconds() -> f32 {
    std::env::var("RTMPM_MULTI_GPU_RIGID_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.5)
}

/// The bodies of a multi-GPU run (`b`) against one GPU's (`a`), printed; a failure per body
/// outside the tolerances of [`several_gpus_agree_with_one_on_the_rigid_scenes`] (`peak`: each
/// body's largest speed and angular speed in the one-GPU run).
#[cfg(feature = "rigid")]
fn bodies_differ(
    label: &str,
    scene: &Scene,
    a: &[rtmpm_rigid::BodyPose],
    b: &[rtmpm_rigid::BodyPose],
    peak: &[(f32, f32)],
) -> Vec<String> {
    assert_eq!(a.len(), b.len(), "{label}");
    let dx = scene.dx;
    let mut failures = Vec::new();
    for (k, (pa, pb)) in a.iter().zip(b).enumerate() {
        let r = scene.rigid_bodies[k].shape.bounding_radius();
        let dpos = (pa.position - pb.position).length();
        let drot = pa.rotation.angle_between(pb.rotation) * r;
        let dv = (pa.velocity - pb.velocity).length();
        let dw = (pa.angular_velocity - pb.angular_velocity).length();
        let (vmax, wmax) = peak[k];
        println!(
            "{label}: body {k}: |d position| {:.4} dx, rotation {:.4} dx at its farthest \
             point, |d v| {dv:.3e} m/s (peak {vmax:.3}), |d omega| {dw:.3e} rad/s (peak \
             {wmax:.3}); 1 GPU at {}, v {}",
            dpos / dx,
            drot / dx,
            pa.position,
            pa.velocity
        );
        if dpos > 0.1 * dx || drot > 0.1 * dx || dv > 0.02 * vmax + 1e-3 || dw > 0.02 * wmax + 1e-2
        {
            failures.push(format!("{label}: body {k} differs"));
        }
    }
    failures
}

/// The particles' aggregates of a multi-GPU run (`b`) against one GPU's (`a`), printed; a
/// failure outside the agreement test's tolerances.
#[cfg(feature = "rigid")]
fn particles_differ(label: &str, dx: f32, a: &Particles, b: &Particles) -> Option<String> {
    let d = a.aggregate_difference(b);
    let dx = dx as f64;
    println!(
        "{label}: particles: |d com| {:.4} dx, d KE {:.3} %, |d bbox| {:.3} dx",
        d.com / dx,
        100.0 * d.kinetic,
        d.bbox / dx,
    );
    (d.com > 0.1 * dx || d.kinetic > 0.02 || d.bbox > dx)
        .then(|| format!("{label}: particle aggregates differ"))
}

/// Rigid bodies on several GPUs (cargo feature `rigid`): every scene of `scenes/rigid/` for
/// `RTMPM_MULTI_GPU_RIGID_SECONDS` of simulated time (default 0.5 s: the ball falls into the
/// sand, the dam breaks onto the gate and the floating bodies) at a fixed dt (0.8 of the
/// scene's first CFL step), frame ends as in a run, and a re-partition halfway, on 2 GPUs (or
/// ranks) against one GPU; heavy_ball also with `rigid_overlap=off`. Every body's position
/// within 0.1 dx and its rotation within 0.1 dx at its farthest point (the tolerance of
/// tests/rigid.rs for one GPU against the CPU: the floating height within a tenth of a cell);
/// its velocity and angular velocity within 2 % of the largest the body reached in the one-GPU
/// run (the kinetic-energy tolerance of the agreement test) plus 1 mm/s (0.01 rad/s); the
/// particles' aggregates within the agreement test's tolerances. heavy_ball's ball starts over
/// the cut between the first two GPUs' slabs (checked), so it lands on blocks both GPUs hold:
/// with their nodes' reactions counted on both, its impulse from them would double.
#[cfg(feature = "rigid")]
#[test]
#[ignore = "needs 2 CUDA GPUs (or RTMPM_MULTI_GPU_DEVICES=0,0)"]
fn several_gpus_agree_with_one_on_the_rigid_scenes() {
    if !usable(2) {
        return;
    }
    let gpus = ranks();
    let seconds = rigid_seconds();
    let (mut failures, mut across, mut ran) = (Vec::new(), Vec::new(), 0);
    for path in rigid_scenes() {
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        let scene = Scene::from_file(&path).expect("scene");
        let p0 = scene.sample_particles().expect("particles");
        let dx = scene.dx;
        let (axis, cut) = first_cut(&p0, gpus);
        for b in &scene.rigid_bodies {
            if (b.position[axis] - cut).abs() < b.shape.bounding_radius() {
                across.push(name.clone());
            }
        }
        let dt = {
            let one = CudaBackend::new(&scene, &p0, CudaOptions::default()).expect("1 GPU");
            0.8 * Simulation::new(scene.clone(), Box::new(one))
                .next_dt()
                .expect("dt")
        };
        let steps = (seconds / dt).ceil() as usize;
        let per_frame = ((1.0 / scene.time.fps) / dt).round().max(1.0) as usize;
        let variants: &[&str] = if name == "heavy_ball" {
            &["", "rigid_overlap=off"]
        } else {
            &[""]
        };
        for (variant, mode) in variants
            .iter()
            .flat_map(|v| MODES.iter().map(move |m| (*v, *m)))
        {
            if !mode_usable(mode, gpus, &scene, &p0) {
                continue;
            }
            ran += 1;
            let label = format!(
                "{name} [{variant}{}{mode}] x{gpus}",
                if variant.is_empty() { "" } else { "," }
            );
            let mut one =
                CudaBackend::new(&scene, &p0, variant.parse().expect("options")).expect("1 GPU");
            let mut many = MultiGpuBackend::new(
                &scene,
                &p0,
                gpus,
                options(gpus, &format!("{variant},{mode}")),
            )
            .expect("N GPUs");
            let mut peak = vec![(0f32, 0f32); scene.rigid_bodies.len()];
            for s in 0..steps {
                if s == steps / 2 {
                    // The re-partition gives the bodies the pending sums first: so does one GPU.
                    many.rebalance_now().expect("rebalance");
                    one.flush_rigid().expect("flush");
                }
                let t = s as f32 * dt;
                one.step(dt, t).expect("step");
                many.step(dt, t).expect("step");
                if (s + 1) % per_frame == 0 || s + 1 == steps {
                    one.end_of_frame().expect("frame end");
                    many.end_of_frame().expect("frame end");
                    for (k, b) in one.rigid_poses().iter().enumerate() {
                        peak[k].0 = peak[k].0.max(b.velocity.length());
                        peak[k].1 = peak[k].1.max(b.angular_velocity.length());
                    }
                }
            }
            assert!(
                one.check().expect("check").is_none(),
                "{label}: 1 GPU blew up"
            );
            assert!(many.check().expect("check").is_none(), "{label}: blow-up");
            let label = format!("{label} after {steps} steps of {dt:.3e} s");
            let (a, b) = (one.rigid_poses(), many.rigid_poses());
            failures.extend(bodies_differ(&label, &scene, &a, &b, &peak));
            if name == "heavy_ball" {
                assert!(peak[0].0 > 0.5, "{label}: the ball never fell ({peak:?})");
            }
            let (pa, pb) = (read(&mut one), read(&mut many));
            let label = format!("{label}, {} rebalance(s)", many.rebalances);
            failures.extend(particles_differ(&label, dx, &pa, &pb));
        }
    }
    println!("{ran} rigid-body runs compared; bodies across the first cut in: {across:?}");
    assert!(ran > 0, "no mode could run");
    assert!(
        across.iter().any(|n| n == "heavy_ball"),
        "heavy_ball's ball no longer starts over the cut: {across:?}"
    );
    assert!(failures.is_empty(), "{failures:#?}");
}

/// What a rank of [`nccl_ranks_agree_with_one_gpu_on_the_rigid_scenes`] ends with: its bodies
/// at the end and at every frame end, its particles at the end (an all-gather: the whole run's),
/// its re-partitions.
#[cfg(feature = "rigid")]
type RankEnd = (
    Vec<rtmpm_rigid::BodyPose>,
    Vec<Vec<rtmpm_rigid::BodyPose>>,
    Particles,
    u32,
);

/// Rigid bodies in a run of one process per GPU (`NcclRankBackend`, the backend of
/// `rtmpm run --rendezvous`; cargo feature `rigid`): its two ranks are run here by two threads,
/// each with its own backend, rapier world and NCCL rank, on devices 0 and 1, meeting through
/// a file rendezvous as two processes do. Every scene of `scenes/rigid/` as in
/// [`several_gpus_agree_with_one_on_the_rigid_scenes`] (fixed dt, frame ends, a re-partition
/// halfway, heavy_ball also with `rigid_overlap=off`), against one GPU with its tolerances;
/// and the two ranks' bodies identical bit for bit at every frame end (each rank advances its
/// own world by the sums of both GPUs). Needs 2 GPUs and NCCL (NCCL refuses two ranks on one
/// device, so `RTMPM_MULTI_GPU_DEVICES=0,0` cannot run it).
#[cfg(feature = "rigid")]
#[test]
#[ignore = "needs 2 CUDA GPUs and NCCL"]
fn nccl_ranks_agree_with_one_gpu_on_the_rigid_scenes() {
    use rtmpm_cuda::NcclRankBackend;
    use rtmpm_cuda::rendezvous::Rendezvous;
    let found = device_count();
    if found < 2 {
        println!(
            "skipped: 2 CUDA GPUs needed (NCCL refuses two ranks on one device), {found} found"
        );
        return;
    }
    if let Err(e) = nccl::library() {
        println!("skipped: NCCL not usable ({e})");
        return;
    }
    let seconds = rigid_seconds();
    let (mut failures, mut ran) = (Vec::new(), 0);
    for path in rigid_scenes() {
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        let scene = Scene::from_file(&path).expect("scene");
        let p0 = scene.sample_particles().expect("particles");
        let dx = scene.dx;
        let dt = {
            let one = CudaBackend::new(&scene, &p0, CudaOptions::default()).expect("1 GPU");
            0.8 * Simulation::new(scene.clone(), Box::new(one))
                .next_dt()
                .expect("dt")
        };
        let steps = (seconds / dt).ceil() as usize;
        let per_frame = ((1.0 / scene.time.fps) / dt).round().max(1.0) as usize;
        let frame_end = |s: usize| (s + 1).is_multiple_of(per_frame) || s + 1 == steps;
        let variants: &[&str] = if name == "heavy_ball" {
            &["", "rigid_overlap=off"]
        } else {
            &[""]
        };
        for (v, variant) in variants.iter().enumerate() {
            ran += 1;
            let label = format!("{name} [{variant}] 2 NCCL ranks, {steps} steps of {dt:.3e} s");
            let o: CudaOptions = variant.parse().expect("options");
            // One GPU, the same steps (the re-partition's flush of the bodies too).
            let mut one = CudaBackend::new(&scene, &p0, o.clone()).expect("1 GPU");
            let mut peak = vec![(0f32, 0f32); scene.rigid_bodies.len()];
            for s in 0..steps {
                if s == steps / 2 {
                    one.flush_rigid().expect("flush");
                }
                one.step(dt, s as f32 * dt).expect("step");
                if frame_end(s) {
                    one.end_of_frame().expect("frame end");
                    for (k, b) in one.rigid_poses().iter().enumerate() {
                        peak[k].0 = peak[k].0.max(b.velocity.length());
                        peak[k].1 = peak[k].1.max(b.angular_velocity.length());
                    }
                }
            }
            assert!(
                one.check().expect("check").is_none(),
                "{label}: 1 GPU blew up"
            );
            let (a, pa) = (one.rigid_poses(), read(&mut one));
            drop(one);
            // Two ranks, one thread each (as two processes: nothing shared but the rendezvous).
            let file = std::env::temp_dir().join(format!(
                "rtmpm-rigid-ranks-{}-{name}-{v}.id",
                std::process::id()
            ));
            let _ = std::fs::remove_file(&file);
            let rdv: Rendezvous = format!("file:{}", file.display()).parse().expect("file:");
            let run = |me: usize| -> Result<RankEnd, String> {
                let err = |e: rtmpm_sim::SimError| format!("rank {me}: {e}");
                let mut b =
                    NcclRankBackend::new(&scene, &p0, me, 2, me, &rdv, o.clone()).map_err(err)?;
                let mut frames = Vec::new();
                for s in 0..steps {
                    if s == steps / 2 {
                        b.rebalance_now().map_err(err)?;
                    }
                    b.step(dt, s as f32 * dt).map_err(err)?;
                    if frame_end(s) {
                        b.end_of_frame().map_err(err)?;
                        frames.push(b.rigid_poses());
                    }
                }
                if let Some(bad) = b.check().map_err(err)? {
                    return Err(format!("rank {me}: blow-up {bad:?}"));
                }
                let p = read(&mut b);
                Ok((b.rigid_poses(), frames, p, b.rebalances))
            };
            let run = &run;
            let ends: Vec<RankEnd> = std::thread::scope(|threads| {
                let ranks: Vec<_> = (0..2).map(|me| threads.spawn(move || run(me))).collect();
                ranks
                    .into_iter()
                    .map(|h| {
                        h.join()
                            .expect("rank thread")
                            .unwrap_or_else(|e| panic!("{e}"))
                    })
                    .collect()
            });
            // Both ranks' worlds took the same steps with the same sums: the same bodies.
            assert_eq!(ends[0].1.len(), ends[1].1.len(), "{label}");
            for (f, (x, y)) in ends[0].1.iter().zip(&ends[1].1).enumerate() {
                assert_eq!(x, y, "{label}: the ranks' bodies differ at frame end {f}");
            }
            assert_eq!(ends[0].0, ends[1].0, "{label}: the ranks' bodies differ");
            let (b, pb, rebalances) = (&ends[0].0, &ends[0].2, ends[0].3);
            assert_eq!(rebalances, ends[1].3, "{label}");
            failures.extend(bodies_differ(&label, &scene, &a, b, &peak));
            if name == "heavy_ball" {
                assert!(peak[0].0 > 0.5, "{label}: the ball never fell ({peak:?})");
            }
            let label = format!("{label}, {rebalances} rebalance(s)");
            failures.extend(particles_differ(&label, dx, &pa, pb));
        }
    }
    println!("{ran} rigid-body runs of 2 NCCL ranks compared");
    assert!(ran > 0, "no scene ran");
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The scene of `tests/loads/mod.rs` with its tool over the cut between the first two GPUs'
/// slabs of a run of `gpus` (checked: the slabs cut the bed along x), and its particles: the
/// tool's nodes lie in pblocks both GPUs hold, whose reactions each GPU adds a share of.
#[cfg(feature = "rigid")]
fn tool_over_the_cut(gpus: usize) -> (Scene, Particles) {
    let p0 = loads::sand_and_tool(0.25)
        .sample_particles()
        .expect("particles");
    let (axis, cut) = first_cut(&p0, gpus);
    assert_eq!(axis, 0, "the slabs cut the bed along x");
    let scene = loads::sand_and_tool(cut);
    let p = scene.sample_particles().expect("particles");
    assert!(p.x == p0.x, "the tool's place changed the particles");
    println!("the tool's centre at x = {cut} m, on the first cut");
    (scene, p)
}

/// Loads on several GPUs of one process (`MultiGpuBackend`, cargo feature `rigid`): the
/// kinematic tool of `tests/loads/mod.rs`, pressed into sand over the cut between the first two
/// GPUs' slabs, reports the load one GPU reports: the mean force and torque over the last 200 of
/// 800 steps within the tolerance of `tests/rigid.rs`'s one GPU against the CPU (the force
/// within 5 % of its size, the torque within 5 % of its size plus 1e-4 N m), in every mode
/// (`MODES`; those that cannot share a device are checked to be refused there), with the bodies
/// moved a step late (the default) and after every step. A kinematic body's reaction not summed
/// would report zero; a shared node counted on both GPUs, up to twice the load. About 20 s on
/// two ranks of an H200.
#[cfg(feature = "rigid")]
#[test]
#[ignore = "needs 2 CUDA GPUs (or RTMPM_MULTI_GPU_DEVICES=0,0)"]
fn several_gpus_report_a_kinematic_tools_load_as_one() {
    if !usable(2) {
        return;
    }
    let gpus = ranks();
    let (scene, p0) = tool_over_the_cut(gpus);
    let (mut failures, mut ran) = (Vec::new(), 0);
    for variant in ["", "rigid_overlap=off"] {
        let mut one =
            CudaBackend::new(&scene, &p0, variant.parse().expect("options")).expect("1 GPU");
        let want = loads::push(&mut one);
        loads::assert_the_sand_pushes_back(&want);
        drop(one);
        for mode in MODES {
            if !mode_usable(mode, gpus, &scene, &p0) {
                continue;
            }
            ran += 1;
            let o = options(gpus, &format!("{variant},{mode}"));
            let mut many = MultiGpuBackend::new(&scene, &p0, gpus, o).expect("N GPUs");
            let got = loads::push(&mut many);
            let label = format!("[{variant},{mode}] x{gpus} (1 GPU: the reference)");
            failures.extend(loads::differ(&label, &got, &want));
        }
    }
    assert!(ran > 0, "no mode could run");
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Loads in a run of one process per GPU (`NcclRankBackend`, `rtmpm run --rendezvous`; cargo
/// feature `rigid`), its two ranks run by two threads on devices 0 and 1 as in
/// [`nccl_ranks_agree_with_one_gpu_on_the_rigid_scenes`]: the kinematic tool of
/// [`several_gpus_report_a_kinematic_tools_load_as_one`] over the cut reports, in both ranks,
/// the same mean load bit for bit (the impulse sums of both GPUs, summed by the all-reduce, with
/// the kinematic body's among them), within that test's tolerance of one GPU's, with the bodies
/// moved a step late and after every step. Needs 2 GPUs and NCCL. About 10 s on two H200s.
#[cfg(feature = "rigid")]
#[test]
#[ignore = "needs 2 CUDA GPUs and NCCL"]
fn nccl_ranks_report_a_kinematic_tools_load_as_one_gpu() {
    use rtmpm_cuda::NcclRankBackend;
    use rtmpm_cuda::rendezvous::Rendezvous;
    let found = device_count();
    if found < 2 {
        println!(
            "skipped: 2 CUDA GPUs needed (NCCL refuses two ranks on one device), {found} found"
        );
        return;
    }
    if let Err(e) = nccl::library() {
        println!("skipped: NCCL not usable ({e})");
        return;
    }
    let (scene, p0) = tool_over_the_cut(2);
    let mut failures = Vec::new();
    for (v, variant) in ["", "rigid_overlap=off"].iter().enumerate() {
        let o: CudaOptions = variant.parse().expect("options");
        let mut one = CudaBackend::new(&scene, &p0, o.clone()).expect("1 GPU");
        let want = loads::push(&mut one);
        loads::assert_the_sand_pushes_back(&want);
        drop(one);
        let file =
            std::env::temp_dir().join(format!("rtmpm-loads-ranks-{}-{v}.id", std::process::id()));
        let _ = std::fs::remove_file(&file);
        let rdv: Rendezvous = format!("file:{}", file.display()).parse().expect("file:");
        let run = |me: usize| -> loads::Mean {
            let mut b = NcclRankBackend::new(&scene, &p0, me, 2, me, &rdv, o.clone())
                .unwrap_or_else(|e| panic!("rank {me}: {e}"));
            loads::push(&mut b)
        };
        let run = &run;
        let means: Vec<loads::Mean> = std::thread::scope(|threads| {
            let ranks: Vec<_> = (0..2).map(|me| threads.spawn(move || run(me))).collect();
            ranks
                .into_iter()
                .map(|h| h.join().expect("rank thread"))
                .collect()
        });
        let label = format!("[{variant}] 2 NCCL ranks");
        assert_eq!(
            means[0].force(),
            means[1].force(),
            "{label}: the ranks' forces"
        );
        assert_eq!(
            means[0].torque(),
            means[1].torque(),
            "{label}: the ranks' torques"
        );
        failures.extend(loads::differ(
            &format!("{label} (1 GPU: the reference)"),
            &means[0],
            &want,
        ));
    }
    assert!(failures.is_empty(), "{failures:#?}");
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
