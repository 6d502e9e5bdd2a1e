//! End-to-end tests of the DCC file formats on the command line: BGEO frames, a run seeded from another
//! run's frame, and clear errors for bad particle files and empty folders.

mod common;

use common::{data, rtmpm, scratch, text};

/// The PLY columns x, y, z of a frame (binary little endian, rtmpm's layout: 8 floats/ints
/// first, then optional fields), as raw f32 triples.
fn ply_positions(path: &std::path::Path) -> Vec<[f32; 3]> {
    let b = std::fs::read(path).unwrap();
    let end = b.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let head = String::from_utf8_lossy(&b[..end]).into_owned();
    let n: usize = head
        .lines()
        .find_map(|l| l.strip_prefix("element vertex "))
        .unwrap()
        .parse()
        .unwrap();
    let props = head.lines().filter(|l| l.starts_with("property")).count();
    let f = |o: usize| f32::from_le_bytes(b[o..o + 4].try_into().unwrap());
    (0..n)
        .map(|i| {
            let o = end + i * props * 4;
            [f(o), f(o + 4), f(o + 8)]
        })
        .collect()
}

#[test]
fn a_runs_bgeo_frame_seeds_a_new_run() {
    let dir = scratch("dcc-seed");
    let first = dir.join("first");
    let scene = std::fs::read_to_string(data("small_drop.toml"))
        .unwrap()
        .replace(
            "formats = [\"ply\", \"vtu\"]",
            "formats = [\"ply\", \"bgeo.gz\"]",
        );
    let scene_path = dir.join("first.toml");
    std::fs::write(&scene_path, scene).unwrap();
    let o = rtmpm(&[
        "run",
        scene_path.to_str().unwrap(),
        "--backend",
        "cpu",
        "--frames",
        "2",
        "--out",
        first.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(first.join("frame_00002.bgeo.gz").exists());

    // A second scene: one body of water made of the first run's last frame.
    let second = r#"name = "seeded"
[domain]
min = [0.0, 0.0, 0.0]
max = [0.5, 0.5, 0.5]
dx = 0.03125
[time]
duration = 0.05
fps = 40
[[material]]
name = "water"
type = "fluid"
density = 1000.0
bulk_modulus = 2.0e4
[[body]]
material = "water"
shape = "particles"
file = "first/frame_00002.bgeo.gz"
[output]
formats = ["ply"]
"#;
    let second_path = dir.join("second.toml");
    std::fs::write(&second_path, second).unwrap();
    let out2 = dir.join("second");
    let o = rtmpm(&[
        "run",
        second_path.to_str().unwrap(),
        "--backend",
        "cpu",
        "--frames",
        "1",
        "--out",
        out2.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    // Frame 0 of the new run is exactly the first run's frame 2.
    let a = ply_positions(&first.join("frame_00002.ply"));
    let b = ply_positions(&out2.join("frame_00000.ply"));
    assert!(!a.is_empty());
    assert_eq!(a, b);

    // `rtmpm check` reports a damaged particle file by name, with a non-zero exit.
    let bytes = std::fs::read(first.join("frame_00002.bgeo.gz")).unwrap();
    std::fs::write(first.join("frame_00002.bgeo.gz"), &bytes[..bytes.len() / 3]).unwrap();
    let o = rtmpm(&["check", second_path.to_str().unwrap()]);
    assert!(!o.status.success());
    let t = text(&o);
    assert!(
        t.contains("frame_00002.bgeo.gz") && t.contains("body[0].file"),
        "{t}"
    );
    assert!(!t.contains("panicked"), "{t}");
}

#[test]
fn mesh_needs_frames() {
    let dir = scratch("dcc-mesh-empty");
    let o = rtmpm(&["mesh", dir.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(text(&o).contains("no frame_NNNNN.ply"), "{}", text(&o));
    let o = rtmpm(&["mesh", dir.to_str().unwrap(), "--formats", "stl"]);
    assert!(
        text(&o).contains("unknown mesh format `stl`"),
        "{}",
        text(&o)
    );
}

/// Every file of every format (frames, surfaces, both `.pvd` collections) belongs to the folder's run:
/// a resume continues `surface.pvd` and writes the later frames again, an unreadable
/// `surface.pvd` stops the resume before anything is removed, and `--overwrite` removes BGEO,
/// USD and surface files with the rest.
#[cfg(feature = "surface")]
#[test]
fn bgeo_usd_and_surface_files_belong_to_the_folders_run() {
    use std::fs;
    let dir = scratch("dcc-folder");
    let out = dir.join("out");
    let scene = fs::read_to_string(data("small_drop.toml"))
        .unwrap()
        .replace(
            "formats = [\"ply\", \"vtu\"]",
            "formats = [\"ply\", \"bgeo.gz\", \"usda\"]\nsurface = [\"obj\", \"vtu\"]",
        );
    let scene_path = dir.join("drop.toml");
    fs::write(&scene_path, scene).unwrap();
    let run = |extra: &[&str]| {
        let mut args = vec!["run"];
        if !extra.contains(&"--resume") {
            args.push(scene_path.to_str().unwrap());
        }
        args.extend(["--backend", "cpu", "--out", out.to_str().unwrap()]);
        args.extend_from_slice(extra);
        rtmpm(&args)
    };
    let o = run(&["--checkpoint-every", "2"]);
    assert!(o.status.success(), "{}", text(&o));
    let surface1 = fs::read(out.join("surface_00001.obj")).unwrap();
    let bgeo4 = fs::read(out.join("frame_00004.bgeo.gz")).unwrap();
    assert!(out.join("frame_00004.usda").exists() && out.join("surface_00004.vtu").exists());

    // Resume after frame 2: frames 3 and 4 are written again (BGEO bit-identical on the CPU),
    // frame 1 untouched, surface.pvd lists frames 0..=4 once each.
    let ckpt = out.join("checkpoint_00002.ckpt");
    fs::remove_file(out.join("surface_00004.obj")).unwrap();
    let o = run(&["--resume", ckpt.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(fs::read(out.join("surface_00001.obj")).unwrap(), surface1);
    assert_eq!(fs::read(out.join("frame_00004.bgeo.gz")).unwrap(), bgeo4);
    assert!(out.join("surface_00004.obj").exists());
    let pvd = fs::read_to_string(out.join("surface.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet").count(), 5, "{pvd}");

    // An unreadable surface.pvd: the resume is refused, the file and the frames stay.
    fs::write(out.join("surface.pvd"), "garbage").unwrap();
    let o = run(&["--resume", ckpt.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(text(&o).contains("surface.pvd"), "{}", text(&o));
    assert_eq!(
        fs::read_to_string(out.join("surface.pvd")).unwrap(),
        "garbage"
    );
    assert!(out.join("frame_00004.bgeo.gz").exists());

    // A fresh run of another scene with --overwrite: no file of the old run is left.
    let plain = fs::read_to_string(data("small_drop.toml")).unwrap();
    fs::write(&scene_path, plain).unwrap();
    let o = run(&["--frames", "1"]);
    assert!(!o.status.success(), "{}", text(&o));
    // The surface.pvd made garbage above carries no rtmpm signature: --overwrite keeps it and
    // refuses, naming it, until it is moved away.
    let o = run(&["--frames", "1", "--overwrite"]);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("surface.pvd") && text(&o).contains("cannot prove it wrote"),
        "{}",
        text(&o)
    );
    assert_eq!(
        fs::read_to_string(out.join("surface.pvd")).unwrap(),
        "garbage"
    );
    fs::remove_file(out.join("surface.pvd")).unwrap();
    let o = run(&["--frames", "1", "--overwrite"]);
    assert!(o.status.success(), "{}", text(&o));
    let left: Vec<String> = fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.contains("bgeo") || n.contains("usda") || n.starts_with("surface"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}
