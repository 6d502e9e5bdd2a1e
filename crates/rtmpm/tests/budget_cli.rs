//! The budget before the run: `check` and `run` refuse what cannot fit, with the
//! numbers and a fix, before sampling; absurd steps and frames are refused or warned about;
//! progress lines appear when stderr is not a terminal.

mod common;

use common::{data, rtmpm, scratch, text};
use std::fs;
use std::time::Instant;

fn scene_with(dir: &std::path::Path, from: &str, to: &str) -> String {
    let s = fs::read_to_string(data("small_drop.toml")).unwrap();
    assert!(s.contains(from), "{from}");
    let path = dir.join("scene.toml");
    fs::write(&path, s.replace(from, to)).unwrap();
    path.display().to_string()
}

#[test]
fn five_huge_bodies_are_refused_before_sampling() {
    let dir = scratch("budget-huge");
    let mut bodies = String::new();
    for i in 0..5 {
        let z = 0.05 + 0.75 * i as f32;
        bodies.push_str(&format!(
            "[[body]]\nmaterial = \"water\"\nshape = \"box\"\nmin = [0.05, 0.05, {z}]\n\
             max = [3.9, 3.9, {}]\n",
            z + 0.34
        ));
    }
    let scene = scene_with(
        &dir,
        "max = [0.5, 0.5, 0.5]\ndx = 0.03125",
        "max = [4.0, 4.0, 4.0]\ndx = 0.01",
    );
    fs::write(&scene, fs::read_to_string(&scene).unwrap() + &bodies).unwrap();
    for cmd in ["check", "run"] {
        let t = Instant::now();
        // 8 GiB of address space (ulimit -v), whatever the machine has: the budget reads it.
        let args = if cmd == "check" {
            ""
        } else {
            " --backend cpu --no-output"
        };
        let o = std::process::Command::new("sh")
            .arg("-c")
            .arg(format!(
                "ulimit -v 8388608 && exec '{}' {cmd} '{scene}'{args}",
                env!("CARGO_BIN_EXE_rtmpm")
            ))
            .output()
            .unwrap();
        assert!(!o.status.success());
        let msg = text(&o);
        assert!(
            msg.contains("does not fit this machine")
                && msg.contains("memory")
                && msg.contains("fix:"),
            "{msg}"
        );
        assert!(t.elapsed().as_secs_f64() < 20.0, "{cmd} sampled first?");
    }
}

#[test]
fn absurd_steps_and_frames_are_refused_with_the_fix() {
    let dir = scratch("budget-absurd");
    let scene = scene_with(&dir, "cfl = 0.4\nmax_dt = 2e-3", "dt = 1e-12");
    let o = rtmpm(&["check", &scene]);
    assert!(!o.status.success());
    let msg = text(&o);
    assert!(msg.contains("steps") && msg.contains("time.dt"), "{msg}");
    let scene = scene_with(&dir, "duration = 0.1", "duration = 1e9");
    let o = rtmpm(&["run", &scene, "--backend", "cpu", "--no-output"]);
    assert!(!o.status.success());
    assert!(text(&o).contains("frames is more than"), "{}", text(&o));
    // check prints the budget of a scene that fits.
    let o = rtmpm(&["check", &data("small_drop.toml")]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("budget") && text(&o).contains("on the host"),
        "{}",
        text(&o)
    );
}

#[test]
fn progress_lines_when_stderr_is_not_a_terminal() {
    let out = scratch("progress");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_rtmpm"))
        .args([
            "run",
            &data("small_drop.toml"),
            "--backend",
            "cpu",
            "--no-output",
        ])
        .arg("--out")
        .arg(&out)
        .env("RTMPM_PROGRESS_SECONDS", "0")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    let line = err
        .lines()
        .find(|l| l.starts_with("progress: frame"))
        .unwrap_or_else(|| panic!("no progress line: {err}"));
    for part in ["t = ", "dt = ", "step ", "particle-steps/s"] {
        assert!(line.contains(part), "{line}");
    }
}
