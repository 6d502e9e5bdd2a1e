//! `rtmpm run` on several GPUs: `--gpus 2` and two processes meeting through a file rendezvous
//! (one GPU each) agree with one GPU on every example scene, and two processes agree with one
//! GPU on the rigid-body scenes (`scenes/rigid/`). Needs 2 CUDA GPUs and NCCL; skips with a
//! message otherwise. Errors of the multi-GPU options need no GPU.

mod common;
use common::{rtmpm, scratch, text};
use rtmpm_io::ply::read_ply;
use rtmpm_physics::Particles;
use rtmpm_physics::math::Vec3;
use rtmpm_scene::Scene;
use std::path::{Path, PathBuf};
use std::process::Command;

fn scenes() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .expect("scenes/")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        // A batch of worlds ([batch]) runs on the CPU backend only.
        .filter(|p| !rtmpm_scene::BatchScene::from_file(p).is_ok_and(|b| b.batch.is_some()))
        .collect();
    v.sort();
    v
}

/// The particles of the last PLY frame of a run, with the masses of the scene's sampling.
fn last_frame(dir: &Path, frames: u64, scene: &Scene) -> Particles {
    let ply = read_ply(&dir.join(format!("frame_{frames:05}.ply")))
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    let col = |n: &str| ply.f32(n).unwrap_or_else(|| panic!("column {n}")).to_vec();
    let (x, y, z, vx, vy, vz) = (
        col("x"),
        col("y"),
        col("z"),
        col("vx"),
        col("vy"),
        col("vz"),
    );
    let mut p = scene.sample_particles().expect("particles");
    assert_eq!(p.len(), x.len());
    for i in 0..x.len() {
        p.x[i] = Vec3::new(x[i], y[i], z[i]);
        p.v[i] = Vec3::new(vx[i], vy[i], vz[i]);
    }
    p
}

/// Agreement as in the CPU/GPU agreement test: centre of mass within 0.1 cell, kinetic energy
/// within 2 %, bounding box within 1 cell.
fn agree(name: &str, dx: f32, a: &Particles, b: &Particles) -> bool {
    let d = a.aggregate_difference(b);
    let dx = dx as f64;
    println!(
        "{name}: |d com| {:.4} dx, d KE {:.3} %, |d bbox| {:.3} dx",
        d.com / dx,
        100.0 * d.kinetic,
        d.bbox / dx
    );
    d.com < 0.1 * dx && d.kinetic < 0.02 && d.bbox < dx
}

#[test]
#[ignore = "needs 2 CUDA GPUs and NCCL"]
fn two_gpus_and_two_processes_agree_with_one_gpu_on_every_example_scene() {
    let found = rtmpm_cuda::device_count();
    if found < 2 {
        println!("skipped: 2 CUDA GPUs needed, {found} found");
        return;
    }
    if let Err(e) = rtmpm_cuda::nccl::library() {
        println!("skipped: NCCL not usable ({e})");
        return;
    }
    let frames: u64 = std::env::var("RTMPM_MULTI_GPU_FRAMES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(4);
    let f = frames.to_string();
    // RTMPM_MULTI_GPU_OPTIONS: --cuda-options of every run, e.g. "graph=off".
    let copts = std::env::var("RTMPM_MULTI_GPU_OPTIONS").unwrap_or_default();
    let run = |extra: &[&str]| {
        let mut a = extra.to_vec();
        a.extend(["--cuda-options", copts.as_str()]);
        rtmpm(&a)
    };
    let mut failures = Vec::new();
    for path in scenes() {
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        let scene = Scene::from_file(&path).expect("scene");
        let s = path.to_str().unwrap();
        let dir = scratch(&format!("mgpu_{name}"));
        let (one, two, ranks) = (dir.join("one"), dir.join("two"), dir.join("ranks"));
        let two_gpus = || {
            let out = two.to_str().unwrap();
            run(&["run", s, "--gpus", "2", "--frames", &f, "--out", out])
        };
        if !scene.emitters.is_empty() {
            // Several GPUs refuse [[emitter]] tables: a clear error and a failed exit.
            let o = two_gpus();
            assert!(
                !o.status.success(),
                "{name}: --gpus 2 took emitters: {}",
                text(&o)
            );
            assert!(text(&o).contains("[[emitter]]"), "{name}: {}", text(&o));
            println!("{name}: refused on 2 GPUs, as documented");
            continue;
        }
        let o = run(&[
            "run",
            s,
            "--backend",
            "cuda",
            "--frames",
            &f,
            "--out",
            one.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", text(&o));
        let o = two_gpus();
        assert!(o.status.success(), "{}", text(&o));
        assert!(text(&o).contains("cuda x2"), "{}", text(&o));
        // The run summary says which transport summed the shared blocks, and why.
        assert!(text(&o).contains("transport "), "{}", text(&o));
        // Two processes, one GPU each, meeting through a file (a free TCP port found by binding
        // and releasing it could be taken again before rank 0 listens: seen once on 2 H200s;
        // the TCP rendezvous has its own tests in rtmpm-cuda's multi::rendezvous).
        let rdv_file = dir.join(format!("{name}.rendezvous"));
        let _ = std::fs::remove_file(&rdv_file);
        let rdv = format!("file:{}", rdv_file.display());
        let children: Vec<_> = (0..2)
            .map(|r| {
                Command::new(env!("CARGO_BIN_EXE_rtmpm"))
                    .args(["run", s, "--frames", &f, "--out", ranks.to_str().unwrap()])
                    .args([
                        "--rendezvous",
                        &rdv,
                        "--nccl-ranks",
                        "2",
                        "--nccl-rank",
                        &r.to_string(),
                    ])
                    .env("RTMPM_RENDEZVOUS_TIMEOUT", "120")
                    .spawn()
                    .expect("rtmpm starts")
            })
            .collect();
        for c in children {
            let o = c.wait_with_output().expect("rank finishes");
            assert!(o.status.success(), "a rank failed on {name}");
        }
        let a = last_frame(&one, frames, &scene);
        for (label, d) in [("--gpus 2", &two), ("2 processes", &ranks)] {
            if !agree(
                &format!("{name} {label}"),
                scene.dx,
                &a,
                &last_frame(d, frames, &scene),
            ) {
                failures.push(format!("{name} {label}"));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// One row of `bodies.csv`: frame, body, position, rotation (x, y, z, w), velocity, angular
/// velocity.
struct BodyRow {
    frame: u64,
    body: String,
    position: [f64; 3],
    rotation: [f64; 4],
    velocity: [f64; 3],
    omega: [f64; 3],
}

fn bodies_csv(dir: &Path) -> Vec<BodyRow> {
    let path = dir.join("bodies.csv");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.lines()
        .skip(1)
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            assert_eq!(c.len(), 16, "{}: {l}", path.display());
            let f = |i: usize| c[i].parse::<f64>().unwrap_or_else(|e| panic!("{l}: {e}"));
            BodyRow {
                frame: c[0].parse().expect("frame"),
                body: c[2].to_string(),
                position: [f(3), f(4), f(5)],
                rotation: [f(6), f(7), f(8), f(9)],
                velocity: [f(10), f(11), f(12)],
                omega: [f(13), f(14), f(15)],
            }
        })
        .collect()
}

fn dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

fn norm(a: &[f64]) -> f64 {
    dist(a, &[0.0; 3])
}

/// Two processes (one GPU each, `--rendezvous`) couple the rigid bodies as one GPU does, on
/// every scene of `scenes/rigid/` for `RTMPM_MULTI_GPU_RIGID_FRAMES` frames (default 15: 0.5 s,
/// the ball falls into the sand, the dam breaks onto the gate, the bodies float), heavy_ball
/// also with `rigid_overlap=off`: every body of the last row of `bodies.csv` against one GPU's
/// with the tolerances of rtmpm-cuda's `several_gpus_agree_with_one_on_the_rigid_scenes`
/// (position and rotation at its farthest point within 0.1 dx, velocity and angular velocity
/// within 10 % of the largest the body reached in the one-GPU run plus 1 mm/s and 0.01 rad/s),
/// the particles of the last frame as the agreement test. Only rank 0 writes: rank 1, given
/// its own output folder, leaves it without bodies.csv or frames. Both runs step by the CFL
/// condition (the step sizes may differ in their last bits between them).
#[test]
#[ignore = "needs 2 CUDA GPUs and NCCL"]
fn two_processes_agree_with_one_gpu_on_the_rigid_scenes() {
    let found = rtmpm_cuda::device_count();
    if found < 2 {
        println!(
            "skipped: 2 CUDA GPUs needed (NCCL refuses two ranks on one device), {found} found"
        );
        return;
    }
    if let Err(e) = rtmpm_cuda::nccl::library() {
        println!("skipped: NCCL not usable ({e})");
        return;
    }
    let frames: u64 = std::env::var("RTMPM_MULTI_GPU_RIGID_FRAMES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(15);
    let f = frames.to_string();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/rigid");
    let mut paths: Vec<_> = std::fs::read_dir(dir)
        .expect("scenes/rigid/")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    paths.sort();
    let mut failures = Vec::new();
    for path in paths {
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        let scene = Scene::from_file(&path).expect("scene");
        let dx = scene.dx as f64;
        let s = path.to_str().unwrap();
        let variants: &[&str] = if name == "heavy_ball" {
            &["", "rigid_overlap=off"]
        } else {
            &[""]
        };
        for (v, variant) in variants.iter().enumerate() {
            let label = format!("{name} [{variant}]");
            let dir = scratch(&format!("mgpu_rigid_{name}_{v}"));
            let (one, ranks, rank1) = (dir.join("one"), dir.join("ranks"), dir.join("rank1"));
            let o = rtmpm(&[
                "run",
                s,
                "--backend",
                "cuda",
                "--frames",
                &f,
                "--out",
                one.to_str().unwrap(),
                "--cuda-options",
                variant,
            ]);
            assert!(o.status.success(), "{label}: {}", text(&o));
            let rdv_file = dir.join("rendezvous");
            let rdv = format!("file:{}", rdv_file.display());
            let children: Vec<_> = [&ranks, &rank1]
                .iter()
                .enumerate()
                .map(|(r, out)| {
                    Command::new(env!("CARGO_BIN_EXE_rtmpm"))
                        .args(["run", s, "--frames", &f, "--out", out.to_str().unwrap()])
                        .args(["--cuda-options", variant])
                        .args([
                            "--rendezvous",
                            &rdv,
                            "--nccl-ranks",
                            "2",
                            "--nccl-rank",
                            &r.to_string(),
                        ])
                        .env("RTMPM_RENDEZVOUS_TIMEOUT", "120")
                        .stdout(std::process::Stdio::piped())
                        .stderr(std::process::Stdio::piped())
                        .spawn()
                        .expect("rtmpm starts")
                })
                .collect();
            for (r, c) in children.into_iter().enumerate() {
                let o = c.wait_with_output().expect("rank finishes");
                assert!(o.status.success(), "{label}: rank {r} failed: {}", text(&o));
                if r == 0 {
                    assert!(text(&o).contains("cuda rank 0/2"), "{label}: {}", text(&o));
                }
            }
            // Rank 1 wrote nothing; rank 0 a row per body and frame, as one GPU.
            let left: Vec<_> = std::fs::read_dir(&rank1)
                .map(|d| d.filter_map(|e| e.ok().map(|e| e.file_name())).collect())
                .unwrap_or_default();
            assert!(left.is_empty(), "{label}: rank 1 wrote {left:?}");
            let (a, b) = (bodies_csv(&one), bodies_csv(&ranks));
            let bodies = scene.rigid_bodies.len();
            assert_eq!(a.len(), (frames as usize + 1) * bodies, "{label}");
            assert_eq!(b.len(), a.len(), "{label}");
            for (k, spec) in scene.rigid_bodies.iter().enumerate() {
                let mine = |rows: &[BodyRow]| -> Vec<usize> {
                    (0..rows.len()).filter(|&i| i % bodies == k).collect()
                };
                let rows_a = mine(&a);
                let vmax = rows_a
                    .iter()
                    .map(|&i| norm(&a[i].velocity))
                    .fold(0.0, f64::max);
                let wmax = rows_a
                    .iter()
                    .map(|&i| norm(&a[i].omega))
                    .fold(0.0, f64::max);
                let (x, y) = (&a[rows_a[rows_a.len() - 1]], &b[mine(&b)[rows_a.len() - 1]]);
                assert_eq!((x.frame, &x.body), (frames, &y.body), "{label}");
                assert_eq!(y.frame, frames, "{label}");
                let r = spec.shape.bounding_radius() as f64;
                let dot: f64 = x.rotation.iter().zip(&y.rotation).map(|(p, q)| p * q).sum();
                let drot = 2.0 * dot.abs().min(1.0).acos() * r;
                let dpos = dist(&x.position, &y.position);
                let dv = dist(&x.velocity, &y.velocity);
                let dw = dist(&x.omega, &y.omega);
                println!(
                    "{label} 2 processes: body {k} ({}) at frame {frames}: |d position| {:.4} dx, \
                     rotation {:.4} dx at its farthest point, |d v| {dv:.3e} m/s (peak \
                     {vmax:.3}), |d omega| {dw:.3e} rad/s (peak {wmax:.3})",
                    x.body,
                    dpos / dx,
                    drot / dx
                );
                if dpos > 0.1 * dx
                    || drot > 0.1 * dx
                    // 10 %: one GPU run twice differs by up to 4.6 % of the peak angular
                    // speed on floating_box (rtmpm-cuda tests/multi_gpu_rigid.rs, VELOCITY_SHARE).
                    || dv > 0.10 * vmax + 1e-3
                    || dw > 0.10 * wmax + 1e-2
                {
                    failures.push(format!("{label}: body {k} differs"));
                }
                if name == "heavy_ball" {
                    assert!(vmax > 0.5, "{label}: the ball never fell ({vmax})");
                }
            }
            let pa = last_frame(&one, frames, &scene);
            if !agree(
                &format!("{label} 2 processes"),
                scene.dx,
                &pa,
                &last_frame(&ranks, frames, &scene),
            ) {
                failures.push(format!("{label}: particles differ"));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn bad_multi_gpu_options_are_clear_errors() {
    let scene = format!("{}/../../scenes/dam_break.toml", env!("CARGO_MANIFEST_DIR"));
    for (args, want) in [
        (vec!["--gpus", "zero"], "expected a number of GPUs"),
        (
            vec!["--gpus", "2", "--backend", "cpu"],
            "need the CUDA backend",
        ),
        (vec!["--nccl-rank", "0"], "need --rendezvous"),
        (vec!["--rendezvous", "udp://x:1"], "tcp://HOST:PORT"),
        (
            vec![
                "--rendezvous",
                "tcp://127.0.0.1:1",
                "--nccl-rank",
                "3",
                "--nccl-ranks",
                "2",
            ],
            "must be in 0..2",
        ),
    ] {
        let mut a = vec!["run", scene.as_str(), "--no-output", "--frames", "1"];
        a.extend(args.iter());
        let o = rtmpm(&a);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(text(&o).contains(want), "{args:?}: {}", text(&o));
    }
}
