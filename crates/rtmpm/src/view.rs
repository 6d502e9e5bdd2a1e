//! `rtmpm view SCENE`: run a scene and watch and steer it live, in a browser (`--serve`), or
//! record what the view shows (`--record`).

use crate::backend::{BackendKind, make_backend};
use crate::render::{Size, parse_range, parse_size, parse_vec3};
use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use rtmpm_driver::Simulation;
use rtmpm_physics::Particles;
use rtmpm_render::Camera;
use rtmpm_scene::ColorBy;
use rtmpm_scene::Scene;
use rtmpm_view::serve::{DEFAULT_ADDR, ServeOptions};
use rtmpm_view::{Pace, Recorder, Session, SessionOptions, SimFactory};
use std::path::PathBuf;
use std::time::Duration;

/// The initial particles are kept for resets up to this many (else sampled again).
const KEEP_FOR_RESET: usize = 20_000_000;

#[derive(Args, Debug)]
#[command(after_help = "\
With a display, the view opens in a window; --serve streams it to a browser instead.
Controls (window and browser): left drag orbits, right drag (or Shift+drag) drags the tool
through the material (the wheel pushes it deeper while held), middle drag (or Ctrl+drag)
pans, the wheel zooms; Space pauses, S steps, R resets, - and + change the pace, C the
colours, T throws a ball of the chosen material at the cursor; buttons set gravity (in the
window: 1 to 5 choose the colours, G steps through gravity presets, Home resets the camera,
Q or Esc closes).

Watch a run on a remote GPU server: start it there with --serve (it listens on
127.0.0.1 only), then on your machine `ssh -L 8080:localhost:8080 gpu-host` and open
http://localhost:8080/ . See docs/viewer.md.")]
pub struct ViewArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Serve the view to a browser at this address (default 127.0.0.1:8080: this machine
    /// only); then open http://ADDR/ in a browser.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = DEFAULT_ADDR)]
    pub serve: Option<String>,
    /// No window even where a display is present (with --record: record only).
    #[arg(long)]
    pub no_window: bool,
    /// Record what the view shows to FILE.gif or FILE.mp4 (MP4 through ffmpeg).
    #[arg(long, value_name = "FILE")]
    pub record: Option<PathBuf>,
    /// Replace the --record file if it exists.
    #[arg(long)]
    pub overwrite: bool,
    /// End after this many simulated frames (default: run until stopped with Ctrl-C; a recording without a window or --serve: the scene's duration x fps)
    #[arg(long, value_name = "N")]
    pub frames: Option<u64>,
    /// Backend.
    #[arg(long, value_enum, default_value_t = BackendKind::Auto)]
    pub backend: BackendKind,
    /// CPU worker threads (default: one per core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Picture size.
    #[arg(long, value_parser = parse_size, value_name = "WxH", default_value = "1280x720")]
    pub size: Size,
    /// Colour by material (default) or by a field: speed, J, stress, plastic.
    #[arg(long, value_name = "FIELD")]
    pub color_by: Option<ColorBy>,
    /// Fixed colour range `lo,hi` of the field (default: per frame).
    #[arg(long, value_parser = parse_range, allow_hyphen_values = true, value_name = "LO,HI")]
    pub range: Option<(f32, f32)>,
    /// Particle radius (m). Default: from the particle spacing.
    #[arg(long, value_name = "M")]
    pub radius: Option<f32>,
    /// Camera position `x,y,z` (m). Default: framing the domain.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, value_name = "X,Y,Z")]
    pub camera: Option<glam::Vec3>,
    /// Point the camera looks at `x,y,z` (m). Default: the domain centre.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, value_name = "X,Y,Z")]
    pub target: Option<glam::Vec3>,
    /// Vertical field of view (degrees, default 40).
    #[arg(long, value_name = "DEG")]
    pub fov: Option<f32>,
    /// Start paused.
    #[arg(long)]
    pub paused: bool,
    /// Simulation between two pictures: `frames:N` (default frames:1, every frame shown)
    /// or `steps:N` (slow motion).
    #[arg(long, value_parser = parse_pace, value_name = "frames:N|steps:N")]
    pub pace: Option<Pace>,
    /// JPEG quality of the browser stream (1 to 100).
    #[arg(long, value_name = "Q", default_value_t = rtmpm_view::jpeg::DEFAULT_QUALITY,
          value_parser = clap::value_parser!(u8).range(1..=100))]
    pub quality: u8,
    /// No shadows (a faster CPU picture).
    #[arg(long)]
    pub no_shadows: bool,
    /// No heads-up line in the picture.
    #[arg(long)]
    pub no_hud: bool,
}

fn parse_pace(s: &str) -> Result<Pace, String> {
    let bad = || {
        format!(
            "expected frames:N or steps:N (N from 1 to {}), got `{s}`",
            rtmpm_view::command::MAX_PACE
        )
    };
    let (kind, n) = s.split_once(':').ok_or_else(bad)?;
    let n: u32 = n.trim().parse().map_err(|_| bad())?;
    if !(1..=rtmpm_view::command::MAX_PACE).contains(&n) {
        return Err(bad());
    }
    match kind.trim() {
        "frames" => Ok(Pace::Frames(n)),
        "steps" => Ok(Pace::Steps(n)),
        _ => Err(bad()),
    }
}

/// Where the view goes.
enum Front {
    Browser(std::net::TcpListener),
    /// A native window (a display is present).
    Window,
    /// Only the recording.
    Recording,
}

/// The front-end the flags ask for, or how to get one.
fn front(args: &ViewArgs) -> Result<Front> {
    if let Some(addr) = &args.serve {
        let addr = rtmpm_view::serve::parse_addr(addr).map_err(|e| anyhow!(e))?;
        let listener = rtmpm_view::serve::bind(addr).map_err(|e| anyhow!(e))?;
        if !addr.ip().is_loopback() {
            eprintln!(
                "warning: serving on {addr}: anyone who can reach this machine can watch and \
                 steer the run; prefer 127.0.0.1 and an SSH tunnel (docs/viewer.md)"
            );
        }
        return Ok(Front::Browser(listener));
    }
    if !args.no_window && rtmpm_view::window::display_present() {
        return Ok(Front::Window);
    }
    if args.record.is_some() {
        return Ok(Front::Recording);
    }
    let scene = args.scene.display();
    let how = format!(
        "watch it in a browser: `rtmpm view {scene} --serve` and open http://{DEFAULT_ADDR}/ \
         (on a remote machine: `ssh -L 8080:localhost:8080 HOST` from yours, then open \
         http://localhost:8080/ there); or record it: `rtmpm view {scene} --record movie.mp4 \
         --frames 120`"
    );
    if args.no_window {
        bail!("--no-window without --serve or --record shows nothing: {how}");
    }
    bail!("no display here (DISPLAY and WAYLAND_DISPLAY are not set), so no window can open: {how}")
}

/// The session's simulations: the scene's initial state on the chosen backend, the sampled
/// particles kept for resets.
fn factory(scene: Scene, args: &ViewArgs) -> SimFactory {
    let (kind, threads) = (args.backend, args.threads);
    let cuda = rtmpm_cuda::CudaOptions::default();
    let mut kept: Option<Particles> = None;
    // What `auto` picked, for the resets (which then say nothing).
    let mut resolved: Option<BackendKind> = None;
    Box::new(move || {
        let particles = match &kept {
            Some(p) => p.clone(),
            None => {
                let (p, _) = rtmpm_driver::setup::sample(&scene).map_err(|e| format!("{e:#}"))?;
                if resolved.is_none() && p.len() <= KEEP_FOR_RESET {
                    kept = Some(p.clone());
                }
                p
            }
        };
        let n = particles.len();
        let backend = make_backend(resolved.unwrap_or(kind), &scene, particles, threads, &cuda)
            .map_err(|e| format!("{e:#}"))?;
        if resolved.is_none() {
            eprintln!(
                "view: `{}`, {n} particles on {}",
                scene.name,
                backend.name()
            );
            resolved = Some(if backend.name().starts_with("cpu") {
                BackendKind::Cpu
            } else {
                BackendKind::Cuda
            });
        }
        Ok(Simulation::new(scene.clone(), backend))
    })
}

pub fn view(args: ViewArgs) -> Result<()> {
    if args.frames == Some(0) {
        bail!("--frames must be at least 1");
    }
    let scene = Scene::from_file(&args.scene)?;
    crate::budget::enforce(&scene, args.frames, None)?;
    let front = front(&args)?;
    // A recording without a window or a server: nothing can resume a pause, so it runs to its
    // --frames, else to the scene's end (where a view pauses), then ends.
    let headless = matches!(front, Front::Recording);
    if headless && args.paused {
        bail!(
            "--paused with a recording and no window or --serve: nothing could resume it, and \
             the recording would wait for ever\n  fix: leave --paused out, or add --serve to \
             steer it from a browser"
        );
    }
    let max_frames = match args.frames {
        None if headless => Some(scene.time.frames()),
        n => n,
    };
    let recorder = match &args.record {
        Some(path) => {
            Some(Recorder::start(path, scene.time.fps, args.overwrite).map_err(|e| anyhow!(e))?)
        }
        None => None,
    };
    let Size(width, height) = args.size;
    let camera = picture_camera(&args, &scene)?;
    let options = SessionOptions {
        width,
        height,
        color_by: args.color_by.or(scene.render.color_by).unwrap_or_default(),
        range: args.range,
        radius: args.radius,
        camera: Some(camera),
        pace: args.pace.unwrap_or_default(),
        paused: args.paused,
        tool: None,
        max_frames,
        hud: !args.no_hud,
        shadows: !args.no_shadows,
        // RTMPM_VIEW_OVERLAP=0: each picture drawn and published before the next step (the
        // view's cost measured both ways in one binary; rtmpm_cuda::backend::view_overlap);
        // the CPU backend draws on the host.
        overlap: std::env::var("RTMPM_VIEW_OVERLAP").map_or(true, |v| v.trim() != "0"),
    };
    let session = Session::start(factory(scene, &args), options, recorder)
        .map_err(|e| anyhow!(e))
        .context("cannot start the view")?;
    let summary = match front {
        Front::Window => {
            let opts = rtmpm_view::window::WindowOptions {
                title: format!("rtmpm view: {}", session.info.name),
            };
            rtmpm_view::window::run(session, opts).map_err(|e| anyhow!(e))?
        }
        Front::Browser(listener) => {
            let addr = listener.local_addr().context("the server's address")?;
            eprintln!("view: open http://{addr}/ to watch and steer (Ctrl-C ends)");
            let opts = ServeOptions {
                quality: args.quality,
                ..Default::default()
            };
            rtmpm_view::serve::serve(listener, &session, &opts, rtmpm_view::serve::interrupted())
                .map_err(|e| anyhow!(e))?;
            session.finish().map_err(|e| anyhow!(e))?
        }
        Front::Recording => {
            eprintln!(
                "view: recording {} frames (Ctrl-C ends sooner)",
                max_frames.unwrap_or(0)
            );
            rtmpm_view::serve::until_ended_or_interrupted(&session, Duration::from_millis(100))
                .map_err(|e| anyhow!(e))?;
            session.finish().map_err(|e| anyhow!(e))?
        }
    };
    report(&summary)
}

/// The live view's camera, framing the scene's interior (or where `--camera` and `--target`
/// put it), once the picture's `--size` and `--radius` are checked.
fn picture_camera(args: &ViewArgs, scene: &Scene) -> Result<Camera> {
    let (lo, hi) = scene.interior();
    let Size(width, height) = args.size;
    let most = rtmpm_render::MAX_VIEW_SIDE;
    if width > most || height > most {
        bail!("--size {width}x{height} is too large for a live view: at most {most} per side");
    }
    let camera = {
        let mut c = Camera::framing(
            lo,
            hi,
            width as f32 / height as f32,
            args.fov.unwrap_or(Camera::DEFAULT_FOV),
        );
        if let Some(t) = args.target {
            c.target = t;
        }
        if let Some(p) = args.camera {
            c.position = p;
        }
        c.check()
            .map_err(|e| anyhow!("bad camera ({}): {e}", crate::render::CAMERA_FIELDS))?;
        crate::render::check_camera_sees(&c, (lo, hi), height, "the scene's domain")?;
        c
    };
    if let Some(r) = args.radius
        && !(r.is_finite() && r > 0.0)
    {
        bail!("--radius must be a positive length, got {r}");
    }
    if let Some(r) = args.radius
        && r > (hi - lo).max_element()
    {
        bail!(
            "--radius {r:e} m is larger than the domain's interior ({} m across): every particle \
             would cover the picture\n  fix: a radius of about the particle spacing (leave \
             --radius out for 0.6 of it)",
            (hi - lo).max_element()
        );
    }
    Ok(camera)
}

/// The session's summary on stderr: pictures, frames, the step time with the view on, why the
/// simulation stopped, and the recording (an error when it failed).
fn report(summary: &rtmpm_view::Summary) -> Result<()> {
    eprintln!(
        "view: {} pictures shown, {} frames ({} steps, t = {:.4} s)",
        summary.displayed, summary.frames, summary.steps, summary.time
    );
    let t = &summary.timing;
    if t.steps > 0 {
        eprintln!(
            "view: after the first frame, {} steps in {:.3} s: {:.4} ms/step with the view on",
            t.steps,
            t.wall_s,
            t.ms_per_step()
        );
        eprintln!("{}", t.line());
    }
    if let Some(e) = &summary.error {
        eprintln!("view: the simulation stopped: {e}");
    }
    match &summary.recording {
        Some(Ok(line)) => eprintln!("view: recorded {line}"),
        Some(Err(e)) => bail!("{e}"),
        None => {}
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paces_parse_with_their_range() {
        assert_eq!(parse_pace("frames:2"), Ok(Pace::Frames(2)));
        assert_eq!(parse_pace("steps:1"), Ok(Pace::Steps(1)));
        for bad in [
            "",
            "frames",
            "frames:0",
            "steps:x",
            "laps:3",
            "steps:100000",
        ] {
            assert!(parse_pace(bad).is_err(), "{bad}");
        }
    }
}
