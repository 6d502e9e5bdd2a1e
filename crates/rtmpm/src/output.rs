//! Per-frame output: PLY and VTK XML (.vtu + .pvd series).

use anyhow::{Context, Result};
use rtmpm_core::io::vtu::PvdWriter;
use rtmpm_core::io::{FrameFields, ply, vtu};
use rtmpm_core::{Particles, Scene};
use std::path::{Path, PathBuf};

/// Writes the frames of one run.
pub struct FrameOutput {
    pub dir: PathBuf,
    pvd: Option<PvdWriter>,
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
        Ok(FrameOutput {
            dir: dir.to_path_buf(),
            pvd,
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
        Ok(())
    }

    /// Write frame `frame` at simulated `time`.
    pub fn write_frame(
        &mut self,
        frame: u64,
        time: f64,
        p: &Particles,
        scene: &Scene,
    ) -> Result<()> {
        let stress = scene.output.stress.then(|| cauchy_stress(p, scene));
        let jacobian = scene
            .output
            .jacobian
            .then(|| p.f.iter().map(|f| f.determinant()).collect::<Vec<f32>>());
        let fields = FrameFields {
            stress: stress.as_deref(),
            jacobian: jacobian.as_deref(),
        };
        if scene.output.ply {
            let path = self.dir.join(format!("frame_{frame:05}.ply"));
            ply::write_ply(&path, p, &fields)
                .with_context(|| format!("writing {}", path.display()))?;
        }
        if let Some(pvd) = self.pvd.as_mut() {
            let name = format!("frame_{frame:05}.vtu");
            let path = self.dir.join(&name);
            vtu::write_vtu(&path, p, &fields)
                .with_context(|| format!("writing {}", path.display()))?;
            pvd.add(time, &name).context("writing frames.pvd")?;
        }
        Ok(())
    }
}

/// Cauchy stress per particle (see [`rtmpm_core::io::cauchy_stress`]).
pub use rtmpm_core::io::cauchy_stress;
