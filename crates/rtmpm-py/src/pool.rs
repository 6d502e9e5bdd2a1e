//! Host arrays whose memory comes back: the NumPy arrays of `particles.x` / `.v` read from the
//! GPU are backed by buffers that return to a small pool when NumPy frees them. On the CUDA
//! backend the buffers are page-locked, so the GPU copies straight into the array's memory at the
//! bus's rate; a fresh 24 MB pageable array costs more in page faults than the copy itself.

use numpy::PyArray2;
use numpy::ndarray::{Array2, ArrayView2};
use pyo3::prelude::*;
use rtmpm_cuda::PinnedHostSlice;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Buffers kept for reuse, at most [`KEEP`] of them and [`KEEP_BYTES`] in all.
static POOL: Mutex<Vec<Buf>> = Mutex::new(Vec::new());
const KEEP: usize = 4;
const KEEP_BYTES: usize = 1 << 30;
/// Page-locked bytes alive (in the pool or under arrays): at most [`PIN_BYTES`]; past it, reads
/// go through the chunked copy into pageable memory.
static PINNED: AtomicUsize = AtomicUsize::new(0);
const PIN_BYTES: usize = 1 << 30;

/// A float buffer: pageable (a `Vec`) or page-locked (CUDA).
pub(crate) enum Buf {
    Host(Vec<f32>),
    Pinned(Pinned),
}

/// Page-locked memory, counted in [`PINNED`] while it lives.
pub(crate) struct Pinned(PinnedHostSlice<f32>);

impl Pinned {
    /// `make()` page-locked memory of `len` floats if the limit allows it (else `None`).
    pub(crate) fn new<E>(
        len: usize,
        make: impl FnOnce() -> Result<PinnedHostSlice<f32>, E>,
    ) -> Result<Option<Pinned>, E> {
        let bytes = len * 4;
        if PINNED.fetch_add(bytes, Ordering::SeqCst) + bytes > PIN_BYTES {
            PINNED.fetch_sub(bytes, Ordering::SeqCst);
            return Ok(None);
        }
        match make() {
            Ok(s) => Ok(Some(Pinned(s))),
            Err(e) => {
                PINNED.fetch_sub(bytes, Ordering::SeqCst);
                Err(e)
            }
        }
    }

    pub(crate) fn slice(&mut self) -> &mut PinnedHostSlice<f32> {
        &mut self.0
    }
}

impl Drop for Pinned {
    fn drop(&mut self) {
        PINNED.fetch_sub(self.0.len() * 4, Ordering::SeqCst);
    }
}

impl Buf {
    fn len(&self) -> usize {
        match self {
            Buf::Host(v) => v.len(),
            Buf::Pinned(p) => p.0.len(),
        }
    }
}

/// A pageable buffer of `len` floats: a returned one of that length, else a new zeroed one.
pub(crate) fn take(len: usize) -> Vec<f32> {
    let mut pool = POOL.lock().unwrap_or_else(|e| e.into_inner());
    let found = pool
        .iter()
        .position(|b| matches!(b, Buf::Host(v) if v.len() == len));
    if let Some(Buf::Host(v)) = found.map(|i| pool.swap_remove(i)) {
        return v;
    }
    drop(pool);
    vec![0f32; len]
}

/// A returned page-locked buffer of `len` floats, if the pool holds one.
pub(crate) fn take_pinned(len: usize) -> Option<Pinned> {
    let mut pool = POOL.lock().unwrap_or_else(|e| e.into_inner());
    let i = pool
        .iter()
        .position(|b| matches!(b, Buf::Pinned(p) if p.0.len() == len))?;
    match pool.swap_remove(i) {
        Buf::Pinned(p) => Some(p),
        Buf::Host(_) => None,
    }
}

fn give_back(b: Buf) {
    let mut pool = POOL.lock().unwrap_or_else(|e| e.into_inner());
    let held: usize = pool.iter().map(|b| b.len() * 4).sum();
    if pool.len() < KEEP && b.len() > 0 && held + b.len() * 4 <= KEEP_BYTES {
        pool.push(b);
    }
}

/// What backs an array: an owned pageable array, or page-locked memory viewed as `(n, 3)`.
enum Data {
    Host(Array2<f32>),
    Pinned(Pinned),
}

/// Owner of the memory of an `(n, 3)` array (its NumPy `base`); gives the buffer back when NumPy
/// frees the array.
#[pyclass(module = "rtmpm")]
pub(crate) struct PooledBuffer {
    data: Option<Data>,
}

impl Drop for PooledBuffer {
    fn drop(&mut self) {
        match self.data.take() {
            Some(Data::Host(a)) => give_back(Buf::Host(a.into_raw_vec_and_offset().0)),
            Some(Data::Pinned(p)) => give_back(Buf::Pinned(p)),
            None => {}
        }
    }
}

/// An `(len / 3, 3)` float32 NumPy array over `buf` (from [`take`] or [`take_pinned`]), which
/// returns to the pool when the array is freed.
pub(crate) fn vec3_array(py: Python<'_>, buf: Buf) -> PyResult<Bound<'_, PyArray2<f32>>> {
    let n = buf.len() / 3;
    let data =
        match buf {
            Buf::Host(v) => Data::Host(Array2::from_shape_vec((n, 3), v).map_err(|e| {
                pyo3::exceptions::PyValueError::new_err(format!("array shape: {e}"))
            })?),
            Buf::Pinned(p) => Data::Pinned(p),
        };
    let owner = Bound::new(py, PooledBuffer { data: Some(data) })?;
    let container = owner.clone().into_any();
    let mut r = owner.borrow_mut();
    // SAFETY (both arms): the array's memory is `owner.data`, which is never reallocated or moved
    // out while `owner` lives (only its Drop takes it), and `owner` is the array's base object.
    let array = match r.data.as_mut() {
        Some(Data::Host(a)) => unsafe { PyArray2::borrow_from_array(&*a, container) },
        Some(Data::Pinned(p)) => {
            let ptr =
                p.0.as_mut_ptr()
                    .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(format!("CUDA: {e}")))?;
            // SAFETY: `ptr` holds 3 n floats (the buffer's length), written by the finished copy.
            let view = unsafe { ArrayView2::from_shape_ptr((n, 3), ptr as *const f32) };
            unsafe { PyArray2::borrow_from_array(&view, container) }
        }
        None => return Err(pyo3::exceptions::PyRuntimeError::new_err("empty buffer")),
    };
    drop(r);
    Ok(array)
}
