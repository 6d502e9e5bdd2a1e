//! `rtmpm.BatchSimulation`: many worlds of one scene stepped together (rtmpm-driver's
//! [`rtmpm_driver::batch::BatchRun`] on the CPU backend, its `LockstepRun` over rtmpm-cuda's `CudaBatch` on one GPU:
//! [`run::Run`]), read and steered world by world from Python: particle arrays of every world
//! at once, resets of chosen worlds, kinematic rigid bodies (tools, pushers) posed per world,
//! the load the material puts on them, and each world's status (a world that blows up is
//! frozen, the others go on), checkpoints of them all, and on the GPU the particles on the
//! device for PyTorch and CuPy ([`device`]). `rtmpm.Simulation(scene, batch=N)` (or a scene
//! with `[batch]`) returns one (python/rtmpm/__init__.py). Documentation: docs/batch.md,
//! docs/python.md.

mod arrays;
mod checkpoint;
mod create;
mod device;
mod reset;
mod rigid;
mod run;
mod status;
mod step;

use crate::errors::{SimulationError, internal_error};
use crate::scene::PyScene;
use pyo3::exceptions::{PyIndexError, PyValueError};
use pyo3::prelude::*;
use rtmpm_backends::BackendRequest;
use rtmpm_physics::Particles;
use run::Run;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Mutex;

/// The batch run, movable to the thread that steps it with the interpreter lock released.
struct Worlds(Run);

// SAFETY: on the CPU, `BatchRun` holds each world's backend as a `Box<dyn Backend>`, which is
// not `Send` by its type. Every backend this module puts in one is an
// `rtmpm_backends::AnyBackend` (`make_backend`, the only constructor used by
// `BatchSimulation::new` and `reset`), which is `Send` (rtmpm-backends states why for its CUDA
// variant). On the GPU, the `LockstepRun` holds a `CudaBatch`, whose only part that is not
// `Send` is its `CudaBackend`'s CUDA graph: `rtmpm_backends::CudaSend` states why that backend
// may move between threads (driver handles are not tied to a thread; cudarc binds the context
// before each use). The rest of the run (scenes, frame outputs, which this module never opens)
// is plain data. The run is used by one thread at a time (`&mut self`).
unsafe impl Send for Worlds {}

impl Worlds {
    fn get(&mut self) -> &mut Run {
        &mut self.0
    }
}

/// The batch's gathered device arrays (allocated at their first read) and whether any device
/// array was handed out; its methods are in `device.rs`.
#[derive(Default)]
struct Gathered {
    x: Option<rtmpm_cuda::export::ordered::OrderedDeviceVec3>,
    v: Option<rtmpm_cuda::export::ordered::OrderedDeviceVec3>,
    /// A view was handed out: readers on other streams may be at work when a call starts.
    exported: bool,
}

/// Many worlds of one scene, stepped together.
///
/// ``rtmpm.Simulation(scene, batch=N)`` makes ``N`` copies of ``scene``; a scene with
/// ``[batch]`` (docs/batch.md) makes its worlds, each with its swept values (``batch`` may then
/// be left out, or must equal its ``count``). On the CPU backend each world is a simulation of
/// its own (own particles, grid, colliders and rigid bodies: no world can touch another's
/// state), the same results bit for bit as a separate :class:`Simulation` of its scene. On one
/// GPU (``backend="cuda"``, or ``"auto"`` with a usable GPU and a batch it supports) every
/// world runs in the same CUDA kernels, each isolated in the grid, at one time step for all
/// worlds (the smallest any world needs); a world's time, frames and steps count from its last
/// reset; each world's rigid bodies are its own there too. What the GPU batch does not do
/// (emitters, worlds that differ in domain or number of colliders or rigid bodies)
/// raises an error naming it and ``backend="cpu"``.
///
/// Arrays: :attr:`x`, :attr:`v`, :attr:`mass`, :attr:`material` are shaped ``(N, n, ...)``
/// when every world has ``n`` particles (:attr:`uniform`), else flat (all worlds' particles one
/// after another) with world ``w``'s at ``offsets[w]:offsets[w + 1]``. On the GPU,
/// :attr:`x_device` and :attr:`v_device` are the same on the device (for PyTorch, CuPy), and
/// :meth:`storage_device` views the batch's own state. A world that blows up is
/// frozen at its last good state (:attr:`status` says why); the others go on; :meth:`reset`
/// starts chosen worlds again.
///
/// On the GPU :meth:`step` returns with its steps queued (:attr:`overlap`, on by default there,
/// as GPU simulators step asynchronously): a blow-up in a call's steps is returned by the next
/// ``step()``, or seen at once by reading :attr:`running`, :attr:`status` or the particles
/// (which wait for the steps). ``sim.overlap = False``, or ``RTMPM_BATCH_OVERLAP=0`` in the
/// environment as the batch is made, gives the old behaviour: each call returns after its
/// check, with the worlds its own steps froze (as on the CPU, which always does).
#[pyclass(name = "BatchSimulation", module = "rtmpm")]
pub struct PyBatch {
    run: Mutex<Worlds>,
    scene: Py<PyScene>,
    request: BackendRequest,
    reason: String,
    /// Each world's particles at time 0 (what a reset starts from).
    initial: Vec<std::sync::Arc<Particles>>,
    /// Set after a panic: the state may be inconsistent.
    broken: Option<String>,
    /// The device arrays of a GPU batch (`x_device`, `v_device`), refreshed after every call.
    device: Gathered,
    /// Steps a driver call of `step(n)` takes at most (`step.rs`): learnt from the calls'
    /// times, kept between calls.
    chunk: u64,
}

/// A Python error from a batch run's error (`anyhow`, with its context).
fn run_error(e: anyhow::Error) -> PyErr {
    SimulationError::new_err(format!("{e:#}"))
}

impl PyBatch {
    /// Run `work` on the worlds with the interpreter lock released, panics caught (the batch is
    /// then marked broken); returns the worlds frozen. On the GPU, once a device array was
    /// handed out, the call first waits for the device's other streams, and the gathered device
    /// arrays are filled again after it.
    fn drive(
        &mut self,
        py: Python<'_>,
        work: impl FnOnce(&mut Run) -> anyhow::Result<Vec<usize>> + Send,
    ) -> PyResult<Vec<usize>> {
        self.usable()?;
        let run = match self.run.get_mut() {
            Ok(r) => r,
            Err(poisoned) => poisoned.into_inner(),
        };
        let device = &mut self.device;
        let call = |run: &mut Run| -> anyhow::Result<Vec<usize>> {
            device.before_call(run)?;
            let frozen = work(run)?;
            device.after_call(run)?;
            Ok(frozen)
        };
        match py.detach(|| catch_unwind(AssertUnwindSafe(|| call(run.get())))) {
            Ok(r) => r.map_err(run_error),
            Err(payload) => {
                let err = internal_error(payload.as_ref());
                self.broken = Some(err.to_string());
                Err(err)
            }
        }
    }

    /// Every world's particles read to the host where the last call left them on the GPU only
    /// (`Run::sync`: the GPU batch keeps its rewind point on the device and reads the worlds
    /// when something needs them), with the interpreter lock released, panics caught (the
    /// batch is then marked broken).
    fn read_back(&mut self, py: Python<'_>) -> PyResult<()> {
        self.detached(py, Run::sync)
    }

    /// `work` on the run with the interpreter lock released, panics caught (the batch is then
    /// marked broken); unlike [`PyBatch::drive`], no device arrays are gathered after it.
    fn detached<T: Send>(
        &mut self,
        py: Python<'_>,
        work: impl FnOnce(&mut Run) -> anyhow::Result<T> + Send,
    ) -> PyResult<T> {
        self.usable()?;
        let run = match self.run.get_mut() {
            Ok(r) => r,
            Err(poisoned) => poisoned.into_inner(),
        };
        match py.detach(|| catch_unwind(AssertUnwindSafe(|| work(run.get())))) {
            Ok(r) => r.map_err(run_error),
            Err(payload) => {
                let err = internal_error(payload.as_ref());
                self.broken = Some(err.to_string());
                Err(err)
            }
        }
    }

    /// The health check a GPU step call left pending made (`overlap`, [`Run::settle`]) before a
    /// read that must see its outcome (status, running, rigid bodies); nothing to do without
    /// one, or on a batch stopped by an internal error (whose state is read as it was left).
    fn settled(&mut self, py: Python<'_>) -> PyResult<()> {
        let pending = matches!(self.r(), Run::Lockstep(r) if r.check_pending());
        if pending && self.broken.is_none() {
            self.detached(py, Run::settle)?;
        }
        Ok(())
    }

    /// The run (no locking: `&mut self` is exclusive already).
    fn r(&mut self) -> &mut Run {
        match self.run.get_mut() {
            Ok(r) => r.get(),
            Err(poisoned) => poisoned.into_inner().get(),
        }
    }

    fn usable(&self) -> PyResult<()> {
        match &self.broken {
            Some(why) => Err(SimulationError::new_err(format!(
                "this batch stopped after an internal error ({why}); create a new one"
            ))),
            None => Ok(()),
        }
    }

    fn count(&mut self) -> usize {
        self.r().count()
    }

    /// World indices from Python (`None`: every world; negative counts from the end).
    fn world_list(&mut self, worlds: Option<Vec<i64>>) -> PyResult<Vec<usize>> {
        let n = self.count();
        let Some(list) = worlds else {
            return Ok((0..n).collect());
        };
        let mut seen = vec![false; n];
        list.into_iter()
            .map(|w| {
                let i = if w < 0 { w + n as i64 } else { w };
                if !(0..n as i64).contains(&i) {
                    return Err(PyIndexError::new_err(format!(
                        "world {w} does not exist: the batch has {n} worlds (0 to {})",
                        n - 1
                    )));
                }
                let i = i as usize;
                if std::mem::replace(&mut seen[i], true) {
                    return Err(PyValueError::new_err(format!("world {w} is listed twice")));
                }
                Ok(i)
            })
            .collect()
    }
}
