//! Rendering from the command line: `rtmpm render OUTDIR` (PLY frames on disk) and
//! `rtmpm run SCENE --render / --preview PNG` (particles in memory, rendered on a background
//! thread while the simulation goes on). Frames become `frame_NNNNN.png`, the run a looping
//! `movie.gif` and, when `ffmpeg` is on the PATH, `movie.mp4`.

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use rtmpm_geometry::Collider;
use rtmpm_geometry::Shape;
use rtmpm_geometry::surface::TriMesh;
use rtmpm_io::ply::read_ply;
use rtmpm_physics::Particles;
use rtmpm_physics::math::Vec3;
use rtmpm_render::{
    Camera, GifMovie, RenderInput, RenderOptions, colormap, estimate_radius, render,
};
use rtmpm_scene::{ColorBy, Scene};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{SyncSender, sync_channel};
use std::thread::JoinHandle;
use std::time::Instant;

/// Camera, image and colouring flags shared by `render` and `run --render`. Each overrides the
/// scene's `[render]` table, which overrides the defaults.
#[derive(Args, Clone, Debug, Default)]
pub struct ViewArgs {
    /// Camera position `x,y,z` (m). Default: front-right-above, framing the domain.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, value_name = "X,Y,Z")]
    pub camera: Option<Vec3>,
    /// Point the camera looks at `x,y,z` (m). Default: the domain centre.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, value_name = "X,Y,Z")]
    pub target: Option<Vec3>,
    /// Vertical field of view (degrees, default 40).
    #[arg(long, value_name = "DEG")]
    pub fov: Option<f32>,
    /// Image size (default 1280x720).
    #[arg(long, value_parser = parse_size, value_name = "WxH")]
    pub size: Option<Size>,
    /// Colour by material (default) or by a field: speed, J, stress (von Mises), plastic.
    #[arg(long, value_name = "FIELD")]
    pub color_by: Option<ColorBy>,
    /// Fixed colour range `lo,hi` of the field (default: 1st-99th percentile per frame).
    #[arg(long, value_parser = parse_range, allow_hyphen_values = true, value_name = "LO,HI")]
    pub range: Option<(f32, f32)>,
    /// Particle radius (m). Default: from the particle spacing.
    #[arg(long, value_name = "M")]
    pub radius: Option<f32>,
    /// Size of movie.gif (default 640x360).
    #[arg(long, value_parser = parse_size, value_name = "WxH")]
    pub gif_size: Option<Size>,
    /// Write no movie (movie.gif, movie.mp4).
    #[arg(long)]
    pub no_movie: bool,
    /// No shadows (a little faster).
    #[arg(long)]
    pub no_shadows: bool,
    /// Do not draw the scene's colliders (drawn grey by default).
    #[arg(long)]
    pub no_colliders: bool,
    /// Draw fluids as particles, not as their reconstructed surface (the default when this
    /// build has fluid surfaces and the scene has a surface material).
    #[arg(long)]
    pub particles: bool,
}

/// An image size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Size(pub u32, pub u32);

pub(crate) fn parse_size(s: &str) -> Result<Size, String> {
    let bad = || format!("expected WIDTHxHEIGHT such as 1280x720, got `{s}`");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let w: u32 = w.trim().parse().map_err(|_| bad())?;
    let h: u32 = h.trim().parse().map_err(|_| bad())?;
    if !(16..=8192).contains(&w) || !(16..=8192).contains(&h) {
        return Err(format!(
            "image size {w}x{h} out of range (16 to 8192 per side)"
        ));
    }
    Ok(Size(w, h))
}

pub(crate) fn parse_floats(s: &str, n: usize) -> Result<Vec<f32>, String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("expected {n} comma-separated numbers, got `{s}`"))?;
    if v.len() != n || v.iter().any(|x| !x.is_finite()) {
        return Err(format!(
            "expected {n} comma-separated finite numbers, got `{s}`"
        ));
    }
    Ok(v)
}

pub(crate) fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let v = parse_floats(s, 3)?;
    Ok(Vec3::new(v[0], v[1], v[2]))
}

pub(crate) fn parse_range(s: &str) -> Result<(f32, f32), String> {
    let v = parse_floats(s, 2)?;
    if v[1] <= v[0] {
        return Err(format!("range `{s}`: hi must be above lo"));
    }
    Ok((v[0], v[1]))
}

/// Where a picture's camera comes from, for its errors.
pub(crate) const CAMERA_FIELDS: &str = "--camera, --target, --fov or the scene's [render]";

/// Refuse a camera so far from the box `bounds` (what it is to show: `what`) that the box would
/// span less than a pixel of a picture `height` pixels high: every picture would be empty.
pub(crate) fn check_camera_sees(
    camera: &Camera,
    bounds: (Vec3, Vec3),
    height: u32,
    what: &str,
) -> Result<()> {
    let pixels = camera.pixels_across(bounds.0, bounds.1, height);
    if pixels < 1.0 {
        let p = camera.position;
        let centre = 0.5 * (bounds.0 + bounds.1);
        bail!(
            "the camera at ({}, {}, {}) ({CAMERA_FIELDS}) is {:.3e} m from {what} ({:.3} m \
             across): with a field of view of {} degrees they would span {pixels:.1e} pixels of \
             the {height}-pixel-high picture, which would show nothing\n  fix: move the camera \
             closer or narrow the field of view, or leave --camera and --fov out to frame them",
            p.x,
            p.y,
            p.z,
            (p.as_dvec3() - centre.as_dvec3()).length(),
            (bounds.1 - bounds.0).length(),
            camera.fov_deg
        );
    }
    Ok(())
}

/// Resolve the render options: flags, then the scene's `[render]`, then defaults. `bounds` is
/// the box the particles live in, `floor` the ground height.
fn resolve(
    view: &ViewArgs,
    scene: Option<&Scene>,
    bounds: (Vec3, Vec3),
    floor: f32,
    radius: f32,
) -> Result<RenderOptions> {
    let sr = scene.map(|s| s.render.clone()).unwrap_or_default();
    let (width, height) = match (view.size, sr.width, sr.height) {
        (Some(Size(w, h)), _, _) => (w, h),
        (None, Some(w), Some(h)) => (w, h),
        (None, Some(w), None) => (w, (w * 9 / 16).max(16)),
        (None, None, Some(h)) => ((h * 16 / 9).max(16), h),
        (None, None, None) => (1280, 720),
    };
    let fov = view.fov.or(sr.fov).unwrap_or(Camera::DEFAULT_FOV);
    let mut camera = Camera::framing(bounds.0, bounds.1, width as f32 / height as f32, fov);
    if let Some(t) = view.target.or(sr.target) {
        camera.target = t;
    }
    if let Some(c) = view.camera.or(sr.camera) {
        camera.position = c;
    }
    camera
        .check()
        .map_err(|e| anyhow!("bad camera ({CAMERA_FIELDS}): {e}"))?;
    check_camera_sees(&camera, bounds, height, "the particles")?;
    let radius = view.radius.unwrap_or(radius);
    if !(radius.is_finite() && radius > 0.0) {
        bail!("--radius must be a positive length, got {radius}");
    }
    // A sphere wider than everything drawn covers the whole picture: every particle would be
    // drawn over every pixel (hours for a large frame), and the picture shows nothing.
    let across = (bounds.1 - bounds.0).max_element();
    if view.radius.is_some() && across.is_finite() && radius > across {
        bail!(
            "--radius {radius:e} m is larger than the particles' extent ({across} m across): \
             every particle would cover the picture\n  fix: a radius of about the particle \
             spacing (leave --radius out to take it from the spacing)"
        );
    }
    let mut opts = RenderOptions::new(bounds.0, bounds.1, radius);
    opts.width = width;
    opts.height = height;
    opts.camera = camera;
    opts.color_by = view.color_by.or(sr.color_by).unwrap_or_default();
    opts.range = view.range;
    if view.range.is_some() && opts.color_by == ColorBy::Material {
        eprintln!(
            "warning: --range is the colour range of a field (--color-by speed, J, stress or \
             plastic); these pictures are coloured by material, which ignores it"
        );
    }
    if view.no_movie && view.gif_size.is_some() {
        eprintln!("warning: --gif-size sizes movie.gif, which --no-movie leaves out");
    }
    opts.floor = Some(floor);
    opts.shadows = !view.no_shadows;
    if let Some(s) = scene {
        opts.palette = colormap::scene_palette(s);
        if !view.no_colliders {
            opts.colliders = s.colliders.clone();
        }
    }
    Ok(opts)
}

pub mod cmd;
mod frame;
pub mod wedge;

use frame::read_bodies_csv;
pub use frame::{FrameJob, SurfaceJob};

/// Where rendered frames go.
struct Sink {
    opts: RenderOptions,
    /// The scene's colliders (each frame adds its rigid bodies to them).
    colliders: Vec<rtmpm_geometry::Collider>,
    /// False with `--no-colliders`: neither colliders nor bodies are drawn.
    draw_bodies: bool,
    /// Folder of `frame_NNNNN.png` (None: preview only).
    dir: Option<PathBuf>,
    preview: Option<PathBuf>,
    gif: Option<GifMovie>,
    first_frame: Option<u64>,
    frames: usize,
    render_s: f64,
}

impl Sink {
    fn new(
        opts: RenderOptions,
        dir: Option<PathBuf>,
        preview: Option<PathBuf>,
        view: &ViewArgs,
        fps: f32,
    ) -> Result<Sink> {
        let gif = match (&dir, view.no_movie) {
            (Some(_), false) => {
                let Size(w, h) = view.gif_size.unwrap_or(Size(640, 360));
                Some(GifMovie::new(w, h, fps)?)
            }
            _ => None,
        };
        Ok(Sink {
            colliders: opts.colliders.clone(),
            draw_bodies: !view.no_colliders,
            opts,
            dir,
            preview,
            gif,
            first_frame: None,
            frames: 0,
            render_s: 0.0,
        })
    }

    fn process(&mut self, job: FrameJob) -> Result<()> {
        self.opts.label = Some(match job.time {
            Some(t) => format!("FRAME {}  T = {:.3} S", job.frame, t),
            None => format!("FRAME {}", job.frame),
        });
        // Moving colliders are posed at the frame's time; rigid bodies at this frame's poses.
        self.opts.time = job.time.unwrap_or(0.0) as f32;
        if self.draw_bodies {
            self.opts.colliders = self.colliders.clone();
            self.opts.colliders.extend(job.bodies.iter().cloned());
        }
        let t0 = Instant::now();
        let surface = match job.surface {
            SurfaceJob::None => None,
            SurfaceJob::Ready(m, mat) => Some((m, mat)),
            SurfaceJob::Build(xs, params, mat) => {
                Some((rtmpm_driver::output::reconstruct_points(&xs, &params)?, mat))
            }
        };
        let img = render(
            &RenderInput {
                positions: &job.positions,
                material: &job.material,
                field: job.field.as_deref(),
                surface: surface.as_ref().map(|(m, k)| (m, *k)),
            },
            &self.opts,
        )
        .with_context(|| format!("rendering frame {}", job.frame))?;
        self.render_s += t0.elapsed().as_secs_f64();
        if let Some(dir) = &self.dir {
            let path = dir.join(format!("frame_{:05}.png", job.frame));
            img.write_png(&path)
                .with_context(|| format!("writing {}", path.display()))?;
        }
        if let Some(p) = &self.preview {
            img.write_png(p)
                .with_context(|| format!("writing preview {}", p.display()))?;
        }
        if let Some(g) = self.gif.as_mut() {
            g.add(&img).context("adding a frame to the GIF")?;
        }
        self.first_frame.get_or_insert(job.frame);
        self.frames += 1;
        Ok(())
    }

    /// Write movie.gif and movie.mp4 (with ffmpeg); returns a summary line.
    fn finish(self, fps: f32) -> Result<String> {
        let mut summary = format!(
            "{} frames rendered ({:.3} s per frame)",
            self.frames,
            self.render_s / self.frames.max(1) as f64
        );
        let (Some(dir), Some(gif), Some(first)) = (&self.dir, self.gif, self.first_frame) else {
            return Ok(summary);
        };
        let path = dir.join("movie.gif");
        gif.finish(&path)
            .with_context(|| format!("writing {}", path.display()))?;
        summary.push_str(&format!(", {}", path.display()));
        match ffmpeg_mp4(dir, first, fps) {
            Ok(Some(mp4)) => summary.push_str(&format!(", {}", mp4.display())),
            Ok(None) => summary.push_str(" (no ffmpeg on the PATH: movie.mp4 skipped)"),
            Err(e) => eprintln!("warning: movie.mp4 not written: {e:#}"),
        }
        Ok(summary)
    }
}

/// Encode `dir/frame_%05d.png` from frame `first` into `dir/movie.mp4` with ffmpeg; `None` when
/// ffmpeg is not installed.
fn ffmpeg_mp4(dir: &Path, first: u64, fps: f32) -> Result<Option<PathBuf>> {
    use std::process::{Command, Stdio};
    let found = Command::new("ffmpeg")
        .arg("-version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !found {
        return Ok(None);
    }
    let out = dir.join("movie.mp4");
    let tmp = dir.join(".movie.tmp.mp4");
    let status = Command::new("ffmpeg")
        .args(["-y", "-loglevel", "error", "-framerate"])
        .arg(format!("{fps}"))
        .args(["-start_number", &first.to_string(), "-i"])
        .arg(dir.join("frame_%05d.png"))
        .args([
            "-vf",
            "pad=ceil(iw/2)*2:ceil(ih/2)*2",
            "-pix_fmt",
            "yuv420p",
        ])
        .arg(&tmp)
        .stdin(Stdio::null())
        .status()
        .context("running ffmpeg")?;
    if !status.success() {
        let _ = std::fs::remove_file(&tmp);
        bail!("ffmpeg failed ({status})");
    }
    std::fs::rename(&tmp, &out).with_context(|| format!("renaming to {}", out.display()))?;
    Ok(Some(out))
}

/// Whether pictures of `scene` show its fluids as surfaces.
fn draws_surfaces(view: &ViewArgs, scene: &Scene) -> bool {
    rtmpm_geometry::surface::AVAILABLE
        && !view.particles
        && !scene.output.surface.materials.is_empty()
}

/// Bounds (the box the particles live in) and ground height of a scene.
fn scene_bounds(scene: &Scene) -> ((Vec3, Vec3), f32) {
    let (lo, hi) = scene.interior();
    ((lo, hi), lo.y)
}

// ---------------------------------------------------------------- rtmpm run --render

/// Renders the frames of `rtmpm run` on a background thread (bounded queue of 2 frames, so the
/// simulation runs ahead by at most that much).
pub struct RunRenderer {
    tx: Option<SyncSender<FrameJob>>,
    handle: Option<JoinHandle<Result<String>>>,
    setup: Option<(ViewArgs, Option<PathBuf>, Option<PathBuf>, f32)>,
    color_by: ColorBy,
    /// Mean initial volume of the surface particles, when fluids are drawn as surfaces.
    surface_volume: Option<f32>,
}

impl RunRenderer {
    /// `None` unless `--render` or `--preview` was given. Frames go to `out_dir` with
    /// `--render`, the preview to `preview`.
    pub fn new(
        render: bool,
        preview: Option<PathBuf>,
        view: &ViewArgs,
        out_dir: &Path,
        scene: &Scene,
    ) -> Option<RunRenderer> {
        if !render && preview.is_none() {
            return None;
        }
        let color_by = view.color_by.or(scene.render.color_by).unwrap_or_default();
        Some(RunRenderer {
            tx: None,
            handle: None,
            setup: Some((
                view.clone(),
                render.then(|| out_dir.to_path_buf()),
                preview,
                scene.time.fps,
            )),
            color_by,
            surface_volume: draws_surfaces(view, scene).then_some(0.0),
        })
    }

    /// Queue frame `frame` (blocks while two frames are waiting). The first call starts the
    /// thread, taking the particle radius from the particles' initial volumes.
    pub fn submit(
        &mut self,
        frame: u64,
        time: f64,
        p: &Particles,
        scene: &Scene,
        mesh: Option<TriMesh>,
        bodies: &[rtmpm_rigid::BodyState],
    ) -> Result<()> {
        if let Some((view, dir, preview, fps)) = self.setup.take() {
            let mean_vol = p.vol0.iter().map(|&v| v as f64).sum::<f64>() / p.len().max(1) as f64;
            let radius = if mean_vol > 0.0 {
                0.6 * (mean_vol as f32).cbrt()
            } else {
                estimate_radius(&p.x)
            };
            // No particles yet (a scene that only emits): the splat of 8 particles a cell.
            let radius = if radius > 0.0 { radius } else { 0.3 * scene.dx };
            let (bounds, floor) = scene_bounds(scene);
            let opts = resolve(&view, Some(scene), bounds, floor, radius)?;
            let mut sink = Sink::new(opts, dir, preview, &view, fps)?;
            let (tx, rx) = sync_channel::<FrameJob>(2);
            self.tx = Some(tx);
            self.handle = Some(
                std::thread::Builder::new()
                    .name("render".into())
                    .spawn(move || {
                        for job in rx {
                            sink.process(job)?;
                        }
                        sink.finish(fps)
                    })
                    .context("starting the render thread")?,
            );
        }
        // The surface particles' volume, from the first frame that has any (a scene may only
        // emit its fluid later).
        if self.surface_volume == Some(0.0) {
            self.surface_volume = Some(scene.output.surface.select(p).1);
        }
        let mut job =
            FrameJob::from_particles(frame, time, p, scene, self.color_by).with_bodies(bodies);
        if let Some(vol) = self.surface_volume.filter(|&v| v > 0.0) {
            job = job.with_surface(&scene.output.surface, vol, mesh);
        }
        let sent = self.tx.as_ref().is_some_and(|tx| tx.send(job).is_ok());
        if !sent {
            // The thread stopped: report its error.
            self.tx = None;
            return match self.handle.take().map(|h| h.join()) {
                Some(Ok(Err(e))) => Err(e),
                Some(Err(_)) => bail!("the render thread panicked"),
                _ => bail!("the render thread stopped"),
            };
        }
        Ok(())
    }

    /// Wait for the queued frames, write the movies; returns a summary line.
    pub fn finish(mut self) -> Result<Option<String>> {
        self.tx = None;
        match self.handle.take().map(|h| h.join()) {
            None => Ok(None),
            Some(Ok(r)) => r.map(Some),
            Some(Err(_)) => bail!("the render thread panicked"),
        }
    }
}
