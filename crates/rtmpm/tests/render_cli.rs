//! End-to-end tests of `rtmpm render` and `rtmpm run --render / --preview`.

use rtmpm_render::Image;
mod common;

use common::{data, rtmpm, scratch, text};
use std::path::Path;

fn png(path: &Path) -> Image {
    Image::decode_png(&std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())))
        .expect("PNG decodes")
}

fn gif_frames(path: &Path) -> usize {
    let file = std::fs::File::open(path).expect("movie.gif exists");
    let mut dec = gif::DecodeOptions::new()
        .read_info(file)
        .expect("GIF decodes");
    let mut n = 0;
    while dec.read_next_frame().expect("GIF frame").is_some() {
        n += 1;
    }
    n
}

fn pngs(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("frame_") && n.ends_with(".png"))
        .collect();
    v.sort();
    v
}

#[test]
fn run_render_preview_then_render_outdir() {
    let dir = scratch("render-run");
    let out = dir.join("out");
    let preview = dir.join("preview.png");
    let o = rtmpm(&[
        "run",
        &data("small_drop.toml"),
        "--backend",
        "cpu",
        "--out",
        out.to_str().unwrap(),
        "--render",
        "--preview",
        preview.to_str().unwrap(),
        "--size",
        "160x90",
        "--gif-size",
        "80x45",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let frames = pngs(&out);
    // duration 0.1 s at 40 fps: frames 0..=4.
    assert_eq!(frames.len(), 5, "{frames:?}");
    let img = png(&out.join(&frames[4]));
    assert_eq!((img.width, img.height), (160, 90));
    assert_eq!(png(&preview), img, "the preview is the last frame");
    assert_eq!(gif_frames(&out.join("movie.gif")), 5);
    assert!(text(&o).contains("render"), "{}", text(&o));

    // Re-render the PLY frames coloured by speed: colour bar at the right edge.
    let o = rtmpm(&[
        "render",
        out.to_str().unwrap(),
        "--scene",
        &data("small_drop.toml"),
        "--color-by",
        "speed",
        "--size",
        "320x180",
        "--no-movie",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let img = png(&out.join("frame_00004.png"));
    assert_eq!((img.width, img.height), (320, 180));
    let top = img.pixel(320 - 15, 180 / 4 + 2);
    assert!(top[0] > 200 && top[1] > 200 && top[2] < 80, "{top:?}");
    // Not blank: the centre region differs from the corners.
    let centre = img.pixel(160, 100);
    assert_ne!(centre, img.pixel(0, 0));

    // Without the scene: framed from the particles.
    let o = rtmpm(&["render", out.to_str().unwrap(), "--size", "64x36"]);
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(gif_frames(&out.join("movie.gif")), 5);

    // Colouring by J and by stress uses the frames' J and stress columns.
    for field in ["J", "stress", "plastic"] {
        let o = rtmpm(&[
            "render",
            out.to_str().unwrap(),
            "--color-by",
            field,
            "--no-movie",
        ]);
        assert!(o.status.success(), "{field}: {}", text(&o));
    }

    // A field the frames lack is a clear error.
    let bare = dir.join("bare");
    let mut ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n".to_vec();
    for c in [0.1f32, 0.2, 0.3] {
        ply.extend_from_slice(&c.to_le_bytes());
    }
    std::fs::create_dir_all(&bare).unwrap();
    std::fs::write(bare.join("frame_00000.ply"), ply).unwrap();
    let o = rtmpm(&["render", bare.to_str().unwrap(), "--color-by", "J"]);
    assert!(!o.status.success());
    assert!(
        text(&o).contains("`J`") && text(&o).contains("fields"),
        "{}",
        text(&o)
    );
    // ... while material colouring of the same frame works.
    let o = rtmpm(&["render", bare.to_str().unwrap(), "--size", "64x36"]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(bare.join("frame_00000.png").exists());
}

#[test]
fn render_errors_are_clear() {
    let dir = scratch("render-errors");
    let o = rtmpm(&["render", dir.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(text(&o).contains("no frame_NNNNN.ply"), "{}", text(&o));
    let o = rtmpm(&["render", dir.join("missing").to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(text(&o).contains("cannot read folder"), "{}", text(&o));
    let o = rtmpm(&["render", dir.to_str().unwrap(), "--size", "big"]);
    assert!(!o.status.success());
    assert!(text(&o).contains("WIDTHxHEIGHT"), "{}", text(&o));
    let o = rtmpm(&["render", dir.to_str().unwrap(), "--camera", "1,2"]);
    assert!(!o.status.success());
    let o = rtmpm(&["render"]);
    assert!(!o.status.success());
    assert!(text(&o).contains("no folder"), "{}", text(&o));
    // A corrupt frame names the file.
    std::fs::write(dir.join("frame_00000.ply"), b"garbage").unwrap();
    let o = rtmpm(&["render", dir.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(text(&o).contains("frame_00000.ply"), "{}", text(&o));
}

#[test]
fn render_bench_reports_time() {
    let o = rtmpm(&[
        "render",
        "--bench",
        "--bench-particles",
        "20000",
        "--size",
        "320x180",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("s per frame"), "{}", text(&o));
}
