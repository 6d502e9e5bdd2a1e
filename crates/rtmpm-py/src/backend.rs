//! The backend arguments of `rtmpm.Simulation` and what `Simulation.backend` reports.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rtmpm_backends::{BackendKind, BackendRequest};

/// The backend request of `Simulation(backend=..., threads=..., gpus=..., cuda_options=...)`.
pub fn request(
    backend: &str,
    threads: Option<usize>,
    gpus: &Bound<'_, PyAny>,
    cuda_options: Option<&str>,
) -> PyResult<BackendRequest> {
    let kind: BackendKind = backend.parse().map_err(PyValueError::new_err)?;
    let gpus = if let Ok(s) = gpus.extract::<String>() {
        if s != "all" {
            return Err(PyValueError::new_err(format!(
                "gpus={s:?}: expected a number of GPUs or \"all\""
            )));
        }
        rtmpm_cuda::device_count().max(1)
    } else {
        let n: usize = gpus.extract().map_err(|_| {
            PyValueError::new_err("gpus must be a positive number of GPUs or \"all\"")
        })?;
        if n == 0 {
            return Err(PyValueError::new_err("gpus must be at least 1"));
        }
        n
    };
    if threads == Some(0) {
        return Err(PyValueError::new_err("threads must be at least 1"));
    }
    let cuda = match cuda_options {
        Some(s) => s
            .parse::<rtmpm_cuda::CudaOptions>()
            .map_err(|e| PyValueError::new_err(format!("cuda_options: {e}")))?,
        None => Default::default(),
    };
    Ok(BackendRequest {
        kind,
        threads,
        gpus,
        cuda,
    })
}

/// What :attr:`Simulation.backend` says: the backend picked and why.
#[pyclass(name = "BackendInfo", module = "rtmpm", frozen, get_all)]
pub struct BackendInfo {
    /// ``"cpu"`` or ``"cuda"``.
    pub kind: String,
    /// The backend's name, e.g. ``"cpu (2 threads)"`` or ``"cuda (NVIDIA H100 80GB HBM3)"``.
    pub name: String,
    /// What was asked for and why this backend was picked.
    pub reason: String,
}

#[pymethods]
impl BackendInfo {
    fn __str__(&self) -> String {
        self.reason.clone()
    }
    fn __repr__(&self) -> String {
        format!(
            "BackendInfo(kind={:?}, name={:?}, reason={:?})",
            self.kind, self.name, self.reason
        )
    }
}
