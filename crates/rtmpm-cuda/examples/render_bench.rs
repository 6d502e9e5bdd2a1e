//! The render stage's cost against the simulation's, on one GPU (the `view` suite of
//! `scripts/gpu/run.sh`):
//!
//! `render_bench SCENE.toml [--frames N] [--size WxH] [--reps R] [--color material,speed]`
//!
//! 1. a warm-up frame and a warm-up picture;
//! 2. N frames without pictures: the simulation's compute time per displayed frame (host clock;
//!    a frame ends with the health check, which waits for the GPU);
//! 3. R pictures of that state per colour mode: the kernels and the copy of the image to
//!    page-locked memory (CUDA events), and the whole call (host clock);
//! 4. N frames each followed by a picture: the frame time with the viewer on.
//!
//! The last line sums it up: picture time as a share of the frame's compute (target: at most
//! 10 %) and the frame time with the viewer on against off.

use rtmpm_cuda::{CudaBackend, CudaOptions};
use rtmpm_driver::Simulation;
use rtmpm_render::{Camera, Image, RenderOptions, colormap, estimate_radius};
use rtmpm_scene::{ColorBy, Scene};
use std::time::Instant;

struct Args {
    scene: String,
    frames: u32,
    size: (u32, u32),
    reps: u32,
    colors: Vec<ColorBy>,
}

fn args() -> Result<Args, String> {
    let mut a = Args {
        scene: String::new(),
        frames: 10,
        size: (1280, 720),
        reps: 20,
        colors: vec![ColorBy::Material, ColorBy::Speed],
    };
    let mut it = std::env::args().skip(1);
    while let Some(x) = it.next() {
        let mut val = || it.next().ok_or(format!("{x} needs a value"));
        match x.as_str() {
            "--frames" => a.frames = val()?.parse().map_err(|e| format!("--frames: {e}"))?,
            "--reps" => a.reps = val()?.parse().map_err(|e| format!("--reps: {e}"))?,
            "--size" => {
                let v = val()?;
                let (w, h) = v.split_once('x').ok_or("--size WxH")?;
                a.size = (
                    w.parse().map_err(|e| format!("--size: {e}"))?,
                    h.parse().map_err(|e| format!("--size: {e}"))?,
                );
            }
            "--color" => {
                a.colors = val()?
                    .split(',')
                    .map(|c| c.parse::<ColorBy>())
                    .collect::<Result<_, _>>()?;
            }
            s if a.scene.is_empty() && !s.starts_with('-') => a.scene = s.to_string(),
            s => return Err(format!("unknown argument {s}")),
        }
    }
    if a.scene.is_empty() {
        return Err("usage: render_bench SCENE.toml [--frames N] [--size WxH] [--reps R] [--color material,speed]".into());
    }
    Ok(a)
}

/// Milliseconds per frame of `frames` frames without and with a picture after each, the two kinds
/// alternating so that both see the same stretch of the scene (a dam break slows as it spreads).
fn frames_off_on(
    sim: &mut Simulation<CudaBackend>,
    frames: u32,
    picture: &RenderOptions,
    img: &mut Image,
) -> Result<(f64, f64), String> {
    let (mut off, mut on) = (0.0, 0.0);
    for _ in 0..frames.max(1) {
        off += self::frames(sim, 1, None, img)?;
        on += self::frames(sim, 1, Some(picture), img)?;
    }
    Ok((off / frames.max(1) as f64, on / frames.max(1) as f64))
}

/// Milliseconds per frame of `frames` frames, with a picture after each when `picture`.
fn frames(
    sim: &mut Simulation<CudaBackend>,
    frames: u32,
    picture: Option<&RenderOptions>,
    img: &mut Image,
) -> Result<f64, String> {
    let t0 = Instant::now();
    for _ in 0..frames {
        sim.advance_frame().map_err(|e| e.to_string())?;
        if let Some(o) = picture {
            let mut o = o.clone();
            o.time = sim.time as f32;
            sim.backend
                .render_picture(&o, true, img)
                .map_err(|e| e.to_string())?;
        }
    }
    Ok(t0.elapsed().as_secs_f64() * 1e3 / frames.max(1) as f64)
}

fn run(a: &Args) -> Result<(), String> {
    let scene = Scene::from_file(std::path::Path::new(&a.scene)).map_err(|e| e.to_string())?;
    let p = scene.sample_particles().map_err(|e| e.to_string())?;
    let radius = estimate_radius(&p.x);
    let backend =
        CudaBackend::new(&scene, &p, CudaOptions::default()).map_err(|e| e.to_string())?;
    drop(p);
    let mut sim = Simulation::with_backend(scene.clone(), Box::new(backend));
    let (lo, hi) = scene.interior();
    let (w, h) = a.size;
    let mut base = RenderOptions::new(lo, hi, radius);
    base.width = w;
    base.height = h;
    base.camera = Camera::framing(lo, hi, w as f32 / h as f32, Camera::DEFAULT_FOV);
    base.palette = colormap::scene_palette(&scene);
    base.colliders = scene.colliders.clone();
    let mut img = Image::new(1, 1, [0, 0, 0]);
    frames(&mut sim, 1, Some(&base), &mut img)?;
    let steps0 = sim.step;
    let off = frames(&mut sim, a.frames, None, &mut img)?;
    let steps = (sim.step - steps0) as f64 / a.frames.max(1) as f64;
    let n = sim.scene.bodies.len();
    println!(
        "{}: {} particles ({n} bodies), {steps:.0} steps a frame, {w}x{h}, radius {radius:.5} m",
        scene.name,
        sim.backend.len()
    );
    println!(
        "frame, viewer off: {off:.3} ms ({:.4} ms/step)",
        off / steps.max(1.0)
    );
    let mut first = None;
    for &c in &a.colors {
        let mut o = base.clone();
        o.color_by = c;
        o.time = sim.time as f32;
        let mut t = Vec::new();
        for _ in 0..a.reps.max(1) {
            t.push(
                sim.backend
                    .time_picture(&o, true, &mut img)
                    .map_err(|e| e.to_string())?,
            );
        }
        let med = |f: &dyn Fn(&rtmpm_cuda::view::render::RenderTiming) -> f64| {
            let mut v: Vec<f64> = t.iter().map(f).collect();
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let (k, cp, tot) = (
            med(&|t| t.kernels_ms),
            med(&|t| t.copy_ms),
            med(&|t| t.total_ms),
        );
        println!(
            "picture {c}: kernels {k:.3} ms, copy {cp:.3} ms, whole call {tot:.3} ms (median of {}); \
             kernels + copy = {:.1} % of the frame's compute",
            t.len(),
            100.0 * (k + cp) / off
        );
        if let Some(dir) = std::env::var_os("RTMPM_BENCH_OUT") {
            let path = std::path::Path::new(&dir).join(format!("{}_{c}.png", scene.name));
            img.write_png(&path).map_err(|e| e.to_string())?;
        }
        first.get_or_insert((c, k, cp, tot));
    }
    let (off, on) = frames_off_on(&mut sim, a.frames, &base, &mut img)?;
    println!(
        "frames alternating: viewer off {off:.3} ms, on (a {} picture a frame) {on:.3} ms",
        base.color_by
    );
    if let Some((c, k, cp, tot)) = first {
        println!(
            "render_bench {}: n={} frame_off_ms={off:.3} frame_on_ms={on:.3} viewer_cost={:.1}% \
             picture_{c}_ms={:.3} (kernels {k:.3} copy {cp:.3} call {tot:.3}) share_of_frame={:.1}% target<=10%",
            scene.name,
            sim.backend.len(),
            100.0 * (on / off - 1.0),
            k + cp,
            100.0 * (k + cp) / off
        );
    }
    Ok(())
}

fn main() {
    match args().and_then(|a| run(&a)) {
        Ok(()) => {}
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
    }
}
