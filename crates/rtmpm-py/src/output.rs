//! Frame files of the particles in memory (`Simulation.write_frame`), with rtmpm-io's
//! writers, and checkpoints (`Simulation.checkpoint`). Pictures are in `picture.rs`.

use crate::errors::RtmpmError;
use crate::simulation::Inner;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rtmpm_io::checkpoint::Checkpoint;
use rtmpm_io::{FrameFields, ply, vtk_appended};
use rtmpm_physics::Particles;
use rtmpm_physics::material::cauchy_stress;
use rtmpm_scene::Scene;
use rtmpm_sim::Backend;
use std::path::Path;

/// Write one frame file; see `Simulation.write_frame`.
pub fn write_frame(
    py: Python<'_>,
    path: &Path,
    format: Option<&str>,
    fields: Option<Vec<String>>,
    p: &Particles,
    scene: &Scene,
) -> PyResult<()> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    let format = format.unwrap_or(ext).to_ascii_lowercase();
    if format != "ply" && format != "vtu" {
        return Err(PyValueError::new_err(format!(
            "unknown frame format {format:?} for {}: use format=\"ply\" or \"vtu\" (or a .ply / .vtu file name)",
            path.display()
        )));
    }
    let (mut stress, mut jacobian) = (scene.output.stress, scene.output.jacobian);
    if let Some(f) = fields {
        (stress, jacobian) = (false, false);
        for name in f {
            match name.as_str() {
                "stress" => stress = true,
                "J" => jacobian = true,
                other => {
                    return Err(PyValueError::new_err(format!(
                        "unknown field {other:?}: the extra fields are \"J\" and \"stress\""
                    )));
                }
            }
        }
    }
    py.detach(|| {
        let stress = stress.then(|| cauchy_stress(p, &scene.materials));
        let jacobian = jacobian.then(|| p.f.iter().map(|f| f.determinant()).collect::<Vec<f32>>());
        let fields = FrameFields {
            stress: stress.as_deref(),
            jacobian: jacobian.as_deref(),
        };
        if format == "ply" {
            ply::write_ply(path, p, &fields)
        } else {
            // The CLI's VTU: compressed appended arrays, 3x3 stress tensors.
            vtk_appended::write_particles_vtu(path, p, &fields, scene.output.compress)
        }
    })
    .map_err(|e| RtmpmError::new_err(format!("writing {}: {e}", path.display())))
}

/// Write a checkpoint of `inner`'s simulation to `path` (atomic): the scene, time, step,
/// frame, every particle and rigid body, the bodies first taking every impulse the grid has sent
/// them (the CUDA backend moves them a step late) so that they are at the particles' time.
pub fn checkpoint(py: Python<'_>, inner: &mut Inner, path: &Path) -> PyResult<()> {
    inner
        .sim
        .backend
        .flush_rigid()
        .map_err(|e| crate::errors::sim_error(py, &e))?;
    let particles = inner.host(py)?.clone();
    let scene = inner.scene.get();
    let ckpt = Checkpoint {
        scene_toml: scene.text.clone(),
        scene_origin: scene.origin.clone(),
        time: inner.sim.time,
        step: inner.sim.step,
        frame: inner.sim.frame,
        bodies: inner.sim.backend.rigid_poses(),
        particles,
    };
    py.detach(|| ckpt.save(path))
        .map_err(|e| RtmpmError::new_err(format!("writing checkpoint {}: {e}", path.display())))
}
