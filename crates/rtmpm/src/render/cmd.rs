//! `rtmpm render OUTDIR`: PNG frames and movies from the PLY frames of a run, and
//! `rtmpm render --bench`.

use super::*;

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
    #[arg(long, default_value_t = BENCH_PARTICLES)]
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

/// The particles of `rtmpm render --bench` unless `--bench-particles` says otherwise.
const BENCH_PARTICLES: usize = 1_000_000;

/// The frame rates a movie of `rtmpm render --fps` may have (frames a second).
const MOVIE_FPS: (f32, f32) = (0.01, 1000.0);

/// `--fps`: a frame rate a movie can have; a warning above the GIF's 50.
fn check_fps(fps: f32, no_movie: bool) -> Result<()> {
    if !(fps.is_finite() && fps > 0.0) {
        bail!("--fps must be positive, got {fps}");
    }
    // A GIF frame lasts 0.02 to 655.35 s (whole centiseconds); an MP4 at 1e30 frames a
    // second, or one frame in 1e30 s, is no movie either.
    if !(MOVIE_FPS.0..=MOVIE_FPS.1).contains(&fps) {
        bail!(
            "--fps {fps:e} is out of range: a movie plays {} to {} frames a second\n  fix: \
             give the frames per second of the movie (leave --fps out for the scene's fps)",
            MOVIE_FPS.0,
            MOVIE_FPS.1
        );
    }
    if fps > 50.0 && !no_movie {
        eprintln!(
            "warning: --fps {fps}: movie.gif plays at most 50 frames a second (GIF delays \
             are whole centiseconds, at least 2); movie.mp4, when written, keeps {fps}"
        );
    }
    Ok(())
}

pub fn render_cmd(args: RenderArgs) -> Result<()> {
    if args.bench {
        return bench(&args);
    }
    let Some(dir) = &args.outdir else {
        bail!("no folder given: rtmpm render OUTDIR (or rtmpm render --bench)")
    };
    if let Some(fps) = args.fps {
        check_fps(fps, args.view.no_movie)?;
    }
    if !dir.is_dir() {
        bail!(
            "cannot read folder {}: it is not a folder (give the output folder of a run)",
            dir.display()
        );
    }
    // Images are written into the folder: not while a run writes into it.
    let _lock = rtmpm_driver::outdir::OutDir::lock(dir, "rtmpm render")?;
    let frames = ply_frames(dir)?;
    if frames.is_empty() {
        bail!(
            "no frame_NNNNN.ply files in {} (run a scene with PLY output first: rtmpm run SCENE)",
            dir.display()
        );
    }
    let scene = match &args.scene {
        // A batch's scene file gives its scene as written (the worlds' common settings).
        Some(p) => Some(rtmpm_scene::BatchScene::from_file(p)?.base),
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
    // The rigid bodies at each frame (from the run's bodies.csv, with the scene's shapes).
    let bodies = match &scene {
        Some(sc) if !sc.rigid_bodies.is_empty() && dir.join("bodies.csv").is_file() => {
            read_bodies_csv(&dir.join("bodies.csv"), sc)?
        }
        _ => Default::default(),
    };
    // Only one run's frames make one movie (`OneRun`).
    let one_run = std::cell::RefCell::new(rtmpm_driver::output::OneRun::default());
    let read = |num: u64, path: &Path| -> Result<FrameJob> {
        let d = read_ply(path).with_context(|| format!("reading {}", path.display()))?;
        one_run.borrow_mut().check(dir, num, &d.comments, d.count)?;
        let mut job = FrameJob::from_ply(num, &d, color_by, path)?;
        if let Some(b) = bodies.get(&num) {
            job = job.with_bodies(b);
        }
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
    let n = args.bench_particles;
    if n == 0 {
        bail!("--bench-particles 0: the bench block needs at least 1 particle");
    }
    // The block's positions, materials and field, and what a frame adds per particle (the
    // field's copy for its range, the shadow map's points): refused with the numbers when
    // they cannot fit, not aborted by a failed allocation.
    const PER_PARTICLE: u64 = 64;
    let bytes = (n as u64).saturating_mul(PER_PARTICLE);
    if let Some(avail) = rtmpm_io::limits::host_memory_available()
        && bytes > avail
    {
        bail!(
            "--bench-particles {n}: rendering {n} particles needs about {} of memory, more than \
             the {} available; about {} particles fit\n  fix: give fewer --bench-particles \
             (the default is {})",
            rtmpm_io::limits::human_bytes(bytes),
            rtmpm_io::limits::human_bytes(avail),
            avail / PER_PARTICLE,
            BENCH_PARTICLES
        );
    }
    let k = (n as f64).cbrt().ceil() as usize;
    let h = 0.5 / k as f32;
    let mut positions = Vec::new();
    positions.try_reserve_exact(n).map_err(|_| {
        anyhow::anyhow!("cannot allocate the {n} positions of --bench-particles {n}")
    })?;
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
            collider(Shape::HalfSpace(rtmpm_geometry::shape::HalfSpace {
                point: Vec3::new(0.0, 0.0, 0.05),
                normal: Vec3::Z,
            })),
            collider(Shape::Sphere(rtmpm_geometry::shape::Sphere {
                center: Vec3::new(0.8, 0.25, 0.35),
                radius: 0.12,
            })),
            collider(Shape::Box(rtmpm_geometry::shape::Cuboid::centred(
                Vec3::new(0.8, 0.2, 0.6),
                Vec3::new(0.1, 0.1, 0.05),
            ))),
        ];
        let dt = time(&with)?;
        println!("render bench with 3 colliders (wall, sphere, box): {dt:.3} s per frame");
    }
    Ok(())
}

fn rayon_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}
