//! The worlds' particle arrays: `(N, n, ...)` when every world holds `n` particles, else flat
//! with `offsets`; and the float32 reading of arrays given from Python.

use super::PyBatch;
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArrayDyn};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rtmpm_physics::Particles;

impl PyBatch {
    /// Particle counts of the worlds.
    pub(super) fn counts(&mut self) -> Vec<usize> {
        let r = self.r();
        (0..r.count()).map(|w| r.particles(w).len()).collect()
    }

    /// Every world's `field` one after another, shaped `(N, n, *shape)` when all worlds have
    /// `n` particles, else `(total, *shape)`.
    fn gather<'py, T: numpy::Element + Copy>(
        &mut self,
        py: Python<'py>,
        shape: &[usize],
        field: impl Fn(&Particles) -> Vec<T>,
    ) -> PyResult<Bound<'py, PyAny>> {
        self.read_back(py)?;
        let counts = self.counts();
        let mut flat = Vec::new();
        let r = self.r();
        for w in 0..r.count() {
            flat.extend(field(r.particles(w)));
        }
        let a = PyArray1::from_vec(py, flat);
        let mut dims: Vec<usize> = match counts.first() {
            Some(&n) if counts.iter().all(|&c| c == n) => vec![counts.len(), n],
            _ => vec![counts.iter().sum()],
        };
        dims.extend_from_slice(shape);
        Ok(a.reshape(dims)?.into_any())
    }
}

/// `value` (an array, a list, any sequence NumPy reads) as float32 numbers.
pub(super) fn f32_array<'py>(
    name: &str,
    value: &Bound<'py, PyAny>,
) -> PyResult<PyReadonlyArrayDyn<'py, f32>> {
    let np = value.py().import("numpy")?;
    let a = np
        .call_method1("asarray", (value, "float32"))
        .map_err(|e| PyValueError::new_err(format!("{name}: not an array of numbers ({e})")))?;
    Ok(a.cast_into::<numpy::PyArrayDyn<f32>>()?.readonly())
}

#[pymethods]
impl PyBatch {
    /// True when every world has the same number of particles (the arrays are then
    /// ``(N, n, ...)``; otherwise flat, cut by :attr:`offsets`).
    #[getter]
    fn uniform(&mut self) -> bool {
        let c = self.counts();
        c.iter().all(|&n| n == c[0])
    }

    /// ``(N,)`` int64 array: each world's number of particles.
    #[getter]
    fn num_particles<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        PyArray1::from_vec(py, self.counts().iter().map(|&n| n as i64).collect())
    }

    /// ``(N + 1,)`` int64 array: world ``w``'s particles are rows ``offsets[w]:offsets[w+1]``
    /// of the flat arrays (``x.reshape(-1, 3)`` when :attr:`uniform`).
    #[getter]
    fn offsets<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        let mut o = vec![0i64];
        for n in self.counts() {
            o.push(o[o.len() - 1] + n as i64);
        }
        PyArray1::from_vec(py, o)
    }

    /// Positions (m), float32: ``(N, n, 3)``, or ``(total, 3)`` for worlds of different sizes.
    /// A copy, of the state after the last call (a frozen world's: its last good state).
    #[getter]
    fn x<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.gather(py, &[3], |p| {
            p.x.iter().flat_map(|v| v.to_array()).collect()
        })
    }

    /// Velocities (m/s), float32, shaped as :attr:`x`.
    #[getter]
    fn v<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.gather(py, &[3], |p| {
            p.v.iter().flat_map(|v| v.to_array()).collect()
        })
    }

    /// Masses (kg), float32: ``(N, n)`` or ``(total,)``.
    #[getter]
    fn mass<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.gather(py, &[], |p| p.mass.clone())
    }

    /// Material indices, int32: ``(N, n)`` or ``(total,)``.
    #[getter]
    fn material<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.gather(py, &[], |p| p.material.iter().map(|&m| m as i32).collect())
    }
}
