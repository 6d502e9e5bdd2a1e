//! A GPU batch's particles on the device, for PyTorch, CuPy, JAX (DLPack and the CUDA Array
//! Interface, [`crate::device::DeviceArray`]):
//!
//! * `x_device`, `v_device`: every world's positions / velocities in original order, each world
//!   in its own coordinates, shaped as the host arrays `x` / `v` (`(N, n, 3)` when every world
//!   holds `n` particles, else `(total, 3)` cut by `offsets`). The batch keeps all worlds in one
//!   state buffer sorted by grid block, and its worlds' blocks interleave there (Morton codes),
//!   so no per-world view of that buffer exists: these are a device-side gather (the export
//!   kernel, `CudaBackend::gather_vec3_device`) into float32 arrays the batch allocates at the
//!   first read and keeps. After every call that changes the state (steps, resets) the batch
//!   gathers them again into the same memory, so a tensor made once follows the batch. A frozen
//!   world's rows are its host rows (its last good state), as `x` / `v` give them.
//! * `storage_device(name)`: views of the batch's own state buffer (no copy at all), in the
//!   GPU's storage order, as `Simulation.particles.x_device` and the others.

use super::{Gathered, PyBatch, Run};
use crate::device::{DeviceArray, Elem};
use crate::errors::{backend_error, sim_error};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rtmpm_cuda::batch::CudaBatch;
use rtmpm_cuda::contract::StateLayout;
use rtmpm_cuda::export::ordered::OrderedDeviceVec3;
use rtmpm_driver::batch::WorldStatus;
use rtmpm_driver::batch::lockstep::LockstepRun;
use rtmpm_sim::SimError;

/// Which gathered array.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Field {
    X,
    V,
}

impl Gathered {
    /// Before a call changes the state: wait for every stream of the device (PyTorch or CuPy
    /// kernels still reading the arrays), once a view was handed out.
    pub(super) fn before_call(&self, run: &mut Run) -> Result<(), SimError> {
        match run {
            Run::Lockstep(r) if self.exported => r.sim.backend.backend().wait_for_device(),
            _ => Ok(()),
        }
    }

    /// After a call: the gathered arrays again, from the state the call left.
    pub(super) fn after_call(&mut self, run: &mut Run) -> Result<(), SimError> {
        let Run::Lockstep(r) = run else {
            return Ok(());
        };
        for (field, out) in [(Field::X, &mut self.x), (Field::V, &mut self.v)] {
            if let Some(out) = out {
                fill(r, field, out)?;
            }
        }
        Ok(())
    }
}

/// Gather `field` of every world into `out`, then put each frozen world's host rows over its
/// parked device state (the GPU holds a frozen world at rest, unstressed: `LockstepRun`).
fn fill(
    r: &mut LockstepRun<CudaBatch>,
    field: Field,
    out: &mut OrderedDeviceVec3,
) -> Result<(), SimError> {
    let b = r.sim.backend.backend();
    let l = b.state_layout();
    b.gather_vec3_device(if field == Field::X { l.x() } else { l.v() }, out)?;
    let mut row = 0;
    for w in &r.worlds {
        let p = w.particles();
        if w.status != WorldStatus::Running {
            let rows = if field == Field::X { &p.x } else { &p.v };
            let flat: Vec<f32> = rows.iter().flat_map(|v| v.to_array()).collect();
            out.write_rows(row, &flat)?;
        }
        row += p.len();
    }
    Ok(())
}

/// The run on the GPU, or the error that names the backend device arrays need.
fn lockstep<'a>(run: &'a mut Run, what: &str) -> PyResult<&'a mut LockstepRun<CudaBatch>> {
    match run {
        Run::Lockstep(r) => Ok(&mut **r),
        Run::Each(_) => Err(backend_error(format!(
            "BatchSimulation.{what}: device arrays of a batch need every world in the same CUDA \
             kernels; this batch runs on the CPU backend: create it with backend=\"cuda\" (the \
             host arrays x, v, mass, material work on every backend)"
        ))),
    }
}

impl PyBatch {
    /// The view of gathered `field`, gathering it first at its first read.
    fn gathered_view(slf: &Bound<'_, Self>, field: Field) -> PyResult<DeviceArray> {
        let py = slf.py();
        let owner = slf.clone().into_any().unbind();
        let mut me = slf.borrow_mut();
        me.usable()?;
        let counts = me.counts();
        let name = if field == Field::X {
            "x_device"
        } else {
            "v_device"
        };
        let PyBatch { run, device, .. } = &mut *me;
        let run = match run.get_mut() {
            Ok(r) => r.get(),
            Err(poisoned) => poisoned.into_inner().get(),
        };
        let r = lockstep(run, name)?;
        let slot = if field == Field::X {
            &mut device.x
        } else {
            &mut device.v
        };
        if slot.is_none() {
            let mut out = r
                .sim
                .backend
                .backend()
                .ordered_device_vec3()
                .map_err(|e| sim_error(py, &e))?;
            fill(r, field, &mut out).map_err(|e| sim_error(py, &e))?;
            *slot = Some(out);
        }
        let Some(out) = slot.as_ref() else {
            return Err(backend_error("the gathered device array is missing"));
        };
        device.exported = true;
        let total: usize = counts.iter().sum();
        let shape = match counts.first() {
            Some(&n) if counts.iter().all(|&c| c == n) => vec![counts.len(), n, 3],
            _ => vec![total, 3],
        };
        Ok(DeviceArray::contiguous_f32(
            owner,
            out.ptr(),
            out.device(),
            &shape,
        ))
    }
}

/// The state word(s), per-particle shape and element type of the storage view `name`, or why
/// the layout `l` has none.
fn storage_field(name: &str, l: StateLayout) -> PyResult<(usize, &'static [usize], Elem)> {
    let (field, inner, elem): (Option<usize>, &'static [usize], Elem) = match name {
        "x" => (Some(l.x()), &[3], Elem::Real),
        "v" => (Some(l.v()), &[3], Elem::Real),
        "F" => ((!l.fluid()).then(|| l.f()), &[3, 3], Elem::Real),
        "C" => ((!l.compact()).then(|| l.c()), &[3, 3], Elem::Real),
        "material" => (Some(l.material()), &[], Elem::Int32),
        "id" => (Some(l.id()), &[], Elem::Int32),
        "mass" => (Some(l.mass()), &[], Elem::Real),
        "vol0" => (Some(l.vol0()), &[], Elem::Real),
        "plastic" => (l.plastic(), &[], Elem::Real),
        _ => {
            return Err(PyValueError::new_err(format!(
                "storage_device({name:?}): no such field; one of \"x\", \"v\", \"F\", \"C\", \
                 \"material\", \"id\", \"mass\", \"vol0\", \"plastic\""
            )));
        }
    };
    match field {
        Some(f) => Ok((f, inner, elem)),
        None => Err(backend_error(format!(
            "storage_device({name:?}): not in the GPU's particle state layout `{}` (the fluid \
             layout keeps F as the one word J^(1/3) and no plastic word; the compact one keeps C \
             in shared-exponent words): run with cuda_options=\"fluid_state=off\" (fluids) and \
             particle_state = \"f32\"",
            l.name()
        ))),
    }
}

#[pymethods]
impl PyBatch {
    /// Every world's positions on the GPU, float32, shaped as :attr:`x` (``(N, n, 3)``, or
    /// ``(total, 3)`` cut by :attr:`offsets`), each world in its own coordinates, in original
    /// order: a :class:`rtmpm.DeviceArray` for ``torch.from_dlpack`` / CuPy. A device-side gather
    /// into memory the batch keeps (the worlds interleave in the GPU's own storage, so no
    /// per-world view of it exists), refreshed in place after every step and reset: a tensor
    /// made once follows the batch. GPU batches only (``backend="cuda"``).
    #[getter]
    fn x_device(slf: &Bound<'_, Self>) -> PyResult<DeviceArray> {
        Self::gathered_view(slf, Field::X)
    }

    /// Every world's velocities on the GPU, as :attr:`x_device`.
    #[getter]
    fn v_device(slf: &Bound<'_, Self>) -> PyResult<DeviceArray> {
        Self::gathered_view(slf, Field::V)
    }

    /// A view of the batch's own GPU state (no copy), as ``Simulation.particles.<name>_device``:
    /// ``name`` one of ``"x"``, ``"v"``, ``"F"``, ``"C"``, ``"material"``, ``"id"``,
    /// ``"mass"``, ``"vol0"``, ``"plastic"``; ``(total, ...)`` rows in the GPU's storage order
    /// (every world's particles mixed, sorted by grid block; it changes at every step): row
    /// ``j`` holds particle ``id[j]`` of the flat arrays (world ``w`` for ``offsets[w] <= id[j]
    /// < offsets[w + 1]``), its ``material`` is ``w * len(scene.materials) + k``. Float32
    /// (float64 in f64), strided; valid until the next call that changes the state; read-only.
    fn storage_device(slf: &Bound<'_, Self>, name: &str) -> PyResult<DeviceArray> {
        let py = slf.py();
        let owner = slf.clone().into_any().unbind();
        let mut me = slf.borrow_mut();
        me.usable()?;
        let PyBatch { run, device, .. } = &mut *me;
        let run = match run.get_mut() {
            Ok(r) => r.get(),
            Err(poisoned) => poisoned.into_inner().get(),
        };
        let r = lockstep(run, "storage_device")?;
        let d = r
            .sim
            .backend
            .backend()
            .device_particles()
            .map_err(|e| sim_error(py, &e))?;
        let (field, inner, elem) = storage_field(name, d.layout)?;
        device.exported = true;
        Ok(DeviceArray::new(owner, &d, field, inner, elem))
    }
}
