//! End-to-end tests of `rtmpm render` and `rtmpm run --render / --preview`.

use rtmpm_render::Image;
use rtmpm_render::text::{text_height, text_width};
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

/// The rectangle `(x0, y0, w, h)` of `img` as RGB rows.
fn region(img: &Image, (x0, y0, w, h): (u32, u32, u32, u32)) -> Vec<[u8; 3]> {
    (y0..y0 + h)
        .flat_map(|y| (x0..x0 + w).map(move |x| (x, y)))
        .map(|(x, y)| img.pixel(x, y))
        .collect()
}

#[test]
fn render_of_a_batch_is_a_grid_of_worlds_with_captions() {
    let dir = scratch("render-wedge");
    let out = dir.join("out");
    let o = rtmpm(&[
        "run",
        &data("tiny_wedge.toml"),
        "--backend",
        "cpu",
        "--out",
        out.to_str().unwrap(),
        "--frames",
        "1",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(out.join("batch.csv").is_file(), "{}", text(&o));
    let o = rtmpm(&["render", out.to_str().unwrap(), "--size", "320x180"]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("wedge of 4 worlds (2 x 2)"),
        "{}",
        text(&o)
    );
    // Frames 0 and 1, one picture each, and the movie of both.
    assert!(!out.join("wedge_00002.png").exists());
    assert_eq!(gif_frames(&out.join("wedge.gif")), 2);
    let img = png(&out.join("wedge_00001.png"));

    // 4 worlds: 2 x 2 tiles of 320 / 2 = 160 x 90 (16:9), each with a caption strip below it,
    // its text at twice the font's size where the longest caption fits in a tile, else once.
    let captions = [
        "center[0] = 0.14",
        "center[0] = 0.21",
        "center[0] = 0.29",
        "center[0] = 0.36",
    ];
    let (cols, rows, tile_w, tile_h) = (2u32, 2u32, 160u32, 90u32);
    let longest = captions.iter().map(|c| text_width(c, 2)).max().unwrap();
    let scale = if longest + 8 <= tile_w { 2 } else { 1 };
    let strip = text_height(scale) + 6 * scale;
    assert_eq!(
        (img.width, img.height),
        (cols * tile_w, rows * (tile_h + strip))
    );

    let background = [24, 24, 28];
    let mut tiles = Vec::new();
    for (w, caption) in captions.iter().enumerate() {
        let (x0, y0) = (
            (w as u32 % cols) * tile_w,
            (w as u32 / cols) * (tile_h + strip),
        );
        let tile = region(&img, (x0, y0, tile_w, tile_h));
        // A picture, not the background.
        assert!(
            tile.iter().any(|p| *p != background),
            "world {w}: blank tile"
        );
        // The caption: light pixels in the strip below the tile, within the caption's width
        // centred under it, and nothing drawn left of it (the text's dark outline reaches one
        // pixel out).
        let cw = text_width(caption, scale);
        let cx = x0 + (tile_w - cw) / 2;
        let inside = region(&img, (cx, y0 + tile_h, cw, strip));
        let lit = inside.iter().filter(|p| p.iter().all(|&c| c > 200)).count();
        assert!(lit >= 4 * caption.len(), "world {w}: {lit} caption pixels");
        let left = region(&img, (x0, y0 + tile_h, cx - 1 - x0, strip));
        assert!(
            left.iter().all(|p| *p == background),
            "world {w}: stray pixels left of the caption"
        );
        tiles.push(tile);
    }
    // Each world's ball is placed elsewhere: no two tiles are the same picture.
    for (a, ta) in tiles.iter().enumerate() {
        for (b, tb) in tiles.iter().enumerate().skip(a + 1) {
            let differ = ta.iter().zip(tb).filter(|(p, q)| p != q).count();
            assert!(
                differ > 50,
                "worlds {a} and {b} differ in {differ} pixels only"
            );
        }
    }
}
