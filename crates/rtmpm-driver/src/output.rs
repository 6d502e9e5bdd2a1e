//! Per-frame output: a file per frame in each of the scene's formats (the registry
//! [`rtmpm_io::FRAME_FORMATS`]: PLY, BGEO, USD, VTU with its `.pvd` series), and fluid surface
//! meshes.

use anyhow::{Context, Result, bail};
use rtmpm_geometry::surface::{SurfaceParams, TriMesh};
use rtmpm_io::FrameFields;
use rtmpm_io::frame::{Frame, FrameBody, FrameFormat};
use rtmpm_io::stream::{Derived, StreamFormat};
use rtmpm_io::vtu::PvdWriter;
use rtmpm_io::{trimesh, usd};
use rtmpm_physics::Particles;
use rtmpm_physics::math::Vec3;
use rtmpm_rigid::BodyPose;
use rtmpm_scene::{MeshFormats, Scene, SurfaceSettings};
use std::path::{Path, PathBuf};

/// Writes the frames of one run.
pub struct FrameOutput {
    pub dir: PathBuf,
    pvd: Option<PvdWriter>,
    surfaces: Option<SurfaceOutput>,
    /// `comment` line of every PLY header naming the run (see `outdir::scene_identity`), so
    /// that `rtmpm render` never mixes the frames of two runs.
    run_comment: String,
}

/// The PLY comment that names the run a frame belongs to.
pub const RUN_COMMENT_PREFIX: &str = "rtmpm-run ";

/// Frames read from one folder belong to one run: every frame names the run of the first (the
/// PLY comment rtmpm writes); frames that name no run must hold as many particles as the first
/// (a run's count changes only with emitters, and its frames name the run).
#[derive(Default)]
pub struct OneRun {
    first: Option<(u64, Option<String>, usize)>,
}

impl OneRun {
    /// Check frame `num` of `dir` with PLY `comments` and `count` particles against the first.
    pub fn check(&mut self, dir: &Path, num: u64, comments: &[String], count: usize) -> Result<()> {
        let run = comments
            .iter()
            .find_map(|c| c.strip_prefix(RUN_COMMENT_PREFIX))
            .map(str::to_string);
        let Some((f, r, n)) = &self.first else {
            self.first = Some((num, run, count));
            return Ok(());
        };
        if *r != run || (run.is_none() && *n != count) {
            bail!(
                "{} holds frames of two runs: frame {f} ({}, {n} particles) and frame {num} ({}, \
                 {count} particles); the frames of one run go together\n  fix: move one run's \
                 frame files to another folder (or rerun the scene with --overwrite)",
                dir.display(),
                r.as_deref().unwrap_or("run unknown"),
                run.as_deref().unwrap_or("run unknown"),
            );
        }
        Ok(())
    }
}

/// A fresh `.pvd` collection at `path`, or, when `resume_time` is given, the existing one
/// continued (entries before that time kept; an unreadable one is an error, never silently
/// replaced).
fn open_pvd(path: &Path, resume_time: Option<f64>) -> Result<PvdWriter> {
    Ok(match resume_time {
        None => PvdWriter::new(path).with_context(|| format!("writing {}", path.display()))?,
        Some(t) => PvdWriter::resume(path, t).with_context(|| {
            format!(
                "cannot continue {} (the frames themselves are intact); move it away to start \
                 a new collection from the resumed frames",
                path.display()
            )
        })?,
    })
}

/// Writes the surface meshes of a run (`surface_NNNNN.{obj,ply,vtu}`, `surface.pvd`).
pub struct SurfaceOutput {
    dir: PathBuf,
    formats: MeshFormats,
    settings: SurfaceSettings,
    compress: bool,
    pvd: Option<PvdWriter>,
}

impl SurfaceOutput {
    /// Start the series in `dir`, or continue it after resuming at `resume_time` (see
    /// [`FrameOutput::new`]); fails when this build cannot reconstruct surfaces.
    pub fn new(
        dir: &Path,
        formats: MeshFormats,
        settings: SurfaceSettings,
        compress: bool,
        resume_time: Option<f64>,
    ) -> Result<SurfaceOutput> {
        if !rtmpm_geometry::surface::AVAILABLE {
            bail!(
                "this rtmpm was built without fluid surfaces (cargo feature `surface`): rebuild with default features, or remove [output] surface"
            );
        }
        let pvd = match formats.vtu {
            true => Some(open_pvd(&dir.join("surface.pvd"), resume_time)?),
            false => None,
        };
        Ok(SurfaceOutput {
            dir: dir.to_path_buf(),
            formats,
            settings,
            compress,
            pvd,
        })
    }

    /// Reconstruct the surface of `p` and write it as frame `frame`; returns the mesh.
    pub fn write(&mut self, frame: u64, time: f64, p: &Particles) -> Result<TriMesh> {
        let mesh = reconstruct(p, &self.settings)?;
        write_mesh(&self.dir, frame, &mesh, self.formats, self.compress)?;
        if let Some(pvd) = self.pvd.as_mut() {
            pvd.add(time, &format!("surface_{frame:05}.vtu"))
                .context("writing surface.pvd")?;
        }
        Ok(mesh)
    }
}

/// The surface of the particles of `settings.materials` (empty when there are none).
pub fn reconstruct(p: &Particles, settings: &SurfaceSettings) -> Result<TriMesh> {
    let (xs, vol) = settings.select(p);
    if xs.is_empty() {
        return Ok(TriMesh::default());
    }
    reconstruct_points(&xs, &settings.params(vol))
}

/// The surface around `xs` (an error when this build has no surfaces).
pub fn reconstruct_points(xs: &[Vec3], params: &SurfaceParams) -> Result<TriMesh> {
    #[cfg(feature = "surface")]
    {
        rtmpm_geometry::surface::reconstruct(xs, params, rtmpm_io::limits::host_memory_available())
            .map_err(anyhow::Error::msg)
    }
    #[cfg(not(feature = "surface"))]
    {
        let _ = (xs, params);
        bail!("this rtmpm was built without fluid surfaces (cargo feature `surface`)")
    }
}

/// Write `surface_NNNNN.{obj,ply,vtu}` in `dir` for the formats asked.
pub fn write_mesh(
    dir: &Path,
    frame: u64,
    mesh: &TriMesh,
    formats: MeshFormats,
    compress: bool,
) -> Result<()> {
    let path = |ext: &str| dir.join(format!("surface_{frame:05}.{ext}"));
    if formats.obj {
        let p = path("obj");
        trimesh::write_obj(&p, mesh).with_context(|| format!("writing {}", p.display()))?;
    }
    if formats.ply {
        let p = path("ply");
        trimesh::write_mesh_ply(&p, mesh).with_context(|| format!("writing {}", p.display()))?;
    }
    if formats.usda {
        let p = path("usda");
        usd::write_usda_mesh(&p, mesh).with_context(|| format!("writing {}", p.display()))?;
    }
    if formats.vtu {
        let p = path("vtu");
        trimesh::write_mesh_vtu(&p, mesh, compress)
            .with_context(|| format!("writing {}", p.display()))?;
    }
    Ok(())
}

impl FrameOutput {
    /// Start writing frames into `dir` (created): fresh `frames.pvd` and `surface.pvd`, or,
    /// when `resume_time` is given, the existing ones continued (see [`open_pvd`]).
    pub fn new(
        dir: &Path,
        scene: &Scene,
        identity: &str,
        resume_time: Option<f64>,
    ) -> Result<FrameOutput> {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create output folder {}", dir.display()))?;
        let pvd = match scene.output.formats.iter().any(|f| f.pvd) {
            true => Some(open_pvd(&dir.join("frames.pvd"), resume_time)?),
            false => None,
        };
        let o = &scene.output;
        let surfaces = match o.surface_formats.any() {
            true => Some(SurfaceOutput::new(
                dir,
                o.surface_formats,
                o.surface.clone(),
                o.compress,
                resume_time,
            )?),
            false => None,
        };
        Ok(FrameOutput {
            dir: dir.to_path_buf(),
            pvd,
            surfaces,
            run_comment: format!("{RUN_COMMENT_PREFIX}{identity}"),
        })
    }

    /// Write frame `frame` at simulated `time` (the particles `p`, the rigid bodies of the scene
    /// at their poses `bodies`); returns the surface mesh when one was made.
    pub fn write_frame(
        &mut self,
        frame: u64,
        time: f64,
        p: &Particles,
        bodies: &[BodyPose],
        scene: &Scene,
    ) -> Result<Option<TriMesh>> {
        let files: Vec<(PathBuf, &FrameFormat)> = (scene.output.formats.iter())
            .map(|f| (self.dir.join(f.file_name(frame)), *f))
            .collect();
        let derived = scene.output.derived();
        write_frame_files(&files, p, bodies, scene, derived, &[&self.run_comment])?;
        if let Some(pvd) = self.pvd.as_mut() {
            for (_, f) in files.iter().filter(|(_, f)| f.pvd) {
                pvd.add(time, &f.file_name(frame))
                    .context("writing frames.pvd")?;
            }
        }
        match self.surfaces.as_mut() {
            Some(s) => s.write(frame, time, p).map(Some),
            None => Ok(None),
        }
    }
}

/// Write one frame's files, each `(path, format)` of `files`: the particles `p` with the derived
/// fields `derived` (computed once here), the scene's rigid bodies at their poses `poses`, the
/// header comments `comments` (formats with comments). Each file is written atomically. `rtmpm
/// run`'s frames ([`FrameOutput::write_frame`]) and Python's `Simulation.write_frame` are
/// written here, so both write every format of [`rtmpm_io::FRAME_FORMATS`] the same way.
pub fn write_frame_files(
    files: &[(PathBuf, &FrameFormat)],
    p: &Particles,
    poses: &[BodyPose],
    scene: &Scene,
    derived: Derived,
    comments: &[&str],
) -> Result<()> {
    let stress = derived.stress.then(|| cauchy_stress(p, &scene.materials));
    let jacobian =
        (derived.jacobian).then(|| p.f.iter().map(|f| f.determinant()).collect::<Vec<f32>>());
    let bodies = frame_bodies(scene, poses);
    let frame = Frame {
        particles: p,
        fields: FrameFields {
            stress: stress.as_deref(),
            jacobian: jacobian.as_deref(),
        },
        comments,
        bodies: &bodies,
        compress: scene.output.compress,
    };
    for (path, format) in files {
        (format.write)(path, &frame).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// The scene's rigid bodies at their poses `poses`, as frame files hold them.
pub fn frame_bodies<'a>(scene: &'a Scene, poses: &[BodyPose]) -> Vec<FrameBody<'a>> {
    scene
        .rigid_bodies
        .iter()
        .zip(poses)
        .map(|(spec, pose)| FrameBody {
            name: &spec.name,
            shape: &spec.shape,
            position: pose.position,
            rotation: pose.rotation,
        })
        .collect()
}

impl FrameOutput {
    /// True when every file of a frame can be streamed in chunks ([`crate::stream`]): formats
    /// with a chunk encoder only (PLY and BGEO; VTU, USD and surfaces need the whole frame).
    pub fn streamable(scene: &Scene) -> bool {
        let o = &scene.output;
        o.formats.iter().all(|f| f.streamable()) && !o.surface_formats.any()
    }

    /// The columns the streamed formats of `scene` copy from the backend (what a frame
    /// buffer holds per particle).
    pub fn stream_columns(scene: &Scene) -> rtmpm_io::chunks::FrameColumns {
        let formats: Vec<StreamFormat> = scene
            .output
            .formats
            .iter()
            .filter_map(|f| StreamFormat::new(f, Vec::new()))
            .collect();
        rtmpm_io::stream::FrameFiles::columns(&formats, derived_fields(scene))
    }

    /// The streamed formats of the scene, for [`crate::stream::FrameStreamer::new`].
    pub fn stream_formats(&self, scene: &Scene) -> Vec<StreamFormat> {
        self.stream_files(0, scene)
            .into_iter()
            .map(|f| f.1)
            .collect()
    }

    /// The files of frame `frame` and their formats (the names [`FrameOutput::write_frame`]
    /// writes); the formats that cannot be streamed are left out.
    pub fn stream_files(&self, frame: u64, scene: &Scene) -> Vec<(PathBuf, StreamFormat)> {
        scene
            .output
            .formats
            .iter()
            .filter_map(|f| {
                let format = StreamFormat::new(f, vec![self.run_comment.clone()])?;
                Some((self.dir.join(f.file_name(frame)), format))
            })
            .collect()
    }
}

/// The derived fields the scene's frames hold.
pub fn derived_fields(scene: &Scene) -> Derived {
    scene.output.derived()
}

/// Cauchy stress per particle (see [`rtmpm_physics::material::cauchy_stress`]).
pub use rtmpm_physics::material::cauchy_stress;
