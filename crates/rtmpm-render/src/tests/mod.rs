//! Image-content tests of the renderer.

mod colliders;

use crate::*;
use rtmpm_io::testing::TestDir;
use rtmpm_physics::math::Vec3;
use rtmpm_scene::ColorBy;

/// A cube of `k^3` particles of side `size` centred at `c`.
fn cube(c: Vec3, size: f32, k: usize) -> Vec<Vec3> {
    let mut v = Vec::new();
    let h = size / k as f32;
    for i in 0..k {
        for j in 0..k {
            for l in 0..k {
                v.push(
                    c - Vec3::splat(0.5 * size)
                        + (Vec3::new(i as f32, j as f32, l as f32) + 0.5) * h,
                );
            }
        }
    }
    v
}

pub(crate) mod support {
    use super::*;

    pub(crate) fn front_camera() -> Camera {
        Camera {
            position: Vec3::new(0.0, 0.0, 3.0),
            target: Vec3::ZERO,
            fov_deg: 40.0,
        }
    }

    pub(crate) fn o_view(w: u32, h: u32) -> camera::View {
        front_camera().view(w, h)
    }

    pub(crate) fn opts(w: u32, h: u32) -> RenderOptions {
        let mut o = RenderOptions::new(Vec3::splat(-1.0), Vec3::splat(1.0), 0.02);
        o.width = w;
        o.height = h;
        o.camera = front_camera();
        o
    }

    /// Save an image for inspection when `RTMPM_RENDER_TEST_DIR` is set.
    pub(crate) fn dump(img: &Image, name: &str) {
        if let Some(dir) = std::env::var_os("RTMPM_RENDER_TEST_DIR") {
            img.write_png(&std::path::Path::new(&dir).join(format!("{name}.png")))
                .unwrap();
        }
    }

    pub(crate) fn count_close(img: &Image, rgb: [u8; 3], tol: i32) -> usize {
        img.rgb
            .chunks(3)
            .filter(|p| (0..3).all(|k| (p[k] as i32 - rgb[k] as i32).abs() <= tol))
            .count()
    }

    /// Hue family of a pixel: which channel dominates clearly.
    pub(crate) fn dominant(p: [u8; 3]) -> Option<usize> {
        let m = *p.iter().max().unwrap();
        let i = p.iter().position(|&c| c == m).unwrap();
        let others = (0..3).filter(|&k| k != i).map(|k| p[k]).max().unwrap();
        (m as i32 - others as i32 > 40).then_some(i)
    }
}
use support::*;

#[test]
fn cube_covers_centre_not_corners() {
    let pos = cube(Vec3::ZERO, 0.6, 20);
    let mat = vec![0u32; pos.len()];
    let mut o = opts(160, 90);
    o.floor = None;
    o.shadows = false;
    let img = render(
        &RenderInput {
            positions: &pos,
            material: &mat,
            field: None,
            surface: None,
        },
        &o,
    )
    .unwrap();
    // Material 0 is blue: the centre is blue, the corners are background.
    assert_eq!(
        dominant(img.pixel(80, 45)),
        Some(2),
        "{:?}",
        img.pixel(80, 45)
    );
    for (x, y) in [(0, 0), (159, 0), (0, 89), (159, 89)] {
        assert_ne!(dominant(img.pixel(x, y)), Some(2), "corner {x},{y}");
    }
    // Not blank: many distinct colours.
    let mut colours: Vec<[u8; 3]> = img.rgb.chunks(3).map(|p| [p[0], p[1], p[2]]).collect();
    colours.sort();
    colours.dedup();
    assert!(colours.len() > 50, "{}", colours.len());
}

#[test]
fn near_red_occludes_far_blue() {
    // Blue (material 0) far, red (material 2) near, on the same line of sight; the far one is
    // listed last so that drawing order alone would show it.
    let pos = [Vec3::new(0.0, 0.0, 0.5), Vec3::new(0.0, 0.0, -0.5)];
    let mat = [2u32, 0];
    let mut o = opts(64, 64);
    o.radius = 0.15;
    o.floor = None;
    o.shadows = false;
    let img = render(
        &RenderInput {
            positions: &pos,
            material: &mat,
            field: None,
            surface: None,
        },
        &o,
    )
    .unwrap();
    assert_eq!(
        dominant(img.pixel(32, 32)),
        Some(0),
        "{:?}",
        img.pixel(32, 32)
    );
    // And swapping depth shows blue.
    let pos = [Vec3::new(0.0, 0.0, -0.5), Vec3::new(0.0, 0.0, 0.5)];
    let img = render(
        &RenderInput {
            positions: &pos,
            material: &mat,
            field: None,
            surface: None,
        },
        &o,
    )
    .unwrap();
    assert_eq!(
        dominant(img.pixel(32, 32)),
        Some(2),
        "{:?}",
        img.pixel(32, 32)
    );
}

#[test]
fn material_colours_present() {
    let mut pos = cube(Vec3::new(-0.5, 0.0, 0.0), 0.4, 12);
    let n0 = pos.len();
    pos.extend(cube(Vec3::new(0.5, 0.0, 0.0), 0.4, 12));
    let mat: Vec<u32> = (0..pos.len()).map(|i| if i < n0 { 1 } else { 3 }).collect();
    let img = render(
        &RenderInput {
            positions: &pos,
            material: &mat,
            field: None,
            surface: None,
        },
        &opts(200, 120),
    )
    .unwrap();
    dump(&img, "materials");
    // Left cube: sand (red > green > blue); right cube: green dominant.
    let view = o_view(200, 120);
    let (lx, ly, _) = view.project(Vec3::new(-0.5, 0.0, 0.0));
    let (rx, ry, _) = view.project(Vec3::new(0.5, 0.0, 0.0));
    let left = img.pixel(lx as u32, ly as u32);
    assert!(left[0] > left[1] && left[1] > left[2] + 20, "{left:?}");
    assert_eq!(dominant(img.pixel(rx as u32, ry as u32)), Some(1));
    // The custom palette replaces the fixed one.
    let mut o = opts(200, 120);
    o.palette = vec![[1.0, 0.0, 1.0]; 4];
    let img = render(
        &RenderInput {
            positions: &pos,
            material: &mat,
            field: None,
            surface: None,
        },
        &o,
    )
    .unwrap();
    let p = img.pixel(lx as u32, ly as u32);
    assert!(p[0] > p[1] + 40 && p[2] > p[1] + 40, "{p:?}");
}

#[test]
fn field_colouring_draws_colour_bar_and_errors_without_field() {
    let pos = cube(Vec3::ZERO, 0.6, 16);
    let mat = vec![0u32; pos.len()];
    let field: Vec<f32> = pos.iter().map(|p| p.y).collect();
    let mut o = opts(320, 180);
    o.color_by = ColorBy::Speed;
    let input = RenderInput {
        positions: &pos,
        material: &mat,
        field: Some(&field),
        surface: None,
    };
    let img = render(&input, &o).unwrap();
    dump(&img, "colour_bar");
    // The bar: near the right edge, bright yellow at the top, dark purple at the bottom.
    let s = 1;
    let xb = 320 - 10 * s - 5;
    let top = img.pixel(xb as u32, 180 / 4 + 2);
    let bottom = img.pixel(xb as u32, 3 * 180 / 4 - 2);
    assert!(top[0] > 200 && top[1] > 200 && top[2] < 80, "{top:?}");
    assert!(bottom[2] > bottom[1] && bottom[0] > bottom[1], "{bottom:?}");
    // Label text is drawn in near-white.
    assert!(count_close(&img, [235, 235, 235], 0) > 40);
    // Material colouring has no bar.
    o.color_by = ColorBy::Material;
    let img2 = render(&input, &o).unwrap();
    assert!(
        dominant(img2.pixel(xb as u32, 180 / 4 + 2)).is_none()
            || img2.pixel(xb as u32, 180 / 4 + 2) != top
    );
    // Missing field: a clear error.
    o.color_by = ColorBy::J;
    let err = render(
        &RenderInput {
            field: None,
            ..input
        },
        &o,
    )
    .unwrap_err();
    assert!(err.to_string().contains("J"), "{err}");
}

#[test]
fn ground_and_shadow_are_drawn() {
    // A slab floating above the ground, lit from above: the ground right under it is darker
    // than the ground far from it.
    let pos = cube(Vec3::new(0.0, 0.0, 0.0), 0.5, 20);
    let mat = vec![4u32; pos.len()];
    let mut o = RenderOptions::new(Vec3::new(-1.0, -0.8, -1.0), Vec3::new(1.0, 1.0, 1.0), 0.015);
    o.width = 160;
    o.height = 90;
    o.camera = Camera {
        position: Vec3::new(0.0, 3.0, 0.01),
        target: Vec3::new(0.0, -0.8, 0.0),
        fov_deg: 60.0,
    };
    let lit = render(
        &RenderInput {
            positions: &pos,
            material: &mat,
            field: None,
            surface: None,
        },
        &o,
    )
    .unwrap();
    o.shadows = false;
    let unlit = render(
        &RenderInput {
            positions: &pos,
            material: &mat,
            field: None,
            surface: None,
        },
        &o,
    )
    .unwrap();
    dump(&lit, "ground_lit");
    dump(&unlit, "ground_unlit");
    let dark = |img: &Image| img.rgb.iter().map(|&c| c as u64).sum::<u64>();
    assert!(dark(&lit) < dark(&unlit), "shadows darken the image");
    // The ground is drawn (grey, not the background) near the image edge below the cube.
    let p = unlit.pixel(62, 45);
    assert!(p[0] > 80 && (p[0] as i32 - p[2] as i32).abs() < 10, "{p:?}");
}

#[test]
fn png_round_trip_and_gif_frame_count() {
    let d = TestDir::new("render");
    let pos = cube(Vec3::ZERO, 0.5, 8);
    let mat = vec![0u32; pos.len()];
    let img = render(
        &RenderInput {
            positions: &pos,
            material: &mat,
            field: None,
            surface: None,
        },
        &opts(96, 54),
    )
    .unwrap();
    let path = d.path("a/frame.png");
    img.write_png(&path).unwrap();
    let back = Image::decode_png(&std::fs::read(&path).unwrap()).unwrap();
    assert_eq!(back, img);

    let mut movie = GifMovie::new(48, 27, 30.0).unwrap();
    for _ in 0..5 {
        movie.add(&img).unwrap();
    }
    let gif_path = d.path("movie.gif");
    assert_eq!(movie.finish(&gif_path).unwrap(), 5);
    let file = std::fs::File::open(&gif_path).unwrap();
    let mut opts = gif::DecodeOptions::new();
    opts.set_color_output(gif::ColorOutput::RGBA);
    let mut dec = opts.read_info(file).unwrap();
    assert_eq!((dec.width(), dec.height()), (48, 27));
    let mut frames = 0;
    while let Some(f) = dec.read_next_frame().unwrap() {
        assert_eq!(f.delay, 3);
        frames += 1;
    }
    assert_eq!(frames, 5);
}

#[test]
fn radius_estimate_and_range_and_format() {
    // Regular lattice of spacing 0.01: nearest neighbour 0.01, radius 0.006.
    let pos = cube(Vec3::ZERO, 0.2, 20);
    let r = estimate_radius(&pos);
    assert!((r - 0.006).abs() < 1e-4, "{r}");
    assert!(estimate_radius(&[]) > 0.0);
    assert!(estimate_radius(&[Vec3::ONE]) > 0.0);
    let v: Vec<f32> = (0..=1000).map(|i| i as f32).collect();
    let (lo, hi) = field_range(&v);
    assert!(
        (lo - 10.0).abs() <= 1.0 && (hi - 990.0).abs() <= 1.0,
        "{lo} {hi}"
    );
    let (lo, hi) = field_range(&[2.0; 10]);
    assert!(lo < 2.0 && hi > 2.0);
    assert_eq!(field_range(&[f32::NAN]), (0.0, 1.0));
    assert_eq!(format_value(0.0), "0");
    assert_eq!(format_value(1.5), "1.5");
    assert_eq!(format_value(2.0), "2");
    assert_eq!(format_value(123456.0), "1.23E5");
    assert!((von_mises([1.0, 0.0, 0.0, 0.0, 0.0, 0.0]) - 1.0).abs() < 1e-6);
    assert_eq!(von_mises([5.0, 5.0, 5.0, 0.0, 0.0, 0.0]), 0.0);
    assert_eq!("J".parse::<ColorBy>().unwrap(), ColorBy::J);
    assert!("colour".parse::<ColorBy>().is_err());
}

#[test]
fn bad_options_are_errors() {
    let pos = [Vec3::ZERO];
    let input = RenderInput {
        positions: &pos,
        material: &[0],
        field: None,
        surface: None,
    };
    let mut o = opts(0, 10);
    assert!(render(&input, &o).is_err());
    o = opts(10, 10);
    o.camera.target = o.camera.position;
    assert!(render(&input, &o).is_err());
    o = opts(10, 10);
    o.radius = -1.0;
    assert!(render(&input, &o).is_err());
    let bad = RenderInput {
        positions: &pos,
        material: &[],
        field: None,
        surface: None,
    };
    assert!(render(&bad, &opts(10, 10)).is_err());
    // Empty frames render the background.
    let empty = RenderInput {
        positions: &[],
        material: &[],
        field: None,
        surface: None,
    };
    assert!(render(&empty, &opts(10, 10)).is_ok());
}

/// `cargo test --release -p rtmpm-render render_1m -- --ignored --nocapture`
#[test]
#[ignore]
fn render_1m_benchmark() {
    let pos = cube(Vec3::ZERO, 1.0, 100);
    let mat: Vec<u32> = (0..pos.len()).map(|i| (i % 3) as u32).collect();
    let mut o = RenderOptions::new(Vec3::splat(-0.6), Vec3::splat(0.6), 0.006);
    o.camera = Camera::framing(Vec3::splat(-0.6), Vec3::splat(0.6), 16.0 / 9.0, 40.0);
    let input = RenderInput {
        positions: &pos,
        material: &mat,
        field: None,
        surface: None,
    };
    render(&input, &o).unwrap();
    let t = std::time::Instant::now();
    let reps = 3;
    for _ in 0..reps {
        render(&input, &o).unwrap();
    }
    let dt = t.elapsed().as_secs_f64() / reps as f64;
    println!(
        "render 1M particles 1280x720: {:.3} s/frame ({} threads)",
        dt,
        rayon::current_num_threads()
    );
}

const SCENE: &str = r#"
[domain]
min = [0.0, 0.0, 0.0]
max = [1.0, 1.0, 1.0]
dx = 0.0625
[time]
duration = 1.0
[[material]]
name = "w"
type = "fluid"
density = 1000.0
bulk_modulus = 1e4
[[body]]
material = "w"
shape = "box"
min = [0.25, 0.25, 0.25]
max = [0.5, 0.5, 0.5]
"#;

#[test]
fn scene_render_table() {
    let s = rtmpm_scene::Scene::from_toml(SCENE, "t.toml").unwrap();
    assert_eq!(s.render, rtmpm_scene::RenderSettings::default());
    let text = format!(
        "{SCENE}[render]\ncamera = [2.0, 1.0, 3.0]\ntarget = [0.5, 0.2, 0.5]\nfov = 30\nwidth = 640\nheight = 360\ncolor_by = \"J\"\n"
    );
    let s = rtmpm_scene::Scene::from_toml(&text, "t.toml").unwrap();
    assert_eq!(s.render.camera, Some(Vec3::new(2.0, 1.0, 3.0)));
    assert_eq!(s.render.fov, Some(30.0));
    assert_eq!((s.render.width, s.render.height), (Some(640), Some(360)));
    assert_eq!(s.render.color_by, Some(ColorBy::J));
    for (bad, field) in [
        ("fov = 180", "render.fov"),
        ("width = 8", "render.width"),
        ("color_by = \"colour\"", "render.color_by"),
        (
            "camera = [1.0, 1.0, 1.0]\ntarget = [1.0, 1.0, 1.0]",
            "render.target",
        ),
        ("zoom = 2", "render.zoom"),
    ] {
        let e = rtmpm_scene::Scene::from_toml(&format!("{SCENE}[render]\n{bad}\n"), "t.toml")
            .expect_err(bad);
        assert!(
            e.field
                .as_deref()
                .is_some_and(|f| f.starts_with(field) || field.starts_with(f)),
            "{bad}: {e}"
        );
    }
}
