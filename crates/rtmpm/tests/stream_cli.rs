//! Frames streamed from the backend and written in the background: the same
//! files as the whole-frame writer, and writer errors reported with the file, leaving nothing.

mod common;

use common::{data, rtmpm, scratch, text};
use std::fs;
use std::path::Path;

/// small_drop with PLY, BGEO and BGEO.gz frames (and J and stress fields).
fn scene(dir: &Path) -> String {
    let s = fs::read_to_string(data("small_drop.toml")).expect("scene");
    let s = s.replace(
        "formats = [\"ply\", \"vtu\"]",
        "formats = [\"ply\", \"bgeo\", \"bgeo.gz\"]",
    );
    assert!(s.contains("bgeo.gz"));
    let path = dir.join("stream.toml");
    fs::write(&path, s).expect("write scene");
    path.display().to_string()
}

fn frame_files(out: &Path) -> Vec<String> {
    let mut v: Vec<String> = fs::read_dir(out)
        .expect("out")
        .map(|e| e.expect("entry").file_name().into_string().expect("name"))
        .filter(|n| n.starts_with("frame_"))
        .collect();
    v.sort();
    v
}

fn leftovers(out: &Path) -> Vec<String> {
    fs::read_dir(out)
        .expect("out")
        .map(|e| e.expect("entry").file_name().into_string().expect("name"))
        .filter(|n| n.contains(".tmp"))
        .collect()
}

#[test]
fn streamed_frames_are_byte_identical_to_whole_frames() {
    let dir = scratch("stream-identical");
    let scene = scene(&dir);
    let run = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let mut args = vec![
            "run",
            &scene,
            "--backend",
            "cpu",
            "--frames",
            "3",
            "--out",
            out.to_str().expect("path"),
        ];
        args.extend_from_slice(extra);
        let o = rtmpm(&args);
        assert!(o.status.success(), "{name}: {}", text(&o));
        (out, text(&o))
    };
    let (whole, _) = run("whole", &["--whole-frames"]);
    // In the background, chunks of 100 particles; and waiting for each frame, chunks of 7.
    let (bg, log) = run("background", &["--frame-chunk", "100"]);
    assert!(log.contains("frame files  4 frames"), "{log}");
    let (sync, _) = run("sync", &["--frames-in-flight", "0", "--frame-chunk", "7"]);
    let names = frame_files(&whole);
    assert_eq!(names.len(), 12, "{names:?}");
    for out in [&bg, &sync] {
        assert_eq!(frame_files(out), names);
        for n in &names {
            let (a, b) = (
                fs::read(whole.join(n)).expect("a"),
                fs::read(out.join(n)).expect("b"),
            );
            assert!(
                a == b,
                "{} differs from the whole-frame writer's",
                out.join(n).display()
            );
        }
        assert!(leftovers(out).is_empty());
    }
}

/// A folder where a frame file goes (frame 2's PLY) is not a file rtmpm wrote: the run is
/// refused before anything is written, naming it, and the folder is kept (with --overwrite too,
/// and whether frames are written in the background or not).
#[test]
fn a_folder_in_place_of_a_frame_file_refuses_the_run_before_it_writes() {
    let dir = scratch("stream-error");
    let scene = scene(&dir);
    let out = dir.join("out");
    fs::create_dir_all(out.join("frame_00002.ply")).expect("dir");
    fs::write(out.join("frame_00002.ply").join("keep"), "x").expect("file");
    for in_flight in ["0", "1"] {
        let o = rtmpm(&[
            "run",
            &scene,
            "--backend",
            "cpu",
            "--frames",
            "3",
            "--overwrite",
            "--frames-in-flight",
            in_flight,
            "--out",
            out.to_str().expect("path"),
        ]);
        let msg = text(&o);
        assert!(!o.status.success(), "{msg}");
        assert!(
            msg.contains("frame_00002.ply") && msg.contains("cannot prove it wrote"),
            "{msg}"
        );
        assert!(leftovers(&out).is_empty(), "{:?}", leftovers(&out));
        assert!(!out.join("frame_00000.ply").exists(), "{msg}");
        assert_eq!(
            fs::read_to_string(out.join("frame_00002.ply").join("keep")).expect("kept"),
            "x"
        );
    }
}

/// Emitters add particles every frame (the chunk buffers grow): still the same files.
#[test]
fn frames_of_a_growing_particle_count_are_byte_identical() {
    let dir = scratch("stream-emitters");
    let scene = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes/fountain.toml")
        .display()
        .to_string();
    let run = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let mut args = vec![
            "run",
            &scene,
            "--backend",
            "cpu",
            "--frames",
            "4",
            "--out",
            out.to_str().expect("path"),
        ];
        args.extend_from_slice(extra);
        let o = rtmpm(&args);
        assert!(o.status.success(), "{name}: {}", text(&o));
        out
    };
    let whole = run("whole", &["--whole-frames"]);
    let streamed = run("streamed", &["--frame-chunk", "1000"]);
    let names = frame_files(&whole);
    assert_eq!(names.len(), 5, "{names:?}");
    let sizes: Vec<u64> = names
        .iter()
        .map(|n| fs::metadata(whole.join(n)).expect("size").len())
        .collect();
    assert!(sizes[4] > sizes[1], "the particle count grows: {sizes:?}");
    assert_eq!(frame_files(&streamed), names);
    for n in &names {
        let (a, b) = (
            fs::read(whole.join(n)).expect("a"),
            fs::read(streamed.join(n)).expect("b"),
        );
        assert!(a == b, "{n} differs from the whole-frame writer's");
    }
}
