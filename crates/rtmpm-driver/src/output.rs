//! Per-frame output: PLY, VTK XML (.vtu + .pvd series), BGEO, USD, and fluid surface meshes.

use anyhow::{Context, Result, bail};
use rtmpm_geometry::surface::{SurfaceParams, TriMesh};
use rtmpm_io::stream::{Derived, StreamFormat};
use rtmpm_io::vtu::PvdWriter;
use rtmpm_io::{FrameFields, bgeo, ply, trimesh, usd, vtk_appended};
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
        rtmpm_geometry::surface::reconstruct(xs, params).map_err(anyhow::Error::msg)
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
        let pvd = match scene.output.vtu {
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
        let stress = scene
            .output
            .stress
            .then(|| cauchy_stress(p, &scene.materials));
        let jacobian = scene
            .output
            .jacobian
            .then(|| p.f.iter().map(|f| f.determinant()).collect::<Vec<f32>>());
        let fields = FrameFields {
            stress: stress.as_deref(),
            jacobian: jacobian.as_deref(),
        };
        let o = &scene.output;
        let path = |ext: &str| self.dir.join(format!("frame_{frame:05}.{ext}"));
        if o.ply {
            let path = path("ply");
            ply::write_ply_with_comments(&path, p, &fields, &[&self.run_comment])
                .with_context(|| format!("writing {}", path.display()))?;
        }
        for (on, ext, gz) in [(o.bgeo, "bgeo", false), (o.bgeo_gz, "bgeo.gz", true)] {
            if on {
                let path = path(ext);
                bgeo::write_bgeo(&path, p, &fields, gz)
                    .with_context(|| format!("writing {}", path.display()))?;
            }
        }
        if o.usda {
            let path = path("usda");
            let bodies: Vec<usd::UsdBody> = scene
                .rigid_bodies
                .iter()
                .zip(bodies)
                .map(|(spec, pose)| usd::UsdBody {
                    name: &spec.name,
                    shape: &spec.shape,
                    position: pose.position,
                    rotation: pose.rotation,
                })
                .collect();
            usd::write_usda_frame(&path, p, &fields, &bodies)
                .with_context(|| format!("writing {}", path.display()))?;
        }
        if let Some(pvd) = self.pvd.as_mut() {
            let name = format!("frame_{frame:05}.vtu");
            let path = self.dir.join(&name);
            vtk_appended::write_particles_vtu(&path, p, &fields, o.compress)
                .with_context(|| format!("writing {}", path.display()))?;
            pvd.add(time, &name).context("writing frames.pvd")?;
        }
        match self.surfaces.as_mut() {
            Some(s) => s.write(frame, time, p).map(Some),
            None => Ok(None),
        }
    }
}

impl FrameOutput {
    /// True when every file of a frame can be streamed in chunks ([`crate::stream`]): the
    /// particle formats PLY and BGEO only (VTU, USD and surfaces need the whole frame).
    pub fn streamable(scene: &Scene) -> bool {
        let o = &scene.output;
        !o.vtu && !o.usda && !o.surface_formats.any()
    }

    /// The streamed formats of the scene, for [`crate::stream::FrameStreamer::new`].
    pub fn stream_formats(&self, scene: &Scene) -> Vec<StreamFormat> {
        self.stream_files(0, scene)
            .into_iter()
            .map(|f| f.1)
            .collect()
    }

    /// The files of frame `frame` and their formats (the names [`FrameOutput::write_frame`]
    /// writes).
    pub fn stream_files(&self, frame: u64, scene: &Scene) -> Vec<(PathBuf, StreamFormat)> {
        let o = &scene.output;
        let path = |ext: &str| self.dir.join(format!("frame_{frame:05}.{ext}"));
        let mut out = Vec::new();
        if o.ply {
            let comments = vec![self.run_comment.clone()];
            out.push((path("ply"), StreamFormat::Ply { comments }));
        }
        if o.bgeo {
            out.push((path("bgeo"), StreamFormat::Bgeo { gzip: false }));
        }
        if o.bgeo_gz {
            out.push((path("bgeo.gz"), StreamFormat::Bgeo { gzip: true }));
        }
        out
    }
}

/// The derived fields the scene's frames hold.
pub fn derived_fields(scene: &Scene) -> Derived {
    Derived {
        jacobian: scene.output.jacobian,
        stress: scene.output.stress,
    }
}

/// Cauchy stress per particle (see [`rtmpm_physics::material::cauchy_stress`]).
pub use rtmpm_physics::material::cauchy_stress;
