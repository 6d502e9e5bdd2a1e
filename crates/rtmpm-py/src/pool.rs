//! Host arrays whose memory comes back: the NumPy arrays of `particles.x` / `.v` read from the
//! GPU are backed by buffers that return to a small pool when NumPy frees them. Reading `x` every
//! frame then writes into memory that is already mapped; a fresh 24 MB array costs more in page
//! faults than the copy over the bus.

use numpy::PyArray2;
use numpy::ndarray::Array2;
use pyo3::prelude::*;
use std::sync::Mutex;

/// Buffers kept for reuse, at most [`KEEP`] of them and [`KEEP_BYTES`] in all.
static POOL: Mutex<Vec<Vec<f32>>> = Mutex::new(Vec::new());
const KEEP: usize = 4;
const KEEP_BYTES: usize = 1 << 30;

/// A buffer of `len` floats: a returned one of that length, else a new zeroed one.
pub(crate) fn take(len: usize) -> Vec<f32> {
    let mut pool = POOL.lock().unwrap_or_else(|e| e.into_inner());
    match pool.iter().position(|v| v.len() == len) {
        Some(i) => pool.swap_remove(i),
        None => {
            drop(pool);
            vec![0f32; len]
        }
    }
}

fn give_back(v: Vec<f32>) {
    let mut pool = POOL.lock().unwrap_or_else(|e| e.into_inner());
    let bytes = |v: &Vec<f32>| v.len() * 4;
    let held: usize = pool.iter().map(bytes).sum();
    if pool.len() < KEEP && !v.is_empty() && held + bytes(&v) <= KEEP_BYTES {
        pool.push(v);
    }
}

/// Owner of the memory of an `(n, 3)` array (its NumPy `base`); gives the buffer back when NumPy
/// frees the array.
#[pyclass(module = "rtmpm")]
pub(crate) struct PooledBuffer {
    data: Array2<f32>,
}

impl Drop for PooledBuffer {
    fn drop(&mut self) {
        let (v, _) = std::mem::take(&mut self.data).into_raw_vec_and_offset();
        give_back(v);
    }
}

/// An `(len / 3, 3)` float32 NumPy array over `buf` (from [`take`]), which returns to the pool
/// when the array is freed.
pub(crate) fn vec3_array(py: Python<'_>, buf: Vec<f32>) -> PyResult<Bound<'_, PyArray2<f32>>> {
    let n = buf.len() / 3;
    let data = Array2::from_shape_vec((n, 3), buf)
        .map_err(|e| pyo3::exceptions::PyValueError::new_err(format!("array shape: {e}")))?;
    let owner = Bound::new(py, PooledBuffer { data })?;
    let array = {
        let r = owner.borrow();
        // SAFETY: the array's memory is `owner.data`, which is never reallocated or moved out
        // while `owner` lives (only its Drop takes it), and `owner` is the array's base object.
        unsafe { PyArray2::borrow_from_array(&r.data, owner.clone().into_any()) }
    };
    Ok(array)
}
