//! `Simulation.frames()`: an iterator that runs a frame per step.

use crate::state::PySimulation;
use pyo3::prelude::*;

/// The iterator of :meth:`Simulation.frames`.
#[pyclass(name = "FrameIterator", module = "rtmpm")]
pub struct FrameIter {
    pub sim: Py<PySimulation>,
    pub left: u64,
}

#[pymethods]
impl FrameIter {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__(&mut self, py: Python<'_>) -> PyResult<Option<u64>> {
        if self.left == 0 {
            return Ok(None);
        }
        self.left -= 1;
        let mut s = self.sim.bind(py).borrow_mut();
        s.run_frame(py)?;
        Ok(Some(s.get().sim.frame))
    }

    fn __len__(&self) -> usize {
        self.left as usize
    }
}
