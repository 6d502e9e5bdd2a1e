//! End-to-end tests of `rtmpm run` of a scene with `[batch]`: what it refuses, and why.

mod common;

use common::{data, rtmpm, scratch, text};

/// `rtmpm run tiny_wedge.toml` with `extra` arguments, into a scratch folder `name`.
fn run_wedge(name: &str, extra: &[&str]) -> std::process::Output {
    let out = scratch(name).join("out");
    let mut args = vec![
        "run".to_string(),
        data("tiny_wedge.toml"),
        "--backend".into(),
        "cpu".into(),
        "--out".into(),
        out.display().to_string(),
    ];
    args.extend(extra.iter().map(|s| s.to_string()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    rtmpm(&args)
}

#[test]
fn precision_of_a_batch_is_refused_with_the_scene_setting() {
    let o = run_wedge("batch-precision", &["--precision", "f64", "--frames", "1"]);
    assert!(!o.status.success(), "{}", text(&o));
    let t = text(&o);
    assert!(t.contains("--precision f64"), "{t}");
    assert!(t.contains("precision = \"f64\""), "{t}");
    assert!(t.contains("[solver]"), "{t}");
}

#[test]
fn checkpoints_of_a_batch_on_the_command_line_name_the_route_that_works() {
    let o = run_wedge(
        "batch-ckpt-every",
        &["--checkpoint-every", "1", "--frames", "1"],
    );
    assert!(!o.status.success(), "{}", text(&o));
    let t = text(&o);
    assert!(t.contains("--checkpoint-every 1"), "{t}");
    assert!(t.contains("BatchSimulation.resume"), "{t}");
    assert!(t.contains("BatchRun::checkpoint"), "{t}");
    assert!(!t.contains("--precision"), "{t}");
    let o = run_wedge("batch-resume", &["--resume", "ckpt_dir"]);
    assert!(!o.status.success(), "{}", text(&o));
    let t = text(&o);
    assert!(t.contains("--resume ckpt_dir"), "{t}");
    assert!(t.contains("BatchSimulation.resume"), "{t}");
    assert!(!t.contains("--precision"), "{t}");
}
