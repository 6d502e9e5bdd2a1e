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
    /// `comment` line of every PLY header naming the run (see `outdir::scene_identity`), so
    /// that `rtmpm render` never mixes the frames of two runs.
    run_comment: String,
}

/// The PLY comment that names the run a frame belongs to.
pub const RUN_COMMENT_PREFIX: &str = "rtmpm-run ";

impl FrameOutput {
    /// Start writing frames into `dir` (created): a fresh `frames.pvd`, or, when `resume_time`
    /// is given, the existing one continued (entries before that time kept; an unreadable one
    /// is an error, never silently replaced).
    pub fn new(
        dir: &Path,
        scene: &Scene,
        identity: &str,
        resume_time: Option<f64>,
    ) -> Result<FrameOutput> {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create output folder {}", dir.display()))?;
        let pvd = match scene.output.vtu {
            true => {
                let path = dir.join("frames.pvd");
                Some(match resume_time {
                    None => PvdWriter::new(&path)
                        .with_context(|| format!("writing {}", path.display()))?,
                    Some(t) => PvdWriter::resume(&path, t).with_context(|| {
                        format!(
                            "cannot continue {} (the frames themselves are intact); move it \
                             away to start a new collection from the resumed frames",
                            path.display()
                        )
                    })?,
                })
            }
            false => None,
        };
        Ok(FrameOutput {
            dir: dir.to_path_buf(),
            pvd,
            run_comment: format!("{RUN_COMMENT_PREFIX}{identity}"),
        })
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
            ply::write_ply_with_comments(&path, p, &fields, &[&self.run_comment])
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
