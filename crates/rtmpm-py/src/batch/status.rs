//! What the worlds are: their number, labels, scene and backend, each world's state (running
//! or frozen, and why), time, frames and steps.

use super::PyBatch;
use crate::backend::BackendInfo;
use crate::scene::PyScene;
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rtmpm_driver::batch::WorldStatus;

#[pymethods]
impl PyBatch {
    /// Number of worlds.
    fn __len__(&mut self) -> usize {
        self.count()
    }

    /// Number of worlds.
    #[getter]
    fn worlds(&mut self) -> usize {
        self.count()
    }

    /// What sets each world apart (``"material[0].yield_stress = 150"``, or ``"world 3"``).
    #[getter]
    fn labels(&mut self) -> Vec<String> {
        let r = self.r();
        (0..r.count()).map(|w| r.label(w).to_string()).collect()
    }

    /// The scene (:class:`rtmpm.Scene`) the worlds come from.
    #[getter]
    fn scene(&mut self, py: Python<'_>) -> Py<PyScene> {
        self.scene.clone_ref(py)
    }

    /// The backend of the worlds and why (:class:`rtmpm.BackendInfo`).
    #[getter]
    fn backend(&mut self) -> BackendInfo {
        let r = self.r();
        let (kind, name) = (r.kind().to_string(), r.backend_name());
        BackendInfo {
            kind,
            name,
            reason: self.reason.clone(),
        }
    }

    /// Each world's state: a dict with ``world``, ``state`` (``"running"`` or ``"frozen"``),
    /// ``frame`` (frames completed; for a frozen world the one it keeps), ``steps`` and
    /// ``reason`` (why it froze, ``None`` while running). On the GPU a world's frames and steps
    /// count from its last reset. With :attr:`overlap` (the GPU's default) it first makes the
    /// last :meth:`step` call's health check, waiting for its steps: a world they froze reads
    /// ``"frozen"`` here before the next ``step()`` returns it.
    #[getter]
    fn status<'py>(&mut self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.settled(py)?;
        let r = self.r();
        (0..r.count())
            .map(|w| {
                let d = PyDict::new(py);
                d.set_item("world", w)?;
                let (_, frame, steps) = r.clock(w);
                match (r.status(w), r.kind()) {
                    (WorldStatus::Running, _) => {
                        d.set_item("state", "running")?;
                        d.set_item("frame", frame)?;
                        d.set_item("reason", py.None())?;
                    }
                    (WorldStatus::Frozen { frame: at, reason }, kind) => {
                        d.set_item("state", "frozen")?;
                        // On the GPU the status holds the shared clock's frame.
                        d.set_item("frame", if kind == "cpu" { *at } else { frame })?;
                        d.set_item("reason", reason)?;
                    }
                }
                d.set_item("steps", steps)?;
                Ok(d)
            })
            .collect()
    }

    /// ``(N,)`` bool array: True where a world is running, False where it is frozen. With
    /// :attr:`overlap` (the GPU's default) it first makes the last :meth:`step` call's health
    /// check, waiting for its steps, as :attr:`status` does.
    #[getter]
    fn running<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<bool>>> {
        self.settled(py)?;
        let r = self.r();
        let running = (0..r.count()).map(|w| *r.status(w) == WorldStatus::Running);
        Ok(PyArray1::from_vec(py, running.collect()))
    }

    /// ``(N,)`` float64 array: each world's simulated time (s). With :attr:`overlap` on, read
    /// without waiting for the last step call's check: a world that check then freezes goes
    /// back to its frame's time.
    #[getter]
    fn time<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let r = self.r();
        PyArray1::from_vec(py, (0..r.count()).map(|w| r.clock(w).0).collect())
    }

    /// ``(N,)`` uint64 array: frames each world has completed.
    #[getter]
    fn frame<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        let r = self.r();
        PyArray1::from_vec(py, (0..r.count()).map(|w| r.clock(w).1).collect())
    }

    /// ``(N,)`` uint64 array: steps each world has taken.
    #[getter]
    fn steps<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        let r = self.r();
        PyArray1::from_vec(py, (0..r.count()).map(|w| r.clock(w).2).collect())
    }

    fn __repr__(&mut self) -> String {
        let frozen = self.count() - self.r().running();
        let (worlds, particles) = (self.count(), self.counts().iter().sum::<usize>());
        format!(
            "BatchSimulation(scene={:?}, worlds={worlds}, frozen={frozen}, particles={particles})",
            self.scene.get().scene.name,
        )
    }
}
