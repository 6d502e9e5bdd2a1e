//! Checkpoints of a batch from Python: every world saved into a folder (rtmpm-driver's
//! `BatchRun::checkpoint`); `BatchSimulation.resume` (create.rs) continues one.

use super::{PyBatch, Run};
use pyo3::prelude::*;
use std::path::PathBuf;

#[pymethods]
impl PyBatch {
    /// Write a checkpoint of every world into the folder ``path`` (made if missing; a folder
    /// holding other files is refused): ``batch.toml`` (each world's label and status) and
    /// ``world_NNN.ckpt`` per world (the format of :meth:`Simulation.checkpoint`: time, step,
    /// frame, particles, rigid bodies; a frozen world's last good state; on the GPU each
    /// world's own clock). Continue with :meth:`BatchSimulation.resume`.
    fn checkpoint(&mut self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let s = self.scene.get();
        let (text, origin) = (s.text.clone(), s.origin.clone());
        self.drive(py, move |run| {
            match run {
                Run::Each(run) => run.checkpoint(&path, &text, &origin)?,
                Run::Lockstep(run) => run.checkpoint(&path, &text, &origin)?,
            }
            Ok(Vec::new())
        })?;
        Ok(())
    }
}
