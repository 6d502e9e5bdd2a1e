//! Rendering from the command line: `rtmpm render OUTDIR` (PLY frames on disk) and
//! `rtmpm run SCENE --render / --preview PNG` (particles in memory, rendered on a background
//! thread while the simulation goes on). Frames become `frame_NNNNN.png`, the run a looping
//! `movie.gif` and, when `ffmpeg` is on the PATH, `movie.mp4`.

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use rtmpm_core::boundary::Collider;
use rtmpm_core::boundary::sdf::Shape;
use rtmpm_core::io::ply::{PlyData, read_ply};
use rtmpm_core::math::Vec3;
use rtmpm_core::render::{
    Camera, ColorBy, GifMovie, RenderInput, RenderOptions, colormap, estimate_radius, render,
    von_mises,
};
use rtmpm_core::scene::SurfaceSettings;
use rtmpm_core::surface::{SurfaceParams, TriMesh};
use rtmpm_core::{Particles, Scene};
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

fn parse_size(s: &str) -> Result<Size, String> {
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

fn parse_floats(s: &str, n: usize) -> Result<Vec<f32>, String> {
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

fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let v = parse_floats(s, 3)?;
    Ok(Vec3::new(v[0], v[1], v[2]))
}

fn parse_range(s: &str) -> Result<(f32, f32), String> {
    let v = parse_floats(s, 2)?;
    if v[1] <= v[0] {
        return Err(format!("range `{s}`: hi must be above lo"));
    }
    Ok((v[0], v[1]))
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
    camera.check().map_err(|e| anyhow!("bad camera: {e}"))?;
    let radius = view.radius.unwrap_or(radius);
    if !(radius.is_finite() && radius > 0.0) {
        bail!("--radius must be a positive length, got {radius}");
    }
    let mut opts = RenderOptions::new(bounds.0, bounds.1, radius);
    opts.width = width;
    opts.height = height;
    opts.camera = camera;
    opts.color_by = view.color_by.or(sr.color_by).unwrap_or_default();
    opts.range = view.range;
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

/// The surface of a frame: none, ready, or to be reconstructed on the render thread from
/// these positions.
pub enum SurfaceJob {
    None,
    Ready(TriMesh, u32),
    Build(Vec<Vec3>, SurfaceParams, u32),
}

/// The particles of one frame, owned (sent to the render thread).
pub struct FrameJob {
    frame: u64,
    time: Option<f64>,
    positions: Vec<Vec3>,
    material: Vec<u32>,
    field: Option<Vec<f32>>,
    surface: SurfaceJob,
}

impl FrameJob {
    /// Take the particles of the surface materials out of the splats and arrange their
    /// surface: `mesh` when given, else reconstructed on the render thread from them with
    /// particles of mean volume `volume`.
    fn with_surface(
        mut self,
        settings: &SurfaceSettings,
        volume: f32,
        mesh: Option<TriMesh>,
    ) -> FrameJob {
        let Some(&first) = settings.materials.first() else {
            return self;
        };
        let keep: Vec<bool> = self
            .material
            .iter()
            .map(|m| !settings.materials.contains(m))
            .collect();
        let pick = |v: &[Vec3]| -> Vec<Vec3> {
            v.iter()
                .zip(&keep)
                .filter(|(_, k)| !**k)
                .map(|(x, _)| *x)
                .collect()
        };
        self.surface = match mesh {
            Some(m) => SurfaceJob::Ready(m, first),
            None => SurfaceJob::Build(pick(&self.positions), settings.params(volume), first),
        };
        let mut k = keep.iter();
        self.positions.retain(|_| *k.next().unwrap_or(&true));
        let mut k = keep.iter();
        self.material.retain(|_| *k.next().unwrap_or(&true));
        if let Some(f) = self.field.as_mut() {
            let mut k = keep.iter();
            f.retain(|_| *k.next().unwrap_or(&true));
        }
        self
    }
}

impl FrameJob {
    /// From particles in memory; the field is computed here (stress needs the scene).
    pub fn from_particles(
        frame: u64,
        time: f64,
        p: &Particles,
        scene: &Scene,
        color_by: ColorBy,
    ) -> FrameJob {
        let field = match color_by {
            ColorBy::Material => None,
            ColorBy::Speed => Some(p.v.iter().map(|v| v.length()).collect()),
            ColorBy::J => Some(p.f.iter().map(|f| f.determinant()).collect()),
            ColorBy::Plastic => Some(p.plastic.clone()),
            ColorBy::Stress => Some(
                crate::output::cauchy_stress(p, scene)
                    .into_iter()
                    .map(von_mises)
                    .collect(),
            ),
        };
        FrameJob {
            frame,
            time: Some(time),
            positions: p.x.clone(),
            material: p.material.clone(),
            field,
            surface: SurfaceJob::None,
        }
    }

    /// From a PLY frame written by `rtmpm run`; a missing column is an error with a hint.
    fn from_ply(frame: u64, d: &PlyData, color_by: ColorBy, path: &Path) -> Result<FrameJob> {
        let col = |name: &str| -> Result<&[f32]> {
            d.f32(name).ok_or_else(|| {
                let hint = match name {
                    "J" => " (add fields = [\"J\"] to the scene's [output] table and run again)",
                    s if s.starts_with('s') => {
                        " (add fields = [\"stress\"] to the scene's [output] table and run again)"
                    }
                    _ => "",
                };
                anyhow!("{} has no float column `{name}`{hint}", path.display())
            })
        };
        let (x, y, z) = (col("x")?, col("y")?, col("z")?);
        let positions: Vec<Vec3> = (0..d.count).map(|i| Vec3::new(x[i], y[i], z[i])).collect();
        let material: Vec<u32> = match d.int("material") {
            Some(m) => m
                .iter()
                .map(|&m| m.clamp(0, u32::MAX as i64) as u32)
                .collect(),
            None => vec![0; d.count],
        };
        let field = match color_by {
            ColorBy::Material => None,
            ColorBy::Speed => {
                let (vx, vy, vz) = (col("vx")?, col("vy")?, col("vz")?);
                Some(
                    (0..d.count)
                        .map(|i| Vec3::new(vx[i], vy[i], vz[i]).length())
                        .collect(),
                )
            }
            ColorBy::J => Some(col("J")?.to_vec()),
            ColorBy::Plastic => Some(col("plastic")?.to_vec()),
            ColorBy::Stress => {
                let c: Vec<&[f32]> = ["sxx", "syy", "szz", "sxy", "syz", "sxz"]
                    .into_iter()
                    .map(col)
                    .collect::<Result<_>>()?;
                Some(
                    (0..d.count)
                        .map(|i| von_mises([c[0][i], c[1][i], c[2][i], c[3][i], c[4][i], c[5][i]]))
                        .collect(),
                )
            }
        };
        Ok(FrameJob {
            frame,
            time: None,
            positions,
            material,
            field,
            surface: SurfaceJob::None,
        })
    }
}

/// Where rendered frames go.
struct Sink {
    opts: RenderOptions,
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
        // Moving colliders are posed at the frame's time.
        self.opts.time = job.time.unwrap_or(0.0) as f32;
        let t0 = Instant::now();
        let surface = match job.surface {
            SurfaceJob::None => None,
            SurfaceJob::Ready(m, mat) => Some((m, mat)),
            SurfaceJob::Build(xs, params, mat) => {
                Some((crate::output::reconstruct_points(&xs, &params)?, mat))
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
    rtmpm_core::surface::AVAILABLE && !view.particles && !scene.output.surface.materials.is_empty()
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
    ) -> Result<()> {
        if let Some((view, dir, preview, fps)) = self.setup.take() {
            if self.surface_volume.is_some() {
                self.surface_volume = Some(scene.output.surface.select(p).1);
            }
            let mean_vol = p.vol0.iter().map(|&v| v as f64).sum::<f64>() / p.len().max(1) as f64;
            let radius = if mean_vol > 0.0 {
                0.6 * (mean_vol as f32).cbrt()
            } else {
                estimate_radius(&p.x)
            };
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
        let mut job = FrameJob::from_particles(frame, time, p, scene, self.color_by);
        if let Some(vol) = self.surface_volume {
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

// ---------------------------------------------------------------- rtmpm render OUTDIR

/// `rtmpm render`.
#[derive(Args)]
pub struct RenderArgs {
    /// Folder with the `frame_NNNNN.ply` files of a run; PNGs and movies are written next to them.
    pub outdir: Option<PathBuf>,
    /// The run's scene file: exact domain, floor, material colours, fps and `[render]` settings
    /// (default: framed from the particles' bounding box).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Frames per second of the movies (default: the scene's fps, else 30).
    #[arg(long)]
    pub fps: Option<f32>,
    /// Render a synthetic cloud of --bench-particles particles and report the time per frame.
    #[arg(long)]
    pub bench: bool,
    /// Particles of --bench.
    #[arg(long, default_value_t = 1_000_000)]
    pub bench_particles: usize,
    #[command(flatten)]
    pub view: ViewArgs,
}

/// Frame files `frame_NNNNN.ply` in `dir`, sorted by number.
pub fn ply_frames(dir: &Path) -> Result<Vec<(u64, PathBuf)>> {
    let entries =
        std::fs::read_dir(dir).with_context(|| format!("cannot read folder {}", dir.display()))?;
    let mut frames = Vec::new();
    for e in entries {
        let e = e.with_context(|| format!("listing {}", dir.display()))?;
        let name = e.file_name();
        let Some(name) = name.to_str() else { continue };
        if let Some(num) = name
            .strip_prefix("frame_")
            .and_then(|s| s.strip_suffix(".ply"))
            .and_then(|s| s.parse::<u64>().ok())
        {
            frames.push((num, e.path()));
        }
    }
    frames.sort();
    Ok(frames)
}

pub fn render_cmd(args: RenderArgs) -> Result<()> {
    if args.bench {
        return bench(&args);
    }
    let Some(dir) = &args.outdir else {
        bail!("no folder given: rtmpm render OUTDIR (or rtmpm render --bench)")
    };
    if let Some(fps) = args.fps
        && !(fps.is_finite() && fps > 0.0)
    {
        bail!("--fps must be positive, got {fps}");
    }
    if !dir.is_dir() {
        bail!(
            "cannot read folder {}: it is not a folder (give the output folder of a run)",
            dir.display()
        );
    }
    // Images are written into the folder: not while a run writes into it.
    let _lock = crate::outdir::OutDir::lock(dir, "rtmpm render")?;
    let frames = ply_frames(dir)?;
    if frames.is_empty() {
        bail!(
            "no frame_NNNNN.ply files in {} (run a scene with PLY output first: rtmpm run SCENE)",
            dir.display()
        );
    }
    let scene = match &args.scene {
        Some(p) => Some(Scene::from_file(p)?),
        None => None,
    };
    let color_by = args
        .view
        .color_by
        .or(scene.as_ref().and_then(|s| s.render.color_by))
        .unwrap_or_default();
    // Fluids as surfaces: the scene says which materials, its particles their volume.
    let surface_volume = match &scene {
        Some(sc) if draws_surfaces(&args.view, sc) => {
            Some(sc.output.surface.select(&sc.sample_particles()?).1)
        }
        _ => None,
    };
    // Only one run's frames make one movie: every frame must name the run of the first (the
    // PLY comment rtmpm writes) and hold as many particles.
    let first_run = std::cell::RefCell::new(None::<(u64, Option<String>, usize)>);
    let read = |num: u64, path: &Path| -> Result<FrameJob> {
        let d = read_ply(path).with_context(|| format!("reading {}", path.display()))?;
        let run = d
            .comments
            .iter()
            .find_map(|c| c.strip_prefix(crate::output::RUN_COMMENT_PREFIX))
            .map(str::to_string);
        let mut first = first_run.borrow_mut();
        match &*first {
            None => *first = Some((num, run, d.count)),
            Some((f, r, count)) => {
                if *r != run || *count != d.count {
                    bail!(
                        "{} holds frames of two runs: frame {f} ({}, {count} particles) and \
                         frame {num} ({}, {} particles); a movie is made of one run\n  fix: \
                         move one run's frame files to another folder (or rerun the scene with \
                         --overwrite)",
                        dir.display(),
                        r.as_deref().unwrap_or("run unknown"),
                        run.as_deref().unwrap_or("run unknown"),
                        d.count
                    );
                }
            }
        }
        let mut job = FrameJob::from_ply(num, &d, color_by, path)?;
        if let (Some(vol), Some(sc)) = (surface_volume, &scene) {
            job = job.with_surface(&sc.output.surface, vol, None);
        }
        // Frame n of a run is at time n / fps.
        job.time = scene.as_ref().map(|s| num as f64 / s.time.fps as f64);
        Ok(job)
    };
    let first = read(frames[0].0, &frames[0].1)?;
    let radius = estimate_radius(&first.positions);
    let (bounds, floor) = match &scene {
        Some(s) => scene_bounds(s),
        None => {
            // Bounding box of the first and last frames.
            let last = match frames.len() {
                1 => None,
                n => Some(read(frames[n - 1].0, &frames[n - 1].1)?),
            };
            let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            for p in first
                .positions
                .iter()
                .chain(last.iter().flat_map(|l| l.positions.iter()))
                .filter(|p| p.is_finite())
            {
                lo = lo.min(*p);
                hi = hi.max(*p);
            }
            if !lo.is_finite() {
                (lo, hi) = (Vec3::ZERO, Vec3::ONE);
            }
            let pad = Vec3::splat(radius);
            ((lo - pad, hi + pad), lo.y - radius)
        }
    };
    let fps = args
        .fps
        .or(scene.as_ref().map(|s| s.time.fps))
        .unwrap_or(30.0);
    let opts = resolve(&args.view, scene.as_ref(), bounds, floor, radius)?;
    eprintln!(
        "rendering {} frames of {} at {}x{}, coloured by {}",
        frames.len(),
        dir.display(),
        opts.width,
        opts.height,
        opts.color_by
    );
    let mut sink = Sink::new(opts, Some(dir.clone()), None, &args.view, fps)?;
    sink.process(first)?;
    for (num, path) in &frames[1..] {
        sink.process(read(*num, path)?)?;
    }
    println!("{}", sink.finish(fps)?);
    Ok(())
}

/// `rtmpm render --bench`: a block of particles (a dam-break column) on a regular lattice with
/// three materials, rendered three times at the chosen size.
fn bench(args: &RenderArgs) -> Result<()> {
    let n = args.bench_particles.max(1);
    let k = (n as f64).cbrt().ceil() as usize;
    let h = 0.5 / k as f32;
    let mut positions = Vec::with_capacity(k * k * k);
    for i in 0..k {
        for j in 0..k {
            for l in 0..k {
                if positions.len() < n {
                    positions.push(
                        Vec3::new(0.1, 0.1, 0.1)
                            + (Vec3::new(i as f32, j as f32, l as f32) + 0.5) * h,
                    );
                }
            }
        }
    }
    let material: Vec<u32> = (0..positions.len())
        .map(|i| (i * 3 / positions.len()) as u32)
        .collect();
    let field: Vec<f32> = positions.iter().map(|p| p.y).collect();
    let (lo, hi) = (Vec3::ZERO, Vec3::new(1.0, 0.75, 0.7));
    let opts = resolve(&args.view, None, (lo, hi), lo.y + 0.1, 0.6 * h)?;
    let input = RenderInput {
        positions: &positions,
        material: &material,
        field: Some(&field),
        surface: None,
    };
    let time = |opts: &RenderOptions| -> Result<f64> {
        render(&input, opts)?;
        let reps = 3;
        let t0 = Instant::now();
        for _ in 0..reps {
            render(&input, opts)?;
        }
        Ok(t0.elapsed().as_secs_f64() / reps as f64)
    };
    let dt = time(&opts)?;
    println!(
        "render bench: {} particles, {}x{}, coloured by {}, {} threads: {:.3} s per frame",
        positions.len(),
        opts.width,
        opts.height,
        opts.color_by,
        rayon_threads(),
        dt
    );
    // The same with three colliders (unless --no-colliders): a back wall (half-space), a
    // sphere and a box beside the block.
    if !args.view.no_colliders {
        let mut with = opts.clone();
        let collider = |shape: Shape| Collider {
            pivot: shape.center(),
            shape,
            rule: Default::default(),
            velocity: Vec3::ZERO,
            angular_velocity: Vec3::ZERO,
            keyframes: None,
        };
        with.colliders = vec![
            collider(Shape::HalfSpace {
                point: Vec3::new(0.0, 0.0, 0.05),
                normal: Vec3::Z,
            }),
            collider(Shape::Sphere {
                center: Vec3::new(0.8, 0.25, 0.35),
                radius: 0.12,
            }),
            collider(Shape::Box {
                center: Vec3::new(0.8, 0.2, 0.6),
                half_extents: Vec3::new(0.1, 0.1, 0.05),
            }),
        ];
        let dt = time(&with)?;
        println!("render bench with 3 colliders (wall, sphere, box): {dt:.3} s per frame");
    }
    Ok(())
}

fn rayon_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}
