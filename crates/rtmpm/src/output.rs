//! Per-frame output: PLY, VTK XML (.vtu + .pvd series), BGEO, USD, and fluid surface meshes.

use anyhow::{Context, Result, bail};
use rtmpm_core::io::vtu::PvdWriter;
use rtmpm_core::io::{FrameFields, bgeo, ply, trimesh, usd, vtk_appended};
use rtmpm_core::math::Vec3;
use rtmpm_core::scene::{MeshFormats, SurfaceSettings};
use rtmpm_core::surface::{SurfaceParams, TriMesh};
use rtmpm_core::{Particles, Scene};
use std::path::{Path, PathBuf};

/// Writes the frames of one run.
pub struct FrameOutput {
    pub dir: PathBuf,
    pvd: Option<PvdWriter>,
    surfaces: Option<SurfaceOutput>,
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
    /// Start the series in `dir` (fails when this build cannot reconstruct surfaces).
    pub fn new(
        dir: &Path,
        formats: MeshFormats,
        settings: SurfaceSettings,
        compress: bool,
    ) -> Result<SurfaceOutput> {
        if !rtmpm_core::surface::AVAILABLE {
            bail!(
                "this rtmpm was built without fluid surfaces (cargo feature `surface`): rebuild with default features, or remove [output] surface"
            );
        }
        let pvd = match formats.vtu {
            true => {
                let path = dir.join("surface.pvd");
                Some(PvdWriter::new(&path).with_context(|| format!("writing {}", path.display()))?)
            }
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

    /// Continue after resuming at `time`.
    fn resume(&mut self, time: f64) -> Result<()> {
        if self.pvd.is_some() {
            let path = self.dir.join("surface.pvd");
            self.pvd = Some(
                PvdWriter::resume(&path, time)
                    .with_context(|| format!("reading {}", path.display()))?,
            );
        }
        Ok(())
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
        rtmpm_core::surface::reconstruct(xs, params).map_err(anyhow::Error::msg)
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
    /// Create the output folder.
    pub fn new(dir: &Path, scene: &Scene) -> Result<FrameOutput> {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create output folder {}", dir.display()))?;
        let pvd = match scene.output.vtu {
            true => {
                let path = dir.join("frames.pvd");
                Some(PvdWriter::new(&path).with_context(|| format!("writing {}", path.display()))?)
            }
            false => None,
        };
        let o = &scene.output;
        let surfaces = match o.surface_formats.any() {
            true => Some(SurfaceOutput::new(
                dir,
                o.surface_formats,
                o.surface.clone(),
                o.compress,
            )?),
            false => None,
        };
        Ok(FrameOutput {
            dir: dir.to_path_buf(),
            pvd,
            surfaces,
        })
    }

    /// Continue a series after resuming at `time`.
    pub fn resume(&mut self, time: f64) -> Result<()> {
        if self.pvd.is_some() {
            let path = self.dir.join("frames.pvd");
            self.pvd = Some(
                PvdWriter::resume(&path, time)
                    .with_context(|| format!("reading {}", path.display()))?,
            );
        }
        if let Some(s) = self.surfaces.as_mut() {
            s.resume(time)?;
        }
        Ok(())
    }

    /// Write frame `frame` at simulated `time`; returns the surface mesh when one was made.
    pub fn write_frame(
        &mut self,
        frame: u64,
        time: f64,
        p: &Particles,
        scene: &Scene,
    ) -> Result<Option<TriMesh>> {
        let stress = scene.output.stress.then(|| cauchy_stress(p, scene));
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
            ply::write_ply(&path, p, &fields)
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
            usd::write_usda_points(&path, p, &fields)
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

/// Cauchy stress per particle (see [`rtmpm_core::io::cauchy_stress`]).
pub use rtmpm_core::io::cauchy_stress;
