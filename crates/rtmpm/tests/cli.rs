//! End-to-end tests of the `rtmpm` command line.

mod common;

use common::{data, rtmpm, scratch, text};

#[test]
fn run_writes_frames_and_resume_is_bit_identical() {
    let dir = scratch("resume");
    let (a, b) = (dir.join("a"), dir.join("b"));
    let full = rtmpm(&[
        "run",
        &data("small_drop.toml"),
        "--backend",
        "cpu",
        "--out",
        a.to_str().unwrap(),
        "--checkpoint-every",
        "2",
    ]);
    assert!(full.status.success(), "{}", text(&full));
    let summary = text(&full);
    assert!(
        summary.contains("particles") && summary.contains("particle-steps/s"),
        "{summary}"
    );
    for f in [
        "frame_00000.ply",
        "frame_00004.ply",
        "frame_00004.vtu",
        "frames.pvd",
        "checkpoint_00002.ckpt",
    ] {
        assert!(a.join(f).exists(), "{f} missing");
    }
    // No temporary files are left behind.
    for e in std::fs::read_dir(&a).unwrap() {
        let name = e.unwrap().file_name().into_string().unwrap();
        assert!(!name.contains(".tmp"), "leftover {name}");
    }
    let ckpt = a.join("checkpoint_00002.ckpt");
    let resumed = rtmpm(&[
        "run",
        "--resume",
        ckpt.to_str().unwrap(),
        "--backend",
        "cpu",
        "--out",
        b.to_str().unwrap(),
    ]);
    assert!(resumed.status.success(), "{}", text(&resumed));
    assert!(
        !b.join("frame_00002.ply").exists(),
        "resume starts after the checkpoint's frame"
    );
    for f in ["frame_00003.ply", "frame_00004.ply", "frame_00004.vtu"] {
        let (x, y) = (
            std::fs::read(a.join(f)).unwrap(),
            std::fs::read(b.join(f)).unwrap(),
        );
        assert!(x == y, "{f} differs after resume");
    }
}

#[test]
fn bad_scene_is_a_clear_error_not_a_panic() {
    let dir = scratch("bad");
    let good = std::fs::read_to_string(data("small_drop.toml")).unwrap();
    let cases = [
        (
            good.replace("poisson_ratio = 0.3", "poisson_ratio = 0.5"),
            "poisson_ratio",
        ),
        (good.replace("dx = 0.03125", "dx = -0.03125"), "dx"),
        (
            good.replace("density = 1000.0\nyoungs", "density = -5.0\nyoungs"),
            "density",
        ),
        (good.replace("radius = 0.06", "radius = 0.6"), "outside"),
        (good.replace("[time]", "[time\n"), "toml:10:6"),
        (good.replace("gamma = 7.0", "gama = 7.0"), "gama"),
    ];
    for (i, (scene, needle)) in cases.iter().enumerate() {
        let path = dir.join(format!("bad{i}.toml"));
        std::fs::write(&path, scene).unwrap();
        for cmd in ["check", "run"] {
            let o = rtmpm(
                &[cmd, path.to_str().unwrap(), "--backend", "cpu"]
                    [..if cmd == "check" { 2 } else { 4 }],
            );
            let t = text(&o);
            assert!(!o.status.success(), "case {i} ({needle}) accepted by {cmd}");
            assert!(
                t.contains(needle),
                "case {i}: message does not name `{needle}`:\n{t}"
            );
            assert!(
                t.contains(&format!("bad{i}.toml:")),
                "case {i}: no file:line in\n{t}"
            );
            assert!(!t.contains("panicked"), "case {i} panicked:\n{t}");
        }
    }
    let o = rtmpm(&["check", "/nonexistent/scene.toml"]);
    assert!(
        !o.status.success() && text(&o).contains("/nonexistent/scene.toml"),
        "{}",
        text(&o)
    );
}

#[test]
fn blowup_stops_with_particle_material_and_advice() {
    let dir = scratch("blowup");
    let good = std::fs::read_to_string(data("small_drop.toml")).unwrap();
    // A stiff material with a huge fixed step explodes.
    let scene = good
        .replace("cfl = 0.4\nmax_dt = 2e-3", "dt = 5e-3")
        .replace("youngs_modulus = 2.0e4", "youngs_modulus = 2.0e9");
    let path = dir.join("explode.toml");
    std::fs::write(&path, scene).unwrap();
    let o = rtmpm(&[
        "run",
        path.to_str().unwrap(),
        "--backend",
        "cpu",
        "--no-output",
    ]);
    let t = text(&o);
    assert!(!o.status.success(), "explosion not detected:\n{t}");
    assert!(
        t.contains("blew up") && t.contains("particle") && t.contains("jelly"),
        "{t}"
    );
    assert!(t.contains("smaller time step"), "{t}");
}

#[test]
fn info_and_auto_backend_work_without_a_gpu() {
    let o = rtmpm(&["info"]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("cpu"), "{}", text(&o));
    let o = rtmpm(&[
        "run",
        &data("small_drop.toml"),
        "--backend",
        "auto",
        "--frames",
        "1",
        "--no-output",
    ]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(
        t.contains("backend: auto ->"),
        "auto does not say what it picked:\n{t}"
    );
    let o = rtmpm(&[
        "run",
        &data("small_drop.toml"),
        "--backend",
        "cuda",
        "--frames",
        "1",
        "--no-output",
    ]);
    let t = text(&o);
    assert!(!t.contains("panicked"), "{t}");
    if !o.status.success() {
        assert!(
            t.contains("CUDA") && t.contains("--backend cpu"),
            "unclear message without a GPU:\n{t}"
        );
    }
}

#[test]
fn steps_limit_stops_early() {
    let o = rtmpm(&[
        "run",
        &data("small_drop.toml"),
        "--backend",
        "cpu",
        "--steps",
        "3",
        "--no-output",
    ]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains("steps        3"), "{t}");
}

/// An unknown `--cuda-options` switch, among them the kernel experiments removed after they lost
/// on an H200 (`halo`, `warp_list`, `cluster`: bench/RESULTS.md), is refused before anything runs,
/// with the option named, in every command that takes the switches.
#[test]
fn unknown_cuda_options_are_clear_errors() {
    for (option, key) in [
        ("bogus=1", "bogus"),
        ("halo=async", "halo"),
        ("warp_list=sorted", "warp_list"),
        ("cluster=2", "cluster"),
    ] {
        for cmd in ["run", "bench"] {
            let scene = data("small_drop.toml");
            let args: &[&str] = if cmd == "run" {
                &["run", &scene, "--cuda-options", option, "--no-output"]
            } else {
                &["bench", "--scene", &scene, "--cuda-options", option]
            };
            let o = rtmpm(args);
            let t = text(&o);
            assert!(!o.status.success(), "{cmd} accepted {option}:\n{t}");
            assert!(
                t.contains(&format!("unknown CUDA option `{key}`")),
                "{cmd} {option}: message does not name `{key}`:\n{t}"
            );
            assert!(!t.contains("panicked"), "{cmd} {option} panicked:\n{t}");
        }
    }
}

#[test]
fn precision_flag_selects_the_f64_backend() {
    let dir = scratch("precision");
    let run = rtmpm(&[
        "run",
        &data("small_drop.toml"),
        "--backend",
        "cpu",
        "--precision",
        "f64",
        "--frames",
        "1",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(run.status.success(), "{}", text(&run));
    assert!(text(&run).contains("threads, f64)"), "{}", text(&run));
    let bad = rtmpm(&["run", &data("small_drop.toml"), "--precision", "f16"]);
    assert!(!bad.status.success());
    assert!(text(&bad).contains("expected f32 or f64"), "{}", text(&bad));
}

#[test]
fn bench_on_the_cpu_reports_its_measurements() {
    let dir = scratch("bench-cpu");
    let frames = dir.join("frames");
    let o = rtmpm(&[
        "bench",
        "--backend",
        "cpu",
        "--n",
        "20",
        "--steps",
        "4",
        "--warmup",
        "1",
        "--frame-write",
        frames.to_str().unwrap(),
    ]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    let lines: Vec<&str> = stdout.lines().collect();
    // The report's lines, in order: n = 20 gives 20^3 / 4 particles.
    let want = [
        "benchmark: MLS-MPM fluid block, n = 20 (dx = 1/20), dt = 2e-4, 4 steps",
        "  backend      cpu",
        "  particles    2000",
        "  set-up       ",
        "  steps        4 timed after 1 warm-up",
        "  wall time    ",
        "  throughput   ",
        "  stage        rebuild",
        "  stage        p2g",
        "  stage        grid_update",
        "  stage        g2p",
        "  memory       host ",
        "  frame write  ply into ",
        "    copy out   ",
        "    write      ",
        "    steps      ",
    ];
    let mut at = 0;
    for w in want {
        let Some(i) = lines[at..].iter().position(|l| l.starts_with(w)) else {
            panic!("no line `{w}` after line {at} in:\n{t}");
        };
        at += i + 1;
    }
    // The throughput is the particles' steps over the wall time it printed.
    let number = |prefix: &str, unit: &str| -> f64 {
        let l = lines.iter().find(|l| l.starts_with(prefix)).unwrap();
        let s = l.rsplit_once('(').unwrap().1;
        s.split(unit).next().unwrap().trim().parse().unwrap()
    };
    let ms = number("  wall time", "ms/step");
    let rate = number("  throughput", "particle-steps/s");
    let expect = 2000.0 / (ms * 1e-3);
    assert!(
        (rate / expect - 1.0).abs() < 0.01,
        "{rate} vs 2000 particles / {ms} ms\n{t}"
    );

    // Bad requests are refused with the reason.
    let o = rtmpm(&["bench", "--backend", "cpu", "--n", "10"]);
    assert!(!o.status.success());
    assert!(text(&o).contains("--n 10 is out of range"), "{}", text(&o));
    let o = rtmpm(&[
        "bench",
        "--backend",
        "cpu",
        "--scene",
        &data("small_drop.toml"),
    ]);
    assert!(!o.status.success());
    assert!(text(&o).contains("fixed time step"), "{}", text(&o));
}
