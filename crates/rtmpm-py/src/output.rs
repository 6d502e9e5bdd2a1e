//! Frame files of the particles in memory (`Simulation.write_frame`), with rtmpm-io's
//! writers, and checkpoints (`Simulation.checkpoint`). Pictures are in `picture.rs`.

use crate::errors::RtmpmError;
use crate::state::Inner;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rtmpm_driver::output::write_frame_files;
use rtmpm_io::checkpoint::Checkpoint;
use rtmpm_io::frame::Derived;
use rtmpm_physics::Particles;
use rtmpm_rigid::BodyPose;
use rtmpm_scene::Scene;
use rtmpm_sim::Backend;
use std::path::Path;

/// Write one frame file in any format of the registry ([`rtmpm_io::FRAME_FORMATS`]), the
/// rigid bodies at their poses `bodies`, through the driver's frame writer (as `rtmpm run`);
/// see `Simulation.write_frame`.
pub fn write_frame(
    py: Python<'_>,
    path: &Path,
    format: Option<&str>,
    fields: Option<Vec<String>>,
    p: &Particles,
    bodies: &[BodyPose],
    scene: &Scene,
) -> PyResult<()> {
    let file_name = path.file_name().and_then(|e| e.to_str()).unwrap_or("");
    let found = match format {
        Some(name) => rtmpm_io::frame_format(&name.to_ascii_lowercase()),
        None => rtmpm_io::frame_format_of(&file_name.to_ascii_lowercase()),
    };
    let Some(format) = found else {
        let what = match format {
            Some(name) => format!("unknown frame format {name:?}"),
            None => format!("no frame format has the extension of {file_name:?}"),
        };
        return Err(PyValueError::new_err(format!(
            "{what} for {}: use format= any of {} (or a file name with its extension)",
            path.display(),
            rtmpm_io::frame_format_names()
        )));
    };
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
    let derived = Derived { stress, jacobian };
    let files = [(path.to_path_buf(), format)];
    py.detach(|| write_frame_files(&files, p, bodies, scene, derived, &[]))
        .map_err(|e| RtmpmError::new_err(format!("{e:#}")))
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
        files: inner.sim.scene.file_hashes(),
        particles,
    };
    py.detach(|| ckpt.save(path))
        .map_err(|e| RtmpmError::new_err(format!("writing checkpoint {}: {e}", path.display())))
}
