//! `rtmpm.DeviceArray`: a view of the CUDA backend's own particle memory, exported without a
//! copy through DLPack (`__dlpack__`, for `torch.from_dlpack`, `cupy.from_dlpack`, JAX, ...)
//! and `__cuda_array_interface__` (version 3, for CuPy, Numba, PyTorch's `as_tensor`).
//!
//! The view keeps the simulation alive (the DLPack capsule holds a reference to it until the
//! consumer's tensor is freed). The data are complete when the view is made (the backend's
//! stream is synchronised) and the next step first waits for every stream of the device
//! context, so readers on their own streams finish before the arrays change.

use pyo3::exceptions::PyBufferError;
use pyo3::ffi;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rtmpm_cuda::DeviceParticles;
use std::ffi::{CStr, c_void};

/// What one element of a view is.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Elem {
    /// The backend's real: float32, or float64 in f64.
    Real,
    /// The low 32 bits of a word, as int32 (material ids, original indices).
    Int32,
}

// DLPack ABI (dlpack.h, v0.8 "legacy" managed tensor, which every consumer accepts).
const KDL_CPU: i32 = 1;
const KDL_CUDA: i32 = 2;
const KDL_INT: u8 = 0;
const KDL_FLOAT: u8 = 2;

#[repr(C)]
struct DLDevice {
    device_type: i32,
    device_id: i32,
}

#[repr(C)]
struct DLDataType {
    code: u8,
    bits: u8,
    lanes: u16,
}

#[repr(C)]
struct DLTensor {
    data: *mut c_void,
    device: DLDevice,
    ndim: i32,
    dtype: DLDataType,
    shape: *mut i64,
    strides: *mut i64,
    byte_offset: u64,
}

#[repr(C)]
struct DLManagedTensor {
    dl_tensor: DLTensor,
    manager_ctx: *mut c_void,
    deleter: Option<unsafe extern "C" fn(*mut DLManagedTensor)>,
}

/// What a managed tensor owns: its shape and strides and a reference to the simulation.
struct Ctx {
    shape: Vec<i64>,
    strides: Vec<i64>,
    _owner: Py<PyAny>,
}

const CAPSULE_NAME: &CStr = c"dltensor";

/// Free a managed tensor (called by the consumer when its tensor dies, or by the capsule if
/// it was never consumed).
unsafe extern "C" fn deleter(m: *mut DLManagedTensor) {
    if m.is_null() {
        return;
    }
    // SAFETY: `m` and its manager_ctx were made by Box::into_raw in `__dlpack__`, and DLPack
    // calls the deleter once.
    let ctx = unsafe {
        let m = Box::from_raw(m);
        Box::from_raw(m.manager_ctx as *mut Ctx)
    };
    // Release the owner now (attaching to the interpreter if the consumer calls from a thread
    // that is not; pyo3 would otherwise defer the release to its next call).
    // Never unwind out of this C callback (an interpreter shutting down: leak the context).
    let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(move || {
        Python::attach(move |_| drop(ctx))
    }));
}

/// Capsule destructor: frees the tensor unless a consumer took it (renamed the capsule).
unsafe extern "C" fn capsule_destructor(capsule: *mut ffi::PyObject) {
    // SAFETY: called by Python with a valid capsule; the pointer is a DLManagedTensor.
    unsafe {
        if ffi::PyCapsule_IsValid(capsule, CAPSULE_NAME.as_ptr()) == 1 {
            let m =
                ffi::PyCapsule_GetPointer(capsule, CAPSULE_NAME.as_ptr()) as *mut DLManagedTensor;
            if !m.is_null()
                && let Some(d) = (*m).deleter
            {
                d(m);
            }
        } else {
            // A consumer took ownership; clear the error PyCapsule_IsValid may not set.
        }
    }
}

/// A strided view of GPU memory owned by a :class:`rtmpm.Simulation` or a
/// :class:`rtmpm.BatchSimulation` (no copy).
///
/// Use ``torch.from_dlpack(a)``, ``cupy.from_dlpack(a)`` or ``cupy.asarray(a)``. Attributes:
/// ``shape``, ``dtype`` (``"float32"``, ``"float64"`` or ``"int32"``), ``strides`` (in bytes,
/// like NumPy), ``ptr`` (device address of element 0), ``device`` (CUDA ordinal).
///
/// The arrays of a simulation's state are not contiguous: component ``k`` of every particle is
/// contiguous (structure of arrays), so ``x_device`` has strides ``(itemsize, capacity *
/// itemsize)``. A batch's ``x_device`` and ``v_device`` (gathered in original order) are
/// C-contiguous.
#[pyclass(name = "DeviceArray", module = "rtmpm", frozen)]
pub struct DeviceArray {
    owner: Py<PyAny>,
    base: u64,
    offset: u64,
    shape: Vec<i64>,
    /// Strides in elements.
    strides: Vec<i64>,
    code: u8,
    bits: u8,
    device: i32,
    /// DLPack device type: kDLCUDA, or kDLCPU for the layout test of `_layout_view`.
    device_type: i32,
}

impl DeviceArray {
    /// The view of word `field` (of the state's `StateLayout`) with per-particle shape
    /// `inner` (`[]`, `[3]` or `[3, 3]` with components `field + 3 * col + row`).
    pub fn new(
        owner: Py<PyAny>,
        d: &DeviceParticles,
        field: usize,
        inner: &[usize],
        elem: Elem,
    ) -> DeviceArray {
        let (code, bits, per_word) = match elem {
            Elem::Real => (KDL_FLOAT, (8 * d.word_bytes) as u8, 1),
            Elem::Int32 => (KDL_INT, 32, (d.word_bytes / 4) as i64),
        };
        let s = d.stride as i64 * per_word;
        let mut shape = vec![d.n as i64];
        let mut strides = vec![per_word];
        match inner {
            [] => {}
            [3] => {
                shape.push(3);
                strides.push(s);
            }
            _ => {
                shape.extend([3, 3]);
                strides.extend([s, 3 * s]);
            }
        }
        DeviceArray {
            owner,
            base: d.ptr,
            offset: (field * d.stride * d.word_bytes) as u64,
            shape,
            strides,
            code,
            bits,
            device: d.device as i32,
            device_type: KDL_CUDA,
        }
    }

    /// A C-contiguous float32 view of `shape` at device address `ptr` on CUDA device `device`
    /// (memory that `owner` keeps alive and never moves, e.g. a GPU batch's gathered
    /// positions, `batch/device.rs`).
    pub fn contiguous_f32(
        owner: Py<PyAny>,
        ptr: u64,
        device: usize,
        shape: &[usize],
    ) -> DeviceArray {
        let mut strides = vec![1i64; shape.len()];
        for k in (0..shape.len().saturating_sub(1)).rev() {
            strides[k] = strides[k + 1] * shape[k + 1] as i64;
        }
        DeviceArray {
            owner,
            base: ptr,
            offset: 0,
            shape: shape.iter().map(|&d| d as i64).collect(),
            strides,
            code: KDL_FLOAT,
            bits: 32,
            device: device as i32,
            device_type: KDL_CUDA,
        }
    }

    fn itemsize(&self) -> i64 {
        self.bits as i64 / 8
    }

    fn typestr(&self) -> String {
        let kind = if self.code == KDL_FLOAT { 'f' } else { 'i' };
        format!("<{kind}{}", self.itemsize())
    }
}

#[pymethods]
impl DeviceArray {
    /// DLPack export (legacy ``dltensor`` capsule). The data are ready on any stream, so
    /// ``stream`` needs no synchronisation; ``copy=True`` is refused (this is a view).
    #[pyo3(signature = (*, stream = None, max_version = None, dl_device = None, copy = None))]
    fn __dlpack__<'py>(
        &self,
        py: Python<'py>,
        stream: Option<Py<PyAny>>,
        max_version: Option<Py<PyAny>>,
        dl_device: Option<(i32, i32)>,
        copy: Option<bool>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let _ = (stream, max_version);
        if copy == Some(true) {
            return Err(PyBufferError::new_err(
                "rtmpm device arrays are views of the simulation's memory: copy=True is not offered",
            ));
        }
        if let Some(dev) = dl_device
            && dev != (self.device_type, self.device)
        {
            return Err(PyBufferError::new_err(format!(
                "this array lives on DLPack device {:?}: cannot export to {dev:?}",
                (self.device_type, self.device)
            )));
        }
        let mut ctx = Box::new(Ctx {
            shape: self.shape.clone(),
            strides: self.strides.clone(),
            _owner: self.owner.clone_ref(py),
        });
        let tensor = DLTensor {
            data: self.base as *mut c_void,
            device: DLDevice {
                device_type: self.device_type,
                device_id: self.device,
            },
            ndim: ctx.shape.len() as i32,
            dtype: DLDataType {
                code: self.code,
                bits: self.bits,
                lanes: 1,
            },
            shape: ctx.shape.as_mut_ptr(),
            strides: ctx.strides.as_mut_ptr(),
            byte_offset: self.offset,
        };
        let managed = Box::into_raw(Box::new(DLManagedTensor {
            dl_tensor: tensor,
            manager_ctx: Box::into_raw(ctx) as *mut c_void,
            deleter: Some(deleter),
        }));
        // SAFETY: a valid pointer and a static name; on failure the tensor is freed here.
        unsafe {
            let cap = ffi::PyCapsule_New(
                managed as *mut c_void,
                CAPSULE_NAME.as_ptr(),
                Some(capsule_destructor),
            );
            if cap.is_null() {
                deleter(managed);
            }
            Bound::from_owned_ptr_or_err(py, cap)
        }
    }

    /// ``(2, device)``: a CUDA device (DLPack's kDLCUDA).
    fn __dlpack_device__(&self) -> (i32, i32) {
        (self.device_type, self.device)
    }

    /// The CUDA Array Interface, version 3 (strides in bytes; no stream synchronisation needed).
    #[getter]
    fn __cuda_array_interface__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("shape", pyo3::types::PyTuple::new(py, &self.shape)?)?;
        d.set_item("typestr", self.typestr())?;
        d.set_item("data", (self.base + self.offset, false))?;
        d.set_item("version", 3)?;
        d.set_item(
            "strides",
            pyo3::types::PyTuple::new(py, self.strides_bytes())?,
        )?;
        d.set_item("stream", py.None())?;
        Ok(d)
    }

    /// Shape, e.g. ``(n, 3)``.
    #[getter]
    fn shape(&self) -> Vec<i64> {
        self.shape.clone()
    }

    /// ``"float32"``, ``"float64"`` or ``"int32"``.
    #[getter]
    fn dtype(&self) -> String {
        let kind = if self.code == KDL_FLOAT {
            "float"
        } else {
            "int"
        };
        format!("{kind}{}", self.bits)
    }

    /// Strides in bytes.
    #[getter]
    fn strides(&self) -> Vec<i64> {
        self.strides_bytes()
    }

    /// Device address of element 0.
    #[getter]
    fn ptr(&self) -> u64 {
        self.base + self.offset
    }

    /// CUDA device ordinal.
    #[getter]
    fn device(&self) -> i32 {
        self.device
    }

    fn __len__(&self) -> usize {
        self.shape[0] as usize
    }

    fn __repr__(&self) -> String {
        format!(
            "DeviceArray(shape={:?}, dtype={}, strides={:?}, device=cuda:{})",
            self.shape,
            self.dtype(),
            self.strides_bytes(),
            self.device
        )
    }
}

impl DeviceArray {
    fn strides_bytes(&self) -> Vec<i64> {
        self.strides.iter().map(|s| s * self.itemsize()).collect()
    }
}

/// A view with the GPU state's layout over a host NumPy buffer (DLPack device kCPU), so that
/// the shapes, strides, dtypes and capsule handling of device arrays are tested without a GPU
/// (tests/test_device_layout.py). `state` is a 1-D float32/float64 array of `29 * stride`
/// words: field `f` of slot `i` at `f * stride + i`.
#[pyfunction]
#[pyo3(signature = (state, n, stride, field, inner, int32 = false))]
pub fn _layout_view(
    state: &Bound<'_, PyAny>,
    n: usize,
    stride: usize,
    field: usize,
    inner: Vec<usize>,
    int32: bool,
) -> PyResult<DeviceArray> {
    let bad = || {
        pyo3::exceptions::PyValueError::new_err(
            "state: a contiguous 1-D NumPy array of 4- or 8-byte words, 29 fields of `stride`",
        )
    };
    let ndim: usize = state.getattr("ndim")?.extract()?;
    let word_bytes: usize = state.getattr("itemsize")?.extract()?;
    let len: usize = state.getattr("size")?.extract()?;
    let contiguous: bool = state
        .getattr("flags")?
        .get_item("C_CONTIGUOUS")?
        .extract()?;
    if ndim != 1 || !contiguous || !(word_bytes == 4 || word_bytes == 8) {
        return Err(bad());
    }
    let layout = rtmpm_cuda::contract::StateLayout::Full;
    if n > stride || len < layout.words() * stride {
        return Err(bad());
    }
    if field + inner.iter().product::<usize>() > layout.words() {
        return Err(pyo3::exceptions::PyValueError::new_err(
            "field out of range",
        ));
    }
    let ptr: u64 = state
        .getattr("__array_interface__")?
        .get_item("data")?
        .get_item(0)?
        .extract()?;
    let d = DeviceParticles {
        device: 0,
        ptr,
        n,
        stride,
        word_bytes,
        layout,
    };
    let elem = if int32 { Elem::Int32 } else { Elem::Real };
    let mut a = DeviceArray::new(state.clone().unbind(), &d, field, &inner, elem);
    a.device_type = KDL_CPU;
    Ok(a)
}
