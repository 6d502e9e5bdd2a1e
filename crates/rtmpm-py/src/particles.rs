//! `rtmpm.Particles`: the particle state of a simulation as NumPy arrays (copies, in original
//! order) with setters for positions, velocities, C and F, and, on the CUDA backend, zero-copy
//! device arrays (see [`crate::device`]).

use crate::device::{DeviceArray, Elem};
use crate::errors::{backend_error, sim_error};
use crate::state::{Inner, PySimulation};
use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use rtmpm_backends::AnyBackend;
use rtmpm_cuda::contract::StateLayout;
use rtmpm_physics::math::{Mat3, Vec3};
use rtmpm_sim::{Backend, ParticleEdit, SimError};

/// The particles of a :class:`rtmpm.Simulation`.
///
/// **Order**: index ``i`` is particle ``i`` of the scene's sampling (the bodies in file order,
/// each in its sampling order), the same on every backend and in output frames;
/// :attr:`id` is ``arange(n)``.
///
/// **Host arrays** (NumPy, fresh copies each access; assigning to an array's elements does not
/// change the simulation, assigning to :attr:`x`, :attr:`v`, :attr:`C` or :attr:`F` does):
///
/// ========== ============== ========== ==============================================
/// name       shape          dtype      meaning
/// ========== ============== ========== ==============================================
/// x          (n, 3)         float32    position (m)
/// v          (n, 3)         float32    velocity (m/s)
/// F          (n, 3, 3)      float32    deformation gradient, ``F[i, row, col]``
/// C          (n, 3, 3)      float32    APIC affine matrix (about grad v), 1/s
/// J          (n,)           float32    volume ratio ``det F``
/// material   (n,)           int32      index into ``scene.materials``
/// id         (n,)           int32      original particle index
/// mass       (n,)           float32    kg
/// vol0       (n,)           float32    initial volume (m^3)
/// plastic    (n,)           float32    the material's plastic scalar (snow Jp, ...)
/// ========== ============== ========== ==============================================
///
/// Host arrays are float32 whatever the precision (an f64 simulation rounds them; setters widen
/// exactly).
///
/// **Device arrays** (CUDA backend, one GPU): ``x_device``, ``v_device``, ``F_device``,
/// ``C_device``, ``material_device``, ``id_device``, ``mass_device``, ``vol0_device``,
/// ``plastic_device`` are :class:`rtmpm.DeviceArray` views of the simulation's own GPU memory
/// (no copy), for ``torch.from_dlpack`` and CuPy (``__cuda_array_interface__``). They are in the
/// GPU's **storage order**, which changes at every step (particles are sorted by grid block):
/// row ``j`` holds particle ``id_device[j]``. Their dtype is float32 (float64 in f64), ids and
/// materials int32; they are strided (one array per component, see :class:`DeviceArray`).
/// Treat them as read-only and read them between steps: use the setters to change the state.
#[pyclass(name = "Particles", module = "rtmpm")]
pub struct PyParticles {
    pub sim: Py<PySimulation>,
}

/// Which host array.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Vec3Field {
    X,
    V,
}

/// Positions or velocities straight from the GPU, in original order: the GPU gathers them into
/// NumPy's layout and copies them into page-locked memory that becomes the array's
/// (`CudaBackend::read_vec3_ordered_pinned`); past the page-locked limit of `pool.rs`, the array
/// crosses in chunks into pageable memory (`CudaBackend::read_vec3_ordered_into`). Both kinds of
/// memory are pooled (`pool.rs`).
fn read_vec3_cuda(
    inner: &mut Inner,
    field: Vec3Field,
) -> Result<Option<crate::pool::Buf>, SimError> {
    use crate::pool::{Buf, Pinned};
    let AnyBackend::Cuda(c) = inner.sim.backend.as_mut() else {
        return Ok(None);
    };
    let l = c.0.state_layout();
    let first = if field == Vec3Field::X { l.x() } else { l.v() };
    let len = 3 * c.0.len();
    let pinned = match crate::pool::take_pinned(len) {
        Some(p) => Some(p),
        None => Pinned::new(len, || c.0.host_buffer(len))?,
    };
    if let Some(mut p) = pinned {
        c.0.read_vec3_ordered_pinned(first, p.slice())?;
        return Ok(Some(Buf::Pinned(p)));
    }
    let mut buf = crate::pool::take(len);
    c.0.read_vec3_ordered_into(first, &mut buf)?;
    Ok(Some(Buf::Host(buf)))
}

fn vec3s_to_array<'py>(py: Python<'py>, v: &[Vec3]) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let flat: Vec<f32> = v.iter().flat_map(|a| a.to_array()).collect();
    PyArray1::from_vec(py, flat).reshape([v.len(), 3])
}

fn mat3s_to_array<'py>(py: Python<'py>, m: &[Mat3]) -> PyResult<Bound<'py, PyArray3<f32>>> {
    // glam stores columns; NumPy rows: F[i, r, c] = column c, row r.
    let flat: Vec<f32> = m
        .iter()
        .flat_map(|a| a.transpose().to_cols_array())
        .collect();
    PyArray1::from_vec(py, flat).reshape([m.len(), 3, 3])
}

impl PyParticles {
    fn vec3<'py>(&self, py: Python<'py>, field: Vec3Field) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let mut s = self.sim.bind(py).borrow_mut();
        let inner = s.get();
        inner.usable()?;
        let cached = inner
            .host
            .as_ref()
            .is_some_and(|(v, _)| *v == inner.version);
        if !cached {
            let r = py.detach(|| {
                std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    read_vec3_cuda(inner, field)
                }))
            });
            if let Some(flat) = inner.settle(py, r)? {
                return crate::pool::vec3_array(py, flat);
            }
        }
        let p = inner.host(py)?;
        vec3s_to_array(py, if field == Vec3Field::X { &p.x } else { &p.v })
    }

    fn set_vec3(&self, py: Python<'_>, value: &Bound<'_, PyAny>, field: Vec3Field) -> PyResult<()> {
        let what = if field == Vec3Field::X {
            "positions (x)"
        } else {
            "velocities (v)"
        };
        let mut s = self.sim.bind(py).borrow_mut();
        let inner = s.get();
        inner.usable()?;
        let n = inner.sim.backend.num_particles();
        let flat = float_rows(py, value, what, &[n, 3])?;
        let vals: Vec<Vec3> = flat.chunks_exact(3).map(Vec3::from_slice).collect();
        if let Some(i) = vals.iter().position(|v| !v.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "{what}: particle {i} is not finite: {:?}",
                vals[i].to_array()
            )));
        }
        if field == Vec3Field::X {
            let (lo, hi) = (inner.sim.scene.domain_min, inner.sim.scene.domain_max);
            if let Some(i) = vals
                .iter()
                .position(|x| x.cmplt(lo).any() || x.cmpgt(hi).any())
            {
                return Err(PyValueError::new_err(format!(
                    "{what}: particle {i} at {:?} is outside the domain [{:?}, {:?}]",
                    vals[i].to_array(),
                    lo.to_array(),
                    hi.to_array()
                )));
            }
        }
        let edit = match field {
            Vec3Field::X => ParticleEdit {
                x: Some(&vals),
                ..Default::default()
            },
            Vec3Field::V => ParticleEdit {
                v: Some(&vals),
                ..Default::default()
            },
        };
        apply_edit(py, inner, &edit)
    }

    /// Set every particle's C (`f` false) or F (`f` true) from an `(n, 3, 3)` float array
    /// (`[i, row, col]`), checked: finite, and for F a positive determinant; a fluid particle's
    /// F is kept as `J^(1/3) I` (only its volume ratio `J = det F` acts).
    fn set_mat3(&self, py: Python<'_>, value: &Bound<'_, PyAny>, f: bool) -> PyResult<()> {
        let what = if f {
            "deformation gradients (F)"
        } else {
            "affine matrices (C)"
        };
        let mut s = self.sim.bind(py).borrow_mut();
        let inner = s.get();
        inner.usable()?;
        let n = inner.sim.backend.num_particles();
        let flat = float_rows(py, value, what, &[n, 3, 3])?;
        // NumPy rows to glam's columns.
        let mut vals: Vec<Mat3> = flat
            .chunks_exact(9)
            .map(|m| Mat3::from_cols_array(&std::array::from_fn(|k| m[k])).transpose())
            .collect();
        if let Some(i) = vals.iter().position(|m| !m.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "{what}: particle {i} is not finite: {:?}",
                rows_of(vals[i])
            )));
        }
        if f {
            if let Some(i) = vals.iter().position(|m| {
                m.determinant().partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
            }) {
                return Err(PyValueError::new_err(format!(
                    "{what}: particle {i} has det F = {:e} (F = {:?}); a deformation gradient \
                     must have a positive determinant (0 or less is a particle flattened or \
                     turned inside out)",
                    vals[i].determinant(),
                    rows_of(vals[i])
                )));
            }
            let fluid = fluid_materials(&inner.sim.scene);
            let host = inner.host(py)?;
            for (m, &mat) in vals.iter_mut().zip(&host.material) {
                if fluid.get(mat as usize).copied().unwrap_or(false) {
                    *m = Mat3::from_diagonal(Vec3::splat(m.determinant().cbrt()));
                }
            }
        }
        let edit = if f {
            ParticleEdit {
                f: Some(&vals),
                ..Default::default()
            }
        } else {
            ParticleEdit {
                c: Some(&vals),
                ..Default::default()
            }
        };
        apply_edit(py, inner, &edit)
    }
}

/// True for each material of `scene` that is a fluid.
fn fluid_materials(scene: &rtmpm_scene::Scene) -> Vec<bool> {
    scene
        .materials
        .iter()
        .map(|m| matches!(m.model, rtmpm_physics::material::Model::Fluid(_)))
        .collect()
}

/// A 3x3 matrix as its rows, for messages.
fn rows_of(m: Mat3) -> [[f32; 3]; 3] {
    let t = m.transpose().to_cols_array_2d();
    [t[0], t[1], t[2]]
}

/// `value` as a float32 array of `shape`, flat in C order: an error naming `what` for another
/// dtype kind than float or another shape.
fn float_rows(
    py: Python<'_>,
    value: &Bound<'_, PyAny>,
    what: &str,
    shape: &[usize],
) -> PyResult<Vec<f32>> {
    let np = py.import("numpy")?;
    let arr = np.call_method1("asarray", (value,))?;
    let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
    if kind != "f" {
        let dtype = arr.getattr("dtype")?.str()?.to_string();
        return Err(PyTypeError::new_err(format!(
            "{what}: expected a float array (float32 or float64), got dtype {dtype}"
        )));
    }
    let got: Vec<usize> = arr.getattr("shape")?.extract()?;
    if got != shape {
        let want: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
        return Err(PyValueError::new_err(format!(
            "{what}: expected shape ({}), got {got:?}",
            want.join(", ")
        )));
    }
    let flat = np
        .call_method1("ascontiguousarray", (arr, "float32"))?
        .call_method1("reshape", (-1,))?;
    let flat = flat.cast::<PyArray1<f32>>()?.readonly();
    Ok(flat.as_slice()?.to_vec())
}

/// Give new columns of the particles to the backend (several GPUs: a new backend from the
/// host state with them).
fn apply_edit(py: Python<'_>, inner: &mut Inner, edit: &ParticleEdit) -> PyResult<()> {
    let r: Result<(), SimError> = match inner.sim.backend.as_mut() {
        AnyBackend::Cpu(b) => b.set_fields(edit),
        AnyBackend::CpuF64(b) => b.set_fields(edit),
        AnyBackend::Cuda(c) => c.0.write_fields(edit),
        AnyBackend::MultiGpu(_) => {
            let mut p = inner.host(py)?.clone();
            for (dst, src) in [(&mut p.x, edit.x), (&mut p.v, edit.v)] {
                if let Some(src) = src {
                    dst.copy_from_slice(src);
                }
            }
            for (dst, src) in [(&mut p.c, edit.c), (&mut p.f, edit.f)] {
                if let Some(src) = src {
                    dst.copy_from_slice(src);
                }
            }
            let created = rtmpm_backends::create(&inner.request, &inner.sim.scene, p)
                .map_err(backend_error)?;
            *inner.sim.backend = created.backend;
            Ok(())
        }
    };
    inner.version += 1;
    r.map_err(|e| sim_error(py, &e))
}

#[pymethods]
impl PyParticles {
    fn __len__(&self, py: Python<'_>) -> usize {
        self.sim
            .bind(py)
            .borrow_mut()
            .get()
            .sim
            .backend
            .num_particles()
    }

    /// Positions, ``(n, 3)`` float32 (m). Assign an ``(n, 3)`` float array to move the
    /// particles (inside the domain; the next step rebuilds the grid layout).
    #[getter]
    fn x<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        self.vec3(py, Vec3Field::X)
    }

    #[setter(x)]
    fn set_x(&self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.set_vec3(py, value, Vec3Field::X)
    }

    /// Velocities, ``(n, 3)`` float32 (m/s). Assign an ``(n, 3)`` float array to set them
    /// (e.g. an initial velocity field).
    #[getter]
    fn v<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        self.vec3(py, Vec3Field::V)
    }

    #[setter(v)]
    fn set_v(&self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.set_vec3(py, value, Vec3Field::V)
    }

    /// Deformation gradients, ``(n, 3, 3)`` float32, ``F[i, row, col]``. Assign an
    /// ``(n, 3, 3)`` float array to set them (finite, each with a positive determinant; a fluid
    /// particle keeps only ``J = det F``, as ``J^(1/3) I``).
    #[getter(F)]
    fn f<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let mut s = self.sim.bind(py).borrow_mut();
        mat3s_to_array(py, &s.get().host(py)?.f)
    }

    #[setter(F)]
    fn set_f(&self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.set_mat3(py, value, true)
    }

    /// APIC affine matrices, ``(n, 3, 3)`` float32, ``C[i, row, col]``. Assign an
    /// ``(n, 3, 3)`` float array (finite) to set them: with a new velocity field ``v(x)``, set
    /// ``C`` to its gradient ``dv_i/dx_j`` (e.g. ``[w]x``, the cross-product matrix of ``w``,
    /// for a spin ``w``), as the scene's ``angular_velocity`` does; a velocity field set
    /// without its ``C`` loses its rotation into ``C`` at the first step.
    #[getter(C)]
    fn c<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let mut s = self.sim.bind(py).borrow_mut();
        mat3s_to_array(py, &s.get().host(py)?.c)
    }

    #[setter(C)]
    fn set_c(&self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.set_mat3(py, value, false)
    }

    /// Volume ratios ``det F``, ``(n,)`` float32.
    #[getter(J)]
    fn j<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let mut s = self.sim.bind(py).borrow_mut();
        let p = s.get().host(py)?;
        Ok(PyArray1::from_vec(
            py,
            p.f.iter().map(|f| f.determinant()).collect(),
        ))
    }

    /// Material index of each particle, ``(n,)`` int32 (into ``scene.materials``).
    #[getter]
    fn material<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<i32>>> {
        let mut s = self.sim.bind(py).borrow_mut();
        let p = s.get().host(py)?;
        Ok(PyArray1::from_vec(
            py,
            p.material.iter().map(|&m| m as i32).collect(),
        ))
    }

    /// Original particle index, ``(n,)`` int32: ``arange(n)`` (host arrays are in original order).
    #[getter]
    fn id<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i32>> {
        let n = self.__len__(py);
        PyArray1::from_vec(py, (0..n as i32).collect())
    }

    /// Masses, ``(n,)`` float32 (kg).
    #[getter]
    fn mass<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let mut s = self.sim.bind(py).borrow_mut();
        Ok(PyArray1::from_slice(py, &s.get().host(py)?.mass))
    }

    /// Initial volumes, ``(n,)`` float32 (m^3).
    #[getter]
    fn vol0<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let mut s = self.sim.bind(py).borrow_mut();
        Ok(PyArray1::from_slice(py, &s.get().host(py)?.vol0))
    }

    /// The material's plastic scalar, ``(n,)`` float32 (snow ``Jp``, sand hardening, von Mises
    /// equivalent plastic strain; 0 otherwise).
    #[getter]
    fn plastic<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let mut s = self.sim.bind(py).borrow_mut();
        Ok(PyArray1::from_slice(py, &s.get().host(py)?.plastic))
    }

    /// Positions on the GPU, ``(n, 3)``, storage order (no copy; CUDA backend only).
    #[getter]
    fn x_device(&self, py: Python<'_>) -> PyResult<DeviceArray> {
        self.device(py, "x_device", |l| Some(l.x()), &[3], Elem::Real)
    }

    /// Velocities on the GPU, ``(n, 3)``, storage order.
    #[getter]
    fn v_device(&self, py: Python<'_>) -> PyResult<DeviceArray> {
        self.device(py, "v_device", |l| Some(l.v()), &[3], Elem::Real)
    }

    /// Deformation gradients on the GPU, ``(n, 3, 3)`` (``[i, row, col]``), storage order.
    #[getter(F_device)]
    fn f_device(&self, py: Python<'_>) -> PyResult<DeviceArray> {
        self.device(
            py,
            "F_device",
            |l| (!l.fluid()).then(|| l.f()),
            &[3, 3],
            Elem::Real,
        )
    }

    /// APIC matrices on the GPU, ``(n, 3, 3)`` (``[i, row, col]``), storage order.
    #[getter(C_device)]
    fn c_device(&self, py: Python<'_>) -> PyResult<DeviceArray> {
        self.device(
            py,
            "C_device",
            |l| (!l.compact()).then(|| l.c()),
            &[3, 3],
            Elem::Real,
        )
    }

    /// Material indices on the GPU, ``(n,)`` int32, storage order.
    #[getter]
    fn material_device(&self, py: Python<'_>) -> PyResult<DeviceArray> {
        self.device(
            py,
            "material_device",
            |l| Some(l.material()),
            &[],
            Elem::Int32,
        )
    }

    /// Original particle index of each GPU slot, ``(n,)`` int32: ``x[id_device[j]]`` is
    /// ``x_device[j]``.
    #[getter]
    fn id_device(&self, py: Python<'_>) -> PyResult<DeviceArray> {
        self.device(py, "id_device", |l| Some(l.id()), &[], Elem::Int32)
    }

    /// Masses on the GPU, ``(n,)``, storage order.
    #[getter]
    fn mass_device(&self, py: Python<'_>) -> PyResult<DeviceArray> {
        self.device(py, "mass_device", |l| Some(l.mass()), &[], Elem::Real)
    }

    /// Initial volumes on the GPU, ``(n,)``, storage order.
    #[getter]
    fn vol0_device(&self, py: Python<'_>) -> PyResult<DeviceArray> {
        self.device(py, "vol0_device", |l| Some(l.vol0()), &[], Elem::Real)
    }

    /// Plastic scalars on the GPU, ``(n,)``, storage order.
    #[getter]
    fn plastic_device(&self, py: Python<'_>) -> PyResult<DeviceArray> {
        self.device(py, "plastic_device", |l| l.plastic(), &[], Elem::Real)
    }
}

impl PyParticles {
    /// The view `name` of the word(s) `field` gives in the backend's state layout (`None`: the
    /// layout does not keep that field as plain words).
    fn device(
        &self,
        py: Python<'_>,
        name: &str,
        field: impl Fn(StateLayout) -> Option<usize>,
        inner_shape: &[usize],
        elem: Elem,
    ) -> PyResult<DeviceArray> {
        let mut s = self.sim.bind(py).borrow_mut();
        let inner = s.get();
        inner.usable()?;
        let AnyBackend::Cuda(c) = inner.sim.backend.as_mut() else {
            return Err(backend_error(format!(
                "device arrays need the CUDA backend on one GPU; this simulation runs on {}",
                inner.sim.backend.name()
            )));
        };
        let d = c.0.device_particles().map_err(|e| sim_error(py, &e))?;
        let Some(field) = field(d.layout) else {
            return Err(backend_error(format!(
                "`{name}` is not in the GPU's particle state layout `{}` (the fluid layout keeps \
                 F as the one word J^(1/3) and no plastic word; the compact one keeps C in \
                 shared-exponent words): read the host array (without `_device`), or run with \
                 cuda_options=\"fluid_state=off\" (fluids) and particle_state = \"f32\"",
                d.layout.name()
            )));
        };
        inner.exported = true;
        Ok(DeviceArray::new(
            self.sim.clone_ref(py).into_any(),
            &d,
            field,
            inner_shape,
            elem,
        ))
    }
}
