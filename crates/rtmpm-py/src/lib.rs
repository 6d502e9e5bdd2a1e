//! rtmpm for Python: the `rtmpm._rtmpm` extension module (pyo3, stable ABI 3.9+), wrapped by
//! the `rtmpm` package (`python/rtmpm/__init__.py`). Documentation: docs/python.md.
//!
//! * [`scene`]: `Scene` (file, TOML text or dict; rtmpm-scene's validation and messages).
//! * [`state`]: the state behind a `Simulation`; [`simulation`]: its methods (backend choice
//!   through rtmpm-backends, stepping with the interpreter lock released and Ctrl-C checks,
//!   checkpoints, frames, rendering).
//! * [`batch`]: `BatchSimulation`, many worlds of a scene stepped together.
//! * [`particles`]: `Particles` (NumPy arrays in original order, setters).
//! * [`device`]: `DeviceArray` (zero-copy DLPack / CUDA Array Interface views on the GPU).
//! * [`validate`]: `rtmpm.validate()`, the published validation cases.
//! * [`errors`]: the exceptions.

mod backend;
mod batch;
mod bodies;
mod device;
mod dict_toml;
mod errors;
mod frames;
mod output;
mod particles;
mod picture;
mod pool;
mod scene;
mod simulation;
mod state;
mod validate;
mod view;

use pyo3::prelude::*;
use std::path::PathBuf;

/// Read a PLY frame written by ``rtmpm run`` or :meth:`Simulation.write_frame` into a dict of
/// NumPy arrays, one per column (``x``, ``y``, ``z``, ``vx``, ... as float32; integer columns
/// as int64).
#[pyfunction]
fn read_ply<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
    use rtmpm_io::ply::{PlyColumn, read_ply as read};
    let data = py
        .detach(|| read(&path))
        .map_err(|e| errors::RtmpmError::new_err(format!("{}: {e}", path.display())))?;
    let d = pyo3::types::PyDict::new(py);
    for name in data.names() {
        match data.column(name) {
            Some(PlyColumn::Float(v)) => d.set_item(name, numpy::PyArray1::from_slice(py, v))?,
            Some(PlyColumn::Double(v)) => d.set_item(name, numpy::PyArray1::from_slice(py, v))?,
            Some(PlyColumn::Int(v)) => d.set_item(name, numpy::PyArray1::from_slice(py, v))?,
            _ => {}
        }
    }
    Ok(d)
}

/// ``(True, description)`` when the CUDA backend can run here, else ``(False, why not)``.
#[pyfunction]
fn cuda_available() -> (bool, String) {
    match rtmpm_cuda::probe() {
        Ok(info) => (
            true,
            format!(
                "{} (compute capability {}.{}, {} SMs, {:.1} GiB)",
                info.name,
                info.compute_capability.0,
                info.compute_capability.1,
                info.sm_count,
                info.memory as f64 / (1u64 << 30) as f64
            ),
        ),
        Err(e) => (false, e.to_string()),
    }
}

#[pymodule]
fn _rtmpm(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add(
        "features",
        pyo3::types::PyTuple::new(py, bodies::features())?,
    )?;
    // The frame formats of `Simulation.write_frame` and `[output] formats`.
    let formats = rtmpm_io::FRAME_FORMATS.iter().map(|f| f.name);
    m.add("frame_formats", pyo3::types::PyTuple::new(py, formats)?)?;
    m.add_class::<scene::PyScene>()?;
    m.add_class::<state::PySimulation>()?;
    m.add_class::<batch::PyBatch>()?;
    m.add_class::<backend::BackendInfo>()?;
    m.add_class::<frames::FrameIter>()?;
    m.add_class::<particles::PyParticles>()?;
    m.add_class::<device::DeviceArray>()?;
    m.add_class::<view::LiveView>()?;
    m.add("RtmpmError", py.get_type::<errors::RtmpmError>())?;
    m.add("SceneError", py.get_type::<errors::SceneError>())?;
    m.add("SimulationError", py.get_type::<errors::SimulationError>())?;
    m.add("BackendError", py.get_type::<errors::BackendError>())?;
    m.add_function(wrap_pyfunction!(read_ply, m)?)?;
    m.add_function(wrap_pyfunction!(cuda_available, m)?)?;
    m.add_function(wrap_pyfunction!(device::_layout_view, m)?)?;
    m.add_function(wrap_pyfunction!(validate::validate, m)?)?;
    m.add_function(wrap_pyfunction!(validate::validation_cases, m)?)?;
    Ok(())
}
