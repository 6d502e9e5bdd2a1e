//! `rtmpm mesh OUTDIR`: a fluid surface mesh per PLY frame of a finished run
//! (`surface_NNNNN.obj/.ply/.vtu/.usda`, `surface.pvd`), and `rtmpm mesh --bench`.

use anyhow::{Context, Result, bail};
use clap::Args;
use rtmpm_driver::output::write_mesh;
use rtmpm_io::ply::read_ply;
use rtmpm_io::vtu::PvdWriter;
use rtmpm_physics::math::Vec3;
use rtmpm_render::estimate_radius;
use rtmpm_scene::{MeshFormats, Scene, SurfaceSettings};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// `rtmpm mesh`.
#[derive(Args)]
pub struct MeshArgs {
    /// Folder with the `frame_NNNNN.ply` files of a run; the meshes are written next to them.
    pub outdir: Option<PathBuf>,
    /// The run's scene: which materials form the surface (its fluids, or `[surface]
    /// materials`), the particle volume, the `[surface]` settings and the frame times.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Material indices to mesh (default: the scene's surface materials; without a scene,
    /// every particle).
    #[arg(long, value_delimiter = ',', value_name = "I,J")]
    pub materials: Option<Vec<u32>>,
    /// Mesh files to write: any of obj, ply, vtu, usda.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "obj,ply,vtu",
        value_name = "LIST"
    )]
    pub formats: Vec<String>,
    /// Write the .vtu meshes without zlib compression.
    #[arg(long)]
    pub no_compress: bool,
    /// Time the reconstruction of one synthetic fluid frame of --bench-particles particles.
    #[arg(long)]
    pub bench: bool,
    /// Particles of --bench.
    #[arg(long, default_value_t = 1_000_000)]
    pub bench_particles: usize,
}

fn formats(list: &[String]) -> Result<MeshFormats> {
    let mut f = MeshFormats::default();
    for s in list {
        match s.trim() {
            "obj" => f.obj = true,
            "ply" => f.ply = true,
            "vtu" => f.vtu = true,
            "usda" => f.usda = true,
            other => bail!("unknown mesh format `{other}`: use obj, ply, vtu or usda"),
        }
    }
    if !f.any() {
        bail!("no mesh format given: --formats obj,ply,vtu");
    }
    Ok(f)
}

pub fn mesh_cmd(args: MeshArgs) -> Result<()> {
    if !rtmpm_geometry::surface::AVAILABLE {
        bail!("this rtmpm was built without fluid surfaces (cargo feature `surface`)");
    }
    if args.bench {
        return bench(args.bench_particles);
    }
    let Some(dir) = &args.outdir else {
        bail!("no folder given: rtmpm mesh OUTDIR (or rtmpm mesh --bench)")
    };
    let formats = formats(&args.formats)?;
    if !dir.is_dir() {
        bail!(
            "cannot read folder {}: it is not a folder (give the output folder of a run)",
            dir.display()
        );
    }
    // Meshes are written into the folder: not while a run writes into it.
    let _lock = rtmpm_driver::outdir::OutDir::lock(dir, "rtmpm mesh")?;
    let frames = run_frames(dir)?;
    let scene = args.scene.as_deref().map(Scene::from_file).transpose()?;
    let settings = surface_settings(scene.as_ref(), args.materials.as_deref())?;
    // Mean particle volume: from the scene's particles, else from the first frame's spacing.
    let mut volume = match &scene {
        Some(s) => Some(settings.select(&s.sample_particles()?).1),
        None => None,
    };
    let fps = scene.as_ref().map_or(30.0, |s| s.time.fps as f64);
    let mut pvd = match formats.vtu {
        true => Some(PvdWriter::new(dir.join("surface.pvd")).context("writing surface.pvd")?),
        false => None,
    };
    let t0 = Instant::now();
    let mut one_run = rtmpm_driver::output::OneRun::default();
    let mut said_empty = false;
    let filter = args.materials.is_some() || scene.is_some();
    for (num, path) in &frames {
        let frame = selected(path, filter, &settings)?;
        one_run.check(dir, *num, &frame.comments, frame.count)?;
        warn_about_frame(path, &frame, &settings, &mut said_empty);
        let xs = frame.positions;
        let vol = *volume.get_or_insert_with(|| (estimate_radius(&xs) / 0.6).powi(3));
        let mesh = rtmpm_driver::output::reconstruct_points(&xs, &settings.params(vol))
            .with_context(|| format!("meshing {}", path.display()))?;
        write_mesh(dir, *num, &mesh, formats, !args.no_compress)?;
        if let Some(p) = pvd.as_mut() {
            p.add(*num as f64 / fps, &format!("surface_{num:05}.vtu"))
                .context("writing surface.pvd")?;
        }
        eprintln!(
            "{}: {} particles -> {} triangles",
            path.display(),
            xs.len(),
            mesh.triangles.len()
        );
    }
    println!(
        "{} surfaces written to {} ({:.2} s per frame)",
        frames.len(),
        dir.display(),
        t0.elapsed().as_secs_f64() / frames.len() as f64
    );
    Ok(())
}

/// The `frame_NNNNN.ply` files of a run's folder, in order; an error that says what to give
/// instead when there are none (the folder of a batch run holds its worlds' folders).
fn run_frames(dir: &Path) -> Result<Vec<(u64, PathBuf)>> {
    let frames = crate::render::cmd::ply_frames(dir)?;
    if frames.is_empty() && dir.join("batch.csv").is_file() {
        bail!(
            "{} is the folder of a batch run: its worlds' frames are in its world_NNN folders \
             (batch.csv lists them)\n  fix: rtmpm mesh {}",
            dir.display(),
            dir.join(rtmpm_driver::batch::world_dir_name(0, 2))
                .display()
        );
    }
    if frames.is_empty() {
        bail!(
            "no frame_NNNNN.ply files in {} (run a scene with PLY output first)",
            dir.display()
        );
    }
    Ok(frames)
}

/// The surface settings: the scene's `[surface]` (defaults without a scene), with the
/// materials of `--materials` when given, each checked against the scene's materials.
fn surface_settings(scene: Option<&Scene>, materials: Option<&[u32]>) -> Result<SurfaceSettings> {
    let mut settings = scene.map(|s| s.output.surface.clone()).unwrap_or_default();
    if let Some(m) = materials {
        if let Some(sc) = scene
            && let Some(&bad) = m.iter().find(|&&i| i as usize >= sc.materials.len())
        {
            let names: Vec<String> = sc
                .materials
                .iter()
                .enumerate()
                .map(|(i, m)| format!("{i} ({})", m.name))
                .collect();
            bail!(
                "--materials {bad}: the scene has no material {bad}; its materials are {}",
                names.join(", ")
            );
        }
        settings.materials = m.to_vec();
    }
    if scene.is_some() && settings.materials.is_empty() {
        bail!(
            "the scene has no fluid material: name the materials with --materials or [surface] materials"
        );
    }
    Ok(settings)
}

/// Warnings about a frame read for meshing: particles left out for a non-finite position,
/// and (once a run) a frame with particles none of which is of the meshed materials.
fn warn_about_frame(path: &Path, frame: &Frame, settings: &SurfaceSettings, said_empty: &mut bool) {
    if frame.non_finite > 0 {
        eprintln!(
            "warning: {}: {} particle(s) with a non-finite position (NaN or infinity) left \
             out of the surface; the run that wrote it blew up",
            path.display(),
            frame.non_finite
        );
    }
    if frame.positions.is_empty() && frame.count > 0 && !*said_empty {
        *said_empty = true;
        eprintln!(
            "warning: {}: no particle of the materials meshed ({:?}); the frame's materials \
             are {:?}: its surface is empty (choose them with --materials or [surface] \
             materials)",
            path.display(),
            settings.materials,
            frame.materials
        );
    }
}

/// What [`selected`] reads of a PLY frame.
struct Frame {
    /// Finite positions of the particles of the chosen materials.
    positions: Vec<Vec3>,
    /// Chosen particles left out for a non-finite position.
    non_finite: usize,
    /// Particles of the frame, its PLY comments and the material indices it holds.
    count: usize,
    comments: Vec<String>,
    materials: Vec<i64>,
}

/// The particles of the chosen materials in a PLY frame (all when `filter` is false).
fn selected(path: &Path, filter: bool, s: &SurfaceSettings) -> Result<Frame> {
    let d = read_ply(path).with_context(|| format!("reading {}", path.display()))?;
    let col = |n: &str| {
        d.f32(n)
            .with_context(|| format!("{} has no float column `{n}`", path.display()))
    };
    let (x, y, z) = (col("x")?, col("y")?, col("z")?);
    let mat = d.int("material");
    if filter && mat.is_none() {
        bail!(
            "{} has no `material` column to choose the fluid by",
            path.display()
        );
    }
    let mut materials: Vec<i64> = mat.map(|m| m.to_vec()).unwrap_or_default();
    materials.sort_unstable();
    materials.dedup();
    let chosen = (0..d.count)
        .filter(|&i| !filter || mat.is_some_and(|m| s.materials.contains(&(m[i] as u32))))
        .map(|i| Vec3::new(x[i], y[i], z[i]));
    let (positions, bad): (Vec<Vec3>, Vec<Vec3>) = chosen.partition(|p| p.is_finite());
    Ok(Frame {
        positions,
        non_finite: bad.len(),
        count: d.count,
        comments: d.comments.clone(),
        materials,
    })
}

/// A dam-break fluid block of about `n` particles (8 per cell, jittered), meshed three times.
fn bench(n: usize) -> Result<()> {
    use rand::{Rng, SeedableRng};
    if n < 8 {
        bail!("--bench-particles {n}: the bench block needs at least 8 particles");
    }
    // The block's positions and its reconstruction (about 80 neighbours a particle at 8 a
    // cell), refused with the numbers when they cannot fit.
    let per_particle = 12 + rtmpm_geometry::surface::memory::BYTES_PER_PARTICLE + 80 * 10;
    let bytes = (n as u64).saturating_mul(per_particle);
    if let Some(avail) = rtmpm_io::limits::host_memory_available()
        && bytes > avail
    {
        bail!(
            "--bench-particles {n}: meshing {n} particles needs about {} of memory, more than \
             the {} available; about {} particles fit\n  fix: give fewer --bench-particles \
             (the default is 1000000)",
            rtmpm_io::limits::human_bytes(bytes),
            rtmpm_io::limits::human_bytes(avail),
            avail / per_particle
        );
    }
    // A block 2 x 1 x 1 of k x k/2 x k/2 sub-cells.
    let k = (4.0 * n as f64).cbrt().round() as usize;
    let h = 1.0 / k as f32;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
    let mut xs = Vec::new();
    xs.try_reserve_exact(k * k * k / 4).map_err(|_| {
        anyhow::anyhow!(
            "cannot allocate the {} positions of --bench-particles {n}",
            k * k * k / 4
        )
    })?;
    for i in 0..k {
        for j in 0..k / 2 {
            for l in 0..k / 2 {
                let jitter = Vec3::new(rng.random(), rng.random(), rng.random()) - 0.5;
                xs.push((Vec3::new(i as f32, j as f32, l as f32) + 0.5 + jitter) * h);
            }
        }
    }
    let params = SurfaceSettings::default().params(h * h * h);
    let run = || -> Result<(usize, f64)> {
        let t = Instant::now();
        let m = rtmpm_driver::output::reconstruct_points(&xs, &params)?;
        Ok((m.triangles.len(), t.elapsed().as_secs_f64()))
    };
    run()?;
    let times: Vec<(usize, f64)> = (0..3).map(|_| run()).collect::<Result<_>>()?;
    let best = times.iter().map(|t| t.1).fold(f64::INFINITY, f64::min);
    let mean = times.iter().map(|t| t.1).sum::<f64>() / 3.0;
    println!(
        "mesh bench: {} particles, {} triangles, {} threads: {:.3} s per frame (best of 3), mean {:.3} s",
        xs.len(),
        times[0].0,
        rayon::current_num_threads(),
        best,
        mean
    );
    Ok(())
}
