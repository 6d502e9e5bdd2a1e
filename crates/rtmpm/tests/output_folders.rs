//! Output folders are protected: one run at a time, one run per folder, nothing of
//! another run lost or mixed, stale temporary files cleaned, `render` never mixes two runs.

mod common;

use common::{data, rtmpm, scratch, text};
use std::fs;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn run_into(out: &Path, extra: &[&str]) -> std::process::Output {
    let scene = data("small_drop.toml");
    let mut args = vec!["run"];
    if !extra.contains(&"--resume") {
        args.push(&scene);
    }
    args.extend(["--backend", "cpu", "--out", out.to_str().unwrap()]);
    args.extend_from_slice(extra);
    rtmpm(&args)
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    v.sort();
    v
}

#[test]
fn second_run_into_a_used_folder_is_refused_and_overwrite_clears_only_run_files() {
    let dir = scratch("used-folder");
    let out = dir.join("out");
    let first = run_into(&out, &["--frames", "4"]);
    assert!(first.status.success(), "{}", text(&first));
    assert!(out.join("frame_00004.ply").exists());
    fs::write(out.join("notes.txt"), "mine").unwrap();

    // A fresh run into it: refused, nothing touched.
    let before = names(&out);
    let second = run_into(&out, &["--frames", "2"]);
    assert!(!second.status.success());
    let msg = text(&second);
    assert!(
        msg.contains("already holds the files of a run") && msg.contains("--overwrite"),
        "{msg}"
    );
    assert_eq!(names(&out), before);

    // --overwrite: the old run's frames are gone (no frame 3 or 4 left to mix with), the
    // user's own file is kept.
    let third = run_into(&out, &["--frames", "2", "--overwrite"]);
    assert!(third.status.success(), "{}", text(&third));
    assert!(out.join("frame_00002.ply").exists());
    assert!(!out.join("frame_00003.ply").exists() && !out.join("frame_00004.vtu").exists());
    assert_eq!(fs::read_to_string(out.join("notes.txt")).unwrap(), "mine");
}

#[test]
fn a_locked_folder_is_refused_while_its_run_goes_on() {
    let dir = scratch("locked-folder");
    let out = dir.join("out");
    let mut long = Command::new(env!("CARGO_BIN_EXE_rtmpm"))
        .args([
            "run",
            &data("small_drop.toml"),
            "--backend",
            "cpu",
            "--threads",
            "1",
            "--frames",
            "100000",
            "--no-output",
            "--checkpoint-every",
            "100000",
            "--out",
            out.to_str().unwrap(),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Wait until it holds the lock (its pid is in the lock file).
    let lock = out.join(".rtmpm.lock");
    let t = Instant::now();
    while !fs::read_to_string(&lock).is_ok_and(|s| s.contains(&long.id().to_string())) {
        assert!(
            t.elapsed() < Duration::from_secs(60),
            "the first run never locked"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let second = run_into(&out, &["--frames", "1", "--overwrite"]);
    let render = rtmpm(&["render", out.to_str().unwrap()]);
    long.kill().unwrap();
    long.wait().unwrap();
    assert!(!second.status.success());
    let msg = text(&second);
    assert!(msg.contains("in use by another rtmpm process"), "{msg}");
    assert!(msg.contains(&format!("pid {}", long.id())), "{msg}");
    assert!(text(&render).contains("in use"), "{}", text(&render));
    // Killed: the lock went with the process; the folder is usable again.
    let after = run_into(&out, &["--frames", "1", "--overwrite"]);
    assert!(after.status.success(), "{}", text(&after));
}

#[test]
fn resume_in_place_keeps_earlier_frames_and_refuses_a_bad_pvd() {
    let dir = scratch("resume-in-place");
    let out = dir.join("out");
    let first = run_into(&out, &["--checkpoint-every", "2"]);
    assert!(first.status.success(), "{}", text(&first));
    let frame1 = fs::read(out.join("frame_00001.ply")).unwrap();
    let frame4 = fs::read(out.join("frame_00004.ply")).unwrap();
    // A killed run leaves a temporary file; the next run into the folder removes it.
    fs::write(out.join(".frame_00005.ply.tmp-999999"), "partial").unwrap();
    let ckpt = out.join("checkpoint_00002.ckpt");
    let resumed = run_into(&out, &["--resume", ckpt.to_str().unwrap()]);
    assert!(resumed.status.success(), "{}", text(&resumed));
    assert!(!out.join(".frame_00005.ply.tmp-999999").exists());
    // Frames before the checkpoint are untouched, later ones written again (bit-identical on
    // the CPU), and frames.pvd still lists all five.
    assert_eq!(fs::read(out.join("frame_00001.ply")).unwrap(), frame1);
    assert_eq!(fs::read(out.join("frame_00004.ply")).unwrap(), frame4);
    let pvd = fs::read_to_string(out.join("frames.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet").count(), 5, "{pvd}");

    // An unparsable frames.pvd is an error on resume, and is left as it was.
    fs::write(out.join("frames.pvd"), "garbage").unwrap();
    let bad = run_into(&out, &["--resume", ckpt.to_str().unwrap()]);
    assert!(!bad.status.success());
    assert!(text(&bad).contains("frames.pvd"), "{}", text(&bad));
    assert_eq!(
        fs::read_to_string(out.join("frames.pvd")).unwrap(),
        "garbage"
    );

    // Resuming a checkpoint of another scene into this folder is refused.
    let other = dir.join("other");
    let scene = fs::read_to_string(data("small_drop.toml"))
        .unwrap()
        .replace("velocity = [0.5, 0.0, 0.0]", "velocity = [0.4, 0.0, 0.0]");
    fs::write(dir.join("other.toml"), scene).unwrap();
    let o = rtmpm(&[
        "run",
        dir.join("other.toml").to_str().unwrap(),
        "--backend",
        "cpu",
        "--frames",
        "2",
        "--checkpoint-every",
        "2",
        "--out",
        other.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let foreign = run_into(
        &out,
        &[
            "--resume",
            other.join("checkpoint_00002.ckpt").to_str().unwrap(),
        ],
    );
    assert!(!foreign.status.success());
    assert!(text(&foreign).contains("another run"), "{}", text(&foreign));
    assert_eq!(fs::read(out.join("frame_00004.ply")).unwrap(), frame4);
}

#[test]
fn render_refuses_frames_of_two_runs() {
    let dir = scratch("render-two-runs");
    let (a, b) = (dir.join("a"), dir.join("b"));
    assert!(run_into(&a, &["--frames", "2"]).status.success());
    let scene = fs::read_to_string(data("small_drop.toml"))
        .unwrap()
        .replace("radius = 0.06", "radius = 0.07");
    fs::write(dir.join("b.toml"), scene).unwrap();
    let o = rtmpm(&[
        "run",
        dir.join("b.toml").to_str().unwrap(),
        "--backend",
        "cpu",
        "--frames",
        "4",
        "--out",
        b.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    // Copied by hand: frames 3 and 4 of run b next to frames 0-2 of run a.
    for f in ["frame_00003.ply", "frame_00004.ply"] {
        fs::copy(b.join(f), a.join(f)).unwrap();
    }
    let r = rtmpm(&[
        "render",
        a.to_str().unwrap(),
        "--size",
        "64x36",
        "--no-movie",
    ]);
    assert!(!r.status.success());
    assert!(text(&r).contains("frames of two runs"), "{}", text(&r));
}
