//! End-to-end tests of `rtmpm run` of a scene with `[batch]`: what it refuses, and why.

mod common;

use common::{data, rtmpm, scratch, text};
use std::collections::BTreeMap;
use std::path::Path;

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

/// `rtmpm run SCENE --backend cpu --out OUT` with `extra` arguments, which must succeed.
fn run_ok(scene: &str, out: &Path, extra: &[&str]) -> String {
    let mut args = vec![
        "run",
        scene,
        "--backend",
        "cpu",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = rtmpm(&args);
    assert!(o.status.success(), "{args:?}:\n{}", text(&o));
    text(&o)
}

/// The files of `dir` and its folders (relative path, bytes), the lock file aside.
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut m = BTreeMap::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                todo.push(p);
            } else if !p.ends_with(".rtmpm.lock") {
                let rel = p.strip_prefix(dir).unwrap().display().to_string();
                m.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    m
}

#[test]
fn a_resumed_batch_run_equals_the_uninterrupted_one_bit_for_bit() {
    resumed_equals_uninterrupted(&scratch("batch-resume-bits"), &data("tiny_wedge.toml"));
}

#[test]
fn a_resumed_batch_with_a_frozen_world_equals_the_uninterrupted_one() {
    // World 3 thrown down at 1 km/s blows up in frame 1 and is frozen there; the checkpoint of
    // frame 2 keeps it frozen, and the resumed run leaves it so while the others go on.
    let dir = scratch("batch-resume-frozen");
    let text = std::fs::read_to_string(data("tiny_wedge.toml"))
        .unwrap()
        .replace("radius = 0.06", "radius = 0.06\nvelocity = [0.0, 0.0, 0.0]")
        + "\"body[0].velocity[1]\" = [0.0, 0.0, 0.0, -1000.0]\n";
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("frozen.toml");
    std::fs::write(&scene, text).unwrap();
    let a = resumed_equals_uninterrupted(&dir, scene.to_str().unwrap());
    let csv = String::from_utf8(a["batch.csv"].clone()).unwrap();
    assert!(csv.lines().nth(4).unwrap().contains("frozen"), "{csv}");
    assert!(!a.contains_key("world_003/frame_00001.ply"), "{csv}");
    let table = std::fs::read_to_string(dir.join("b/checkpoint_00002/batch.toml")).unwrap();
    assert!(table.contains("state = \"frozen\""), "{table}");
}

/// Run `scene` for 4 frames into `dir/a` and for 2 frames + a resume to 4 into `dir/b`; the
/// files of both (`a`'s returned) must be byte for byte the same.
fn resumed_equals_uninterrupted(dir: &Path, scene: &str) -> BTreeMap<String, Vec<u8>> {
    let scene = scene.to_string();
    let (a, b) = (dir.join("a"), dir.join("b"));
    // 4 frames at once, a checkpoint at the end; 2 frames with a checkpoint, then resumed to 4.
    run_ok(&scene, &a, &["--frames", "4", "--checkpoint-every", "4"]);
    run_ok(&scene, &b, &["--frames", "2", "--checkpoint-every", "2"]);
    let ckpt = b.join("checkpoint_00002");
    assert!(ckpt.join("batch.toml").is_file());
    assert!(ckpt.join("world_003.ckpt").is_file());
    let t = run_ok(
        &scene,
        &b,
        &[
            "--frames",
            "4",
            "--checkpoint-every",
            "4",
            "--resume",
            ckpt.to_str().unwrap(),
        ],
    );
    // It took up at frame 2: frames 3 and 4 stepped, not 1 and 2 again.
    assert!(t.contains("resuming the batch"), "{t}");
    assert!(t.contains("frame 3/4") && t.contains("frame 4/4"), "{t}");
    assert!(!t.contains("frame 1/4") && !t.contains("frame 2/4"), "{t}");
    let (fa, mut fb) = (files(&a), files(&b));
    // The resumed run's folder also holds the checkpoint it started from.
    fb.retain(|k, _| !k.starts_with("checkpoint_00002"));
    assert_eq!(
        fa.keys().collect::<Vec<_>>(),
        fb.keys().collect::<Vec<_>>(),
        "the same files"
    );
    // Every world's frames (positions, velocities, ...), frames.pvd, batch.csv, and the final
    // checkpoint of every world (its whole particle state, clock and step count).
    for (name, bytes) in &fa {
        assert!(fb[name] == *bytes, "{name} differs after the resume");
    }
    for w in 0..4 {
        assert!(fa.contains_key(&format!("checkpoint_00004/world_00{w}.ckpt")));
    }
    assert!(fa.contains_key("world_000/frame_00004.ply"));
    // The checkpoint is a real state: world 0 at frame 2 differs from world 0 at frame 4.
    assert_ne!(
        std::fs::read(ckpt.join("world_000.ckpt")).unwrap(),
        fa["checkpoint_00004/world_000.ckpt"]
    );
    fa
}

#[test]
fn a_batch_checkpoint_of_another_batch_or_damaged_is_refused_with_the_fix() {
    let dir = scratch("batch-resume-bad");
    let scene = data("tiny_wedge.toml");
    let out = dir.join("out");
    run_ok(&scene, &out, &["--frames", "1", "--checkpoint-every", "1"]);
    let ckpt = out.join("checkpoint_00001");
    let ck = ckpt.to_str().unwrap();
    // The folder run again afresh: refused, and the resume advised.
    let o = rtmpm(&[
        "run",
        &scene,
        "--backend",
        "cpu",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(
        text(&o).contains("--overwrite") && text(&o).contains(&format!("--resume {ck}")),
        "{}",
        text(&o)
    );
    let resume = |scene: &str, ckpt: &str, extra: &[&str]| {
        let o2 = dir.join("o2");
        let mut args = vec![
            "run",
            scene,
            "--backend",
            "cpu",
            "--out",
            o2.to_str().unwrap(),
        ];
        args.extend_from_slice(&["--overwrite", "--resume", ckpt]);
        args.extend_from_slice(extra);
        let o = rtmpm(&args);
        assert!(!o.status.success(), "{args:?} accepted:\n{}", text(&o));
        text(&o)
    };
    // Another batch count.
    let text4 = std::fs::read_to_string(&scene).unwrap();
    let two = dir.join("two.toml");
    std::fs::write(
        &two,
        text4
            .replace("count = 4", "count = 2")
            .replace("[0.14, 0.21, 0.29, 0.36]", "[0.14, 0.21]"),
    )
    .unwrap();
    let t = resume(two.to_str().unwrap(), ck, &[]);
    assert!(
        t.contains("count = 4") && t.contains("the batch has 2"),
        "{t}"
    );
    assert!(t.contains("fix:"), "{t}");
    // Another scene text (same count).
    let other = dir.join("other.toml");
    std::fs::write(&other, text4.replace("radius = 0.06", "radius = 0.05")).unwrap();
    let t = resume(other.to_str().unwrap(), ck, &[]);
    assert!(
        t.contains("another scene text") && t.contains("world_000.ckpt"),
        "{t}"
    );
    // A truncated world checkpoint: named.
    let cut = dir.join("cut");
    std::fs::create_dir_all(&cut).unwrap();
    for e in std::fs::read_dir(&ckpt).unwrap() {
        let p = e.unwrap().path();
        let mut bytes = std::fs::read(&p).unwrap();
        if p.ends_with("world_002.ckpt") {
            bytes.truncate(bytes.len() / 2);
        }
        std::fs::write(cut.join(p.file_name().unwrap()), bytes).unwrap();
    }
    let t = resume(&scene, cut.to_str().unwrap(), &[]);
    assert!(t.contains("world_002.ckpt"), "{t}");
    // A file, not a checkpoint folder.
    let t = resume(&scene, ckpt.join("world_000.ckpt").to_str().unwrap(), &[]);
    assert!(
        t.contains("not a folder") && t.contains("checkpoint_NNNNN"),
        "{t}"
    );
    // --backend cuda without a usable GPU: refused before anything runs, naming the CPU.
    let o = rtmpm(&[
        "run",
        &scene,
        "--backend",
        "cuda",
        "--no-output",
        "--resume",
        ck,
    ]);
    assert!(!o.status.success());
    assert!(text(&o).contains("--backend cpu"), "{}", text(&o));
    // Without the scene file.
    let o = rtmpm(&["run", "--resume", ck]);
    assert!(!o.status.success());
    assert!(
        text(&o).contains("rtmpm run SCENE --resume"),
        "{}",
        text(&o)
    );
    // --checkpoint-every 0 and with --no-output.
    let o = run_wedge("batch-ckpt-0", &["--checkpoint-every", "0"]);
    assert!(
        !o.status.success() && text(&o).contains("--checkpoint-every N"),
        "{}",
        text(&o)
    );
    let o = run_wedge(
        "batch-ckpt-noout",
        &["--checkpoint-every", "1", "--no-output"],
    );
    assert!(
        !o.status.success() && text(&o).contains("--no-output"),
        "{}",
        text(&o)
    );
}

/// `--backend auto` (the default) of a batch: on a machine without a usable GPU it runs the
/// CPU backend and says why in one line; the same frames as `--backend cpu`.
#[test]
fn auto_runs_a_batch_on_the_cpu_without_a_gpu_and_says_why() {
    if rtmpm_cuda::probe().is_ok() {
        println!("skipped: a usable GPU is here (auto would run the batch on it)");
        return;
    }
    let dir = scratch("batch-auto");
    let scene = data("tiny_wedge.toml");
    let auto_out = dir.join("auto");
    let o = rtmpm(&[
        "run",
        &scene,
        "--frames",
        "1",
        "--out",
        auto_out.to_str().unwrap(),
    ]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    let notes: Vec<&str> = t.lines().filter(|l| l.starts_with("backend: ")).collect();
    assert_eq!(notes.len(), 1, "{t}");
    assert!(
        notes[0].starts_with("backend: auto -> cpu (CUDA not usable: "),
        "{t}"
    );
    assert!(t.contains("worlds on the CPU backend"), "{t}");
    let cpu_out = dir.join("cpu");
    let c = run_ok(&scene, &cpu_out, &["--frames", "1"]);
    assert!(!c.contains("backend: "), "--backend cpu needs no note: {c}");
    let strip = |d: &Path| {
        files(d)
            .into_iter()
            .filter(|(k, _)| k.ends_with(".ply"))
            .collect::<BTreeMap<_, _>>()
    };
    let frames = strip(&auto_out);
    assert_eq!(frames.len(), 8, "{:?}", frames.keys());
    assert_eq!(
        frames,
        strip(&cpu_out),
        "auto's frames are the CPU backend's"
    );
    // --backend cuda says why it cannot, and names the CPU backend.
    let o = rtmpm(&["run", &scene, "--backend", "cuda", "--no-output"]);
    assert!(!o.status.success());
    let t = text(&o);
    assert!(
        t.contains("the CUDA backend is not usable here") && t.contains("--backend cpu"),
        "{t}"
    );
}
