//! The command line with rigid bodies and emitters: `rtmpm validate` runs the rigid-body and emitter checks
//! (or says which feature they need), and checkpoints resume the rigid bodies.

mod common;

use common::{rtmpm, scratch, text};

fn scenes() -> String {
    concat!(env!("CARGO_MANIFEST_DIR"), "/../../validation").to_string()
}

/// The emitter case needs no feature; without `rigid` the rigid cases name the feature and how
/// to build it, and `rtmpm validate` without `--case` skips them with that message.
#[test]
fn validate_runs_the_emitter_case_and_names_the_rigid_feature() {
    let dir = scratch("validate-emitter");
    let o = rtmpm(&[
        "validate",
        "--backend",
        "cpu",
        "--quick",
        "--case",
        "emitter_mass",
        "--scenes",
        &scenes(),
        "--out",
        dir.to_str().unwrap(),
    ]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains("emitter_mass") && t.contains("PASS"), "{t}");
    if cfg!(feature = "rigid") {
        return;
    }
    let o = rtmpm(&[
        "validate",
        "--backend",
        "cpu",
        "--quick",
        "--case",
        "sinking,emitter_mass",
        "--scenes",
        &scenes(),
        "--out",
        dir.to_str().unwrap(),
    ]);
    let t = text(&o);
    assert!(!o.status.success(), "{t}");
    assert!(
        t.contains("case sinking could not run") && t.contains("--features rigid"),
        "{t}"
    );
    // The other case still ran and passed.
    assert!(t.contains("emitter_mass") && t.contains("PASS"), "{t}");
    assert!(!t.contains("panicked"), "{t}");
}

/// `rtmpm validate --quick --case rigid_momentum` passes on the CPU (the quickest rigid case).
#[cfg(feature = "rigid")]
#[test]
fn validate_runs_the_rigid_momentum_case() {
    let dir = scratch("validate-momentum");
    let o = rtmpm(&[
        "validate",
        "--backend",
        "cpu",
        "--quick",
        "--case",
        "rigid_momentum",
        "--scenes",
        &scenes(),
        "--out",
        dir.to_str().unwrap(),
    ]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert_eq!(t.matches("PASS").count(), 2, "{t}");
}

/// A floating box checkpointed at frame 2 and resumed: frames 3 and 4 (particles and the rows of
/// bodies.csv) are bit-identical to the uninterrupted run's, and resuming into the run's own
/// folder keeps the rows up to the checkpoint and rewrites the later ones identically.
#[cfg(feature = "rigid")]
#[test]
fn checkpoints_resume_rigid_bodies_bit_for_bit() {
    let dir = scratch("rigid-resume");
    let scene = std::fs::read_to_string(format!("{}/archimedes.toml", scenes()))
        .unwrap()
        .replace("formats = []", "formats = [\"ply\"]");
    let path = dir.join("archimedes.toml");
    std::fs::write(&path, scene).unwrap();
    let (a, b) = (dir.join("a"), dir.join("b"));
    let run = |extra: &[&str], out: &std::path::Path| {
        let mut args = vec!["run", "--backend", "cpu", "--frames", "4"];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["--out", out.to_str().unwrap()]);
        let o = rtmpm(&args);
        assert!(o.status.success(), "{}", text(&o));
    };
    run(&[path.to_str().unwrap(), "--checkpoint-every", "2"], &a);
    let csv = |d: &std::path::Path| std::fs::read_to_string(d.join("bodies.csv")).unwrap();
    let full = csv(&a);
    assert_eq!(full.lines().count(), 1 + 5, "{full}");
    let ckpt = a.join("checkpoint_00002.ckpt");
    run(&["--resume", ckpt.to_str().unwrap()], &b);
    let later = |t: &str| -> Vec<String> {
        t.lines()
            .filter(|l| l.starts_with("3,") || l.starts_with("4,"))
            .map(str::to_string)
            .collect()
    };
    assert_eq!(later(&csv(&b)).len(), 2);
    assert_eq!(later(&csv(&b)), later(&full));
    assert_eq!(
        std::fs::read(a.join("frame_00004.ply")).unwrap(),
        std::fs::read(b.join("frame_00004.ply")).unwrap()
    );
    // Into the same folder: the file is the uninterrupted run's again.
    run(&["--resume", ckpt.to_str().unwrap()], &a);
    assert_eq!(csv(&a), full);
}
