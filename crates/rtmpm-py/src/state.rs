//! The state behind a `Simulation` object ([`Inner`]: the driver's simulation, the host copy
//! of the particles, the stepping chunk) and the Python class that holds it; its methods are in
//! `simulation.rs`, `particles.rs`, `bodies.rs`, `output.rs` and `picture.rs`.

use crate::errors::{backend_error, internal_error, sim_error};
use crate::scene::PyScene;
use pyo3::prelude::*;
use rtmpm_backends::{AnyBackend, BackendRequest};
use rtmpm_driver::Simulation;
use rtmpm_physics::Particles;
use rtmpm_sim::{Backend, SimError};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Mutex;
use std::time::Instant;

/// Wall time between two checks for Ctrl-C while stepping (s).
pub const CHUNK_SECONDS: f64 = 0.05;

pub type Sim = Simulation<AnyBackend>;

/// The state behind a `Simulation` object.
pub struct Inner {
    pub sim: Sim,
    pub request: BackendRequest,
    /// Which backend was picked and why.
    pub reason: String,
    /// The scene object (kept for `sim.scene` and checkpoints).
    pub scene: Py<PyScene>,
    /// Changes whenever the particle state may have changed (steps, setters).
    pub version: u64,
    /// Host copy of the particles at `version`.
    pub host: Option<(u64, Particles)>,
    /// Steps per call with the interpreter lock released (adapted to [`CHUNK_SECONDS`]).
    pub chunk: u64,
    /// Device arrays were handed out: wait for their readers before the next step.
    pub exported: bool,
    /// Set after a panic: the state may be inconsistent.
    pub broken: Option<String>,
}

impl Inner {
    /// The particles on the host, in original order (read from the backend when stale).
    pub fn host(&mut self, py: Python<'_>) -> PyResult<&Particles> {
        self.usable()?;
        let stale = self.host.as_ref().is_none_or(|(v, _)| *v != self.version);
        if stale {
            let sim = &mut self.sim;
            let mut p = self.host.take().map(|(_, p)| p).unwrap_or_default();
            let r =
                py.detach(|| catch_unwind(AssertUnwindSafe(|| sim.backend.read_particles(&mut p))));
            self.settle(py, r)?;
            self.host = Some((self.version, p));
        }
        match &self.host {
            Some((_, p)) => Ok(p),
            None => Err(backend_error("particles could not be read")),
        }
    }

    pub fn usable(&self) -> PyResult<()> {
        match &self.broken {
            Some(why) => Err(crate::errors::SimulationError::new_err(format!(
                "this simulation stopped after an internal error ({why}); create a new one"
            ))),
            None => Ok(()),
        }
    }

    /// Turn the result of a guarded call into a Python result, marking the simulation broken
    /// after a panic.
    pub fn settle<T>(
        &mut self,
        py: Python<'_>,
        r: std::thread::Result<Result<T, SimError>>,
    ) -> PyResult<T> {
        match r {
            Ok(Ok(v)) => Ok(v),
            Ok(Err(e)) => Err(sim_error(py, &e)),
            Err(payload) => {
                let err = internal_error(payload.as_ref());
                self.broken = Some(err.to_string());
                Err(err)
            }
        }
    }

    /// Run `work(sim, chunk)` with the interpreter lock released until it returns true, in
    /// chunks of about [`CHUNK_SECONDS`], checking for Ctrl-C between chunks.
    pub fn drive(
        &mut self,
        py: Python<'_>,
        mut work: impl FnMut(&mut Sim, u64) -> Result<bool, SimError> + Send,
    ) -> PyResult<()> {
        self.usable()?;
        if self.exported
            && let AnyBackend::Cuda(c) = self.sim.backend.as_mut()
        {
            // Readers of the device arrays (PyTorch, CuPy) may still be at work on their streams.
            c.0.wait_for_device().map_err(|e| sim_error(py, &e))?;
        }
        loop {
            let chunk = self.chunk;
            let sim = &mut self.sim;
            let t0 = Instant::now();
            let r = py.detach(|| catch_unwind(AssertUnwindSafe(|| work(sim, chunk))));
            self.version += 1;
            let elapsed = t0.elapsed().as_secs_f64();
            if elapsed < 0.5 * CHUNK_SECONDS {
                self.chunk = (self.chunk * 2).min(1 << 20);
            } else if elapsed > 2.0 * CHUNK_SECONDS {
                self.chunk = (self.chunk / 2).max(1);
            }
            if self.settle(py, r)? {
                return Ok(());
            }
            py.check_signals()?;
        }
    }
}

/// A simulation of a scene on a backend.
///
/// ``Simulation(scene, backend="auto", precision=None, threads=None, gpus=1)``:
///
/// * ``scene``: an :class:`rtmpm.Scene`, a path to a scene file or a dict;
/// * ``backend``: ``"auto"`` (CUDA when a GPU is usable, else the CPU), ``"cpu"`` or ``"cuda"``;
///   :attr:`backend` says what was picked and why;
/// * ``precision``: ``"f32"`` or ``"f64"`` (default: the scene's ``[solver] precision``);
/// * ``threads``: CPU worker threads (default: one per core);
/// * ``gpus``: GPUs of this machine to split the particles over (CUDA), an int or ``"all"``;
/// * ``cuda_options``: the switches of ``rtmpm run --cuda-options``, e.g. ``"graph=off"``.
///
/// The particles are in :attr:`particles`; :meth:`step`, :meth:`run_frame`, :meth:`advance`,
/// :meth:`frames` and :meth:`run` move the simulation on.
#[pyclass(name = "Simulation", module = "rtmpm", subclass)]
pub struct PySimulation {
    pub inner: Mutex<Inner>,
}

impl PySimulation {
    /// The state (no locking: `&mut self` is exclusive already).
    pub fn get(&mut self) -> &mut Inner {
        match self.inner.get_mut() {
            Ok(i) => i,
            Err(poisoned) => poisoned.into_inner(),
        }
    }
}
