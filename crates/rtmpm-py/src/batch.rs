//! `rtmpm.BatchSimulation`: many worlds of one scene stepped together (rtmpm-driver's
//! [`BatchRun`]), read and steered world by world from Python: particle arrays of every world
//! at once, resets of chosen worlds, kinematic rigid bodies (tools, pushers) posed per world,
//! the load the material puts on them, and each world's status (a world that blows up is
//! frozen, the others go on). `rtmpm.Simulation(scene, batch=N)` (or a scene with `[batch]`)
//! returns one (python/rtmpm/__init__.py). Documentation: docs/batch.md, docs/python.md.

use crate::backend::{BackendInfo, request};
use crate::bodies::{BodyUpdate, body_index, set_body};
use crate::errors::{BackendError, SceneError, SimulationError, internal_error, scene_error};
use crate::scene::{PyScene, scene_arg};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyIndexError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rtmpm_backends::{BackendKind, BackendRequest};
use rtmpm_driver::batch::{BatchOptions, BatchRun, WorldStatus};
use rtmpm_physics::Particles;
use rtmpm_physics::math::Vec3;
use rtmpm_scene::batch::{MAX_WORLDS, memory_refusal, scaled_budget};
use rtmpm_scene::{BatchScene, Budget, Precision, Scene};
use rtmpm_sim::Backend;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Mutex;

/// The batch run, movable to the thread that steps it with the interpreter lock released.
struct Worlds(BatchRun);

// SAFETY: `BatchRun` holds each world's backend as a `Box<dyn Backend>`, which is not `Send`
// by its type. Every backend this module puts in one is an `rtmpm_backends::AnyBackend`
// (`make_backend`, the only constructor used by `BatchSimulation::new` and `reset`), which is
// `Send` (rtmpm-backends states why for its CUDA variant). The rest of the run (scenes, frame
// outputs, which this module never opens) is plain data. The run is used by one thread at a
// time (`&mut self`).
unsafe impl Send for Worlds {}

impl Worlds {
    fn get(&mut self) -> &mut BatchRun {
        &mut self.0
    }
}

/// Many worlds of one scene, stepped together.
///
/// ``rtmpm.Simulation(scene, batch=N)`` makes ``N`` copies of ``scene``; a scene with
/// ``[batch]`` (docs/batch.md) makes its worlds, each with its swept values (``batch`` may then
/// be left out, or must equal its ``count``). Each world is a simulation of its own (own
/// particles, grid, colliders and rigid bodies: no world can touch another's state) on the CPU
/// backend, the same results bit for bit as a separate :class:`Simulation` of its scene.
///
/// Arrays: :attr:`x`, :attr:`v`, :attr:`mass`, :attr:`material` are shaped ``(N, n, ...)``
/// when every world has ``n`` particles (:attr:`uniform`), else flat (all worlds' particles one
/// after another) with world ``w``'s at ``offsets[w]:offsets[w + 1]``. A world that blows up is
/// frozen at its last good state (:attr:`status` says why); the others go on; :meth:`reset`
/// starts chosen worlds again.
#[pyclass(name = "BatchSimulation", module = "rtmpm")]
pub struct PyBatch {
    run: Mutex<Worlds>,
    scene: Py<PyScene>,
    request: BackendRequest,
    reason: String,
    /// Each world's particles at time 0 (what a reset starts from).
    initial: Vec<Particles>,
    /// Set after a panic: the state may be inconsistent.
    broken: Option<String>,
}

/// The worlds asked for: the scene's `[batch]` or `n` copies of the scene, in `precision`.
fn worlds_of(scene: &PyScene, n: Option<i64>, precision: Option<&str>) -> PyResult<BatchScene> {
    let n = match n {
        None => None,
        Some(n) if n < 1 || n > MAX_WORLDS as i64 => {
            return Err(PyValueError::new_err(format!(
                "batch = {n}: a batch has from 1 to {MAX_WORLDS} worlds"
            )));
        }
        Some(n) => Some(n as usize),
    };
    let mut b = match (&scene.batch, n) {
        (Some(b), Some(n)) if n != b.count() => {
            return Err(PyValueError::new_err(format!(
                "batch = {n}, but the scene's [batch] has count = {} worlds: leave batch out, \
                 or change [batch] count",
                b.count()
            )));
        }
        (Some(b), _) => b.clone(),
        (None, n) => {
            let n = n.unwrap_or(1);
            refuse_memory(&scaled_budget(&Budget::estimate(&scene.scene, None), n), n)?;
            BatchScene {
                base: scene.scene.clone(),
                batch: None,
                worlds: vec![scene.scene.clone(); n],
            }
        }
    };
    if let Some(p) = precision {
        let p = p.parse::<Precision>().map_err(PyValueError::new_err)?;
        for w in &mut b.worlds {
            w.precision = p;
        }
    }
    refuse_memory(&b.budget(None), b.count())?;
    Ok(b)
}

/// A batch whose memory does not fit this machine, refused with the numbers before any world's
/// particles are made.
fn refuse_memory(budget: &Budget, count: usize) -> PyResult<()> {
    match memory_refusal(budget, count, rtmpm_io::limits::host_memory_available()) {
        Some(r) => Err(PyValueError::new_err(format!(
            "the batch does not fit this machine: {r}"
        ))),
        None => Ok(()),
    }
}

/// The backend a batch runs on: the CPU (the worlds of a batch in the same CUDA kernels are
/// not built yet), with the reason.
fn batch_request(
    py: Python<'_>,
    backend: &str,
    threads: Option<usize>,
    gpus: Option<&Bound<'_, PyAny>>,
    cuda_options: Option<&str>,
) -> PyResult<(BackendRequest, String)> {
    if threads.is_some() {
        return Err(PyValueError::new_err(
            "threads: the worlds of a batch share the process's worker threads (one per core); \
             leave threads out",
        ));
    }
    let one = 1usize.into_pyobject(py)?.into_any();
    let mut req = request(backend, None, gpus.unwrap_or(&one), cuda_options)?;
    if req.gpus > 1 || req.kind == BackendKind::Cuda {
        return Err(BackendError::new_err(
            "a batch runs on the CPU backend (its worlds in the same CUDA kernels are not built \
             yet): use backend=\"cpu\" or \"auto\", one GPU",
        ));
    }
    let reason = format!("{} -> cpu (batches run on the CPU backend)", backend);
    req.kind = BackendKind::Cpu;
    Ok((req, reason))
}

/// A world's backend from its particles.
fn make_backend(
    req: &BackendRequest,
    scene: &Scene,
    particles: Particles,
) -> anyhow::Result<Box<dyn Backend>> {
    let created = rtmpm_backends::create(req, scene, particles).map_err(anyhow::Error::msg)?;
    Ok(Box::new(created.backend))
}

/// A Python error from a batch run's error (`anyhow`, with its context).
fn run_error(e: anyhow::Error) -> PyErr {
    SimulationError::new_err(format!("{e:#}"))
}

impl PyBatch {
    /// Run `work` on the worlds with the interpreter lock released, panics caught (the batch is
    /// then marked broken); returns the worlds frozen.
    fn drive(
        &mut self,
        py: Python<'_>,
        work: impl FnOnce(&mut BatchRun) -> anyhow::Result<Vec<usize>> + Send,
    ) -> PyResult<Vec<usize>> {
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

    /// The run (no locking: `&mut self` is exclusive already).
    fn r(&mut self) -> &mut BatchRun {
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
        self.r().worlds.len()
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

    /// Particle counts of the worlds.
    fn counts(&mut self) -> Vec<usize> {
        self.r()
            .worlds
            .iter()
            .map(|w| w.particles().len())
            .collect()
    }

    /// Every world's `field` one after another, shaped `(N, n, *shape)` when all worlds have
    /// `n` particles, else `(total, *shape)`.
    fn gather<'py, T: numpy::Element + Copy>(
        &mut self,
        py: Python<'py>,
        shape: &[usize],
        field: impl Fn(&Particles) -> Vec<T>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let counts = self.counts();
        let mut flat = Vec::new();
        for w in &self.r().worlds {
            flat.extend(field(w.particles()));
        }
        let a = PyArray1::from_vec(py, flat);
        let mut dims: Vec<usize> = match counts.first() {
            Some(&n) if counts.iter().all(|&c| c == n) => vec![counts.len(), n],
            _ => vec![counts.iter().sum()],
        };
        dims.extend_from_slice(shape);
        Ok(a.reshape(dims)?.into_any())
    }

    /// World `w`'s particles at time 0, with `x` / `v` (rows of `n` x 3) replacing theirs.
    fn start_state(
        &mut self,
        w: usize,
        x: Option<&[f32]>,
        v: Option<&[f32]>,
    ) -> PyResult<Particles> {
        let mut p = self.initial[w].clone();
        for (name, given, target) in [("x", x, &mut p.x), ("v", v, &mut p.v)] {
            let Some(rows) = given else { continue };
            for (i, r) in rows.chunks_exact(3).enumerate() {
                let r = Vec3::new(r[0], r[1], r[2]);
                if !r.is_finite() {
                    return Err(PyValueError::new_err(format!(
                        "{name} of world {w}, particle {i}: {r} is not finite"
                    )));
                }
                target[i] = r;
            }
        }
        Ok(p)
    }
}

/// `value` (an array, a list, any sequence NumPy reads) as float32 numbers.
fn f32_array<'py>(name: &str, value: &Bound<'py, PyAny>) -> PyResult<PyReadonlyArrayDyn<'py, f32>> {
    let np = value.py().import("numpy")?;
    let a = np
        .call_method1("asarray", (value, "float32"))
        .map_err(|e| PyValueError::new_err(format!("{name}: not an array of numbers ({e})")))?;
    Ok(a.cast_into::<numpy::PyArrayDyn<f32>>()?.readonly())
}

/// `value` (an array of `k x n x 3` or, for one world, `n x 3` numbers) split into the rows of
/// the `k` worlds `worlds` with `counts[w]` particles each.
fn split_rows(
    name: &str,
    value: Option<Bound<'_, PyAny>>,
    worlds: &[usize],
    counts: &[usize],
) -> PyResult<Option<Vec<Vec<f32>>>> {
    let Some(a) = value else { return Ok(None) };
    let a = f32_array(name, &a)?;
    let shape = a.shape().to_vec();
    let data: Vec<f32> = a.as_array().iter().copied().collect();
    let wanted: Vec<usize> = worlds.iter().map(|&w| counts[w]).collect();
    let fits = match shape.as_slice() {
        [k, n, 3] => *k == worlds.len() && wanted.iter().all(|c| c == n),
        [total, 3] => *total == wanted.iter().sum::<usize>(),
        _ => false,
    };
    if !fits {
        return Err(PyValueError::new_err(format!(
            "{name} has shape {shape:?}: the {} worlds reset hold {wanted:?} particles, so give \
             ({}, n, 3) when they all hold n, or their rows one world after another, ({}, 3)",
            worlds.len(),
            worlds.len(),
            wanted.iter().sum::<usize>()
        )));
    }
    let mut rows = Vec::with_capacity(worlds.len());
    let mut at = 0;
    for n in wanted {
        rows.push(data[at..at + 3 * n].to_vec());
        at += 3 * n;
    }
    Ok(Some(rows))
}

/// A per-world vector argument: one value for every world listed, or one row per world.
fn per_world<const K: usize>(
    name: &str,
    value: Option<Bound<'_, PyAny>>,
    k: usize,
) -> PyResult<Option<Vec<[f32; K]>>> {
    let Some(a) = value else { return Ok(None) };
    let a = f32_array(name, &a)?;
    let shape = a.shape().to_vec();
    let data: Vec<f32> = a.as_array().iter().copied().collect();
    let rows: Vec<[f32; K]> = data
        .chunks_exact(K)
        .map(|c| std::array::from_fn(|i| c[i]))
        .collect();
    match shape.as_slice() {
        [n] if *n == K => Ok(Some(vec![rows[0]; k])),
        [r, n] if *n == K && *r == k => Ok(Some(rows)),
        _ => Err(PyValueError::new_err(format!(
            "{name} has shape {shape:?}: give ({K},) for every world listed, or ({k}, {K}), one \
             row per world"
        ))),
    }
}

#[pymethods]
impl PyBatch {
    #[new]
    #[pyo3(signature = (scene, batch = None, backend = "auto", precision = None, threads = None, gpus = None, cuda_options = None))]
    #[allow(clippy::too_many_arguments)] // Python's keyword arguments
    fn new(
        py: Python<'_>,
        scene: &Bound<'_, PyAny>,
        batch: Option<i64>,
        backend: &str,
        precision: Option<&str>,
        threads: Option<usize>,
        gpus: Option<&Bound<'_, PyAny>>,
        cuda_options: Option<&str>,
    ) -> PyResult<PyBatch> {
        let (req, reason) = batch_request(py, backend, threads, gpus, cuda_options)?;
        let scene = scene_arg(py, scene)?;
        let s = scene.get();
        crate::scene::warn(py, &s.scene)?;
        let worlds = worlds_of(s, batch, precision)?;
        let from_dict = s.origin == "<dict>";
        let mut initial = Vec::with_capacity(worlds.count());
        for (w, ws) in worlds.worlds.iter().enumerate() {
            let p = ws
                .sample_particles()
                .map_err(|e| scene_error(py, &e, from_dict))?;
            if p.is_empty() {
                return Err(SceneError::new_err(format!(
                    "{}: world {w}'s bodies hold no particles (add a [[body]] or make it larger)",
                    s.origin
                )));
            }
            initial.push(p);
        }
        let options = BatchOptions::default();
        let built = py.detach(|| {
            catch_unwind(AssertUnwindSafe(|| {
                BatchRun::new(
                    &worlds,
                    &s.text,
                    |scene, w| make_backend(&req, scene, initial[w].clone()),
                    &options,
                )
                .and_then(|mut run| run.write_first_frame().map(|_| Worlds(run)))
            }))
        });
        let run = built
            .map_err(|p| internal_error(p.as_ref()))?
            .map_err(|e| BackendError::new_err(format!("{e:#}")))?;
        Ok(PyBatch {
            run: Mutex::new(run),
            scene,
            request: req,
            reason,
            initial,
            broken: None,
        })
    }

    /// Number of worlds.
    fn __len__(&mut self) -> usize {
        self.count()
    }

    /// Number of worlds.
    #[getter]
    fn worlds(&mut self) -> usize {
        self.count()
    }

    /// What sets each world apart (``"material[0].yield_stress = 150"``, or ``"world 3"``).
    #[getter]
    fn labels(&mut self) -> Vec<String> {
        self.r().worlds.iter().map(|w| w.label.clone()).collect()
    }

    /// The scene (:class:`rtmpm.Scene`) the worlds come from.
    #[getter]
    fn scene(&mut self, py: Python<'_>) -> Py<PyScene> {
        self.scene.clone_ref(py)
    }

    /// The backend of the worlds and why (:class:`rtmpm.BackendInfo`).
    #[getter]
    fn backend(&mut self) -> BackendInfo {
        let name = self
            .r()
            .worlds
            .first()
            .map(|w| w.sim.backend.name())
            .unwrap_or_default();
        BackendInfo {
            kind: "cpu".into(),
            name,
            reason: self.reason.clone(),
        }
    }

    /// Take ``n`` steps in every running world, each of its own time step (frames end on their
    /// times as with ``rtmpm run``). Returns the worlds frozen by a blow-up during the call.
    #[pyo3(signature = (n = 1))]
    fn step(&mut self, py: Python<'_>, n: u64) -> PyResult<Vec<usize>> {
        self.drive(py, |run| run.advance_steps(n))
    }

    /// Simulate every running world to the end of its current frame (exactly as one call of
    /// :meth:`Simulation.run_frame` per world). Returns the worlds frozen during the call.
    fn run_frame(&mut self, py: Python<'_>) -> PyResult<Vec<usize>> {
        self.drive(py, |run| run.advance_frame())
    }

    /// Run ``frames`` frames in every running world (default: to the end of the scene's
    /// duration), checking for Ctrl-C between frames. Returns the worlds frozen during the run.
    #[pyo3(signature = (frames = None))]
    fn run(&mut self, py: Python<'_>, frames: Option<u64>) -> PyResult<Vec<usize>> {
        let count = frames.unwrap_or_else(|| {
            let max = self.r().worlds.iter().map(|w| w.sim.frame).max();
            self.r().frames.saturating_sub(max.unwrap_or(0))
        });
        let mut frozen = Vec::new();
        for _ in 0..count {
            frozen.extend(self.drive(py, |run| run.advance_frame())?);
            py.check_signals()?;
        }
        Ok(frozen)
    }

    /// Put worlds ``worlds`` (default: all) back to time 0: to their initial state, or with
    /// positions ``x`` and/or velocities ``v`` given (``(k, n, 3)`` when the ``k`` worlds hold
    /// ``n`` particles each, or their rows one world after another; the other fields, and
    /// what is not given, as at time 0). The other worlds are not touched. A frozen world runs
    /// again.
    #[pyo3(signature = (worlds = None, *, x = None, v = None))]
    fn reset(
        &mut self,
        py: Python<'_>,
        worlds: Option<Vec<i64>>,
        x: Option<Bound<'_, PyAny>>,
        v: Option<Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        self.usable()?;
        let list = self.world_list(worlds)?;
        let counts: Vec<usize> = self.initial.iter().map(Particles::len).collect();
        let xs = split_rows("x", x, &list, &counts)?;
        let vs = split_rows("v", v, &list, &counts)?;
        let mut starts = Vec::with_capacity(list.len());
        for (k, &w) in list.iter().enumerate() {
            let x = xs.as_ref().map(|r| r[k].as_slice());
            let v = vs.as_ref().map(|r| r[k].as_slice());
            starts.push(self.start_state(w, x, v)?);
        }
        let req = self.request.clone();
        self.drive(py, move |run| {
            for (w, p) in list.into_iter().zip(starts) {
                run.reset_world(w, |scene| make_backend(&req, scene, p))?;
            }
            Ok(Vec::new())
        })?;
        Ok(())
    }

    /// Each world's state: a dict with ``world``, ``state`` (``"running"`` or ``"frozen"``),
    /// ``frame`` (frames completed; for a frozen world the one it keeps), ``steps`` and
    /// ``reason`` (why it froze, ``None`` while running).
    #[getter]
    fn status<'py>(&mut self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.r()
            .worlds
            .iter()
            .enumerate()
            .map(|(i, w)| {
                let d = PyDict::new(py);
                d.set_item("world", i)?;
                match &w.status {
                    WorldStatus::Running => {
                        d.set_item("state", "running")?;
                        d.set_item("frame", w.sim.frame)?;
                        d.set_item("reason", py.None())?;
                    }
                    WorldStatus::Frozen { frame, reason } => {
                        d.set_item("state", "frozen")?;
                        d.set_item("frame", *frame)?;
                        d.set_item("reason", reason)?;
                    }
                }
                d.set_item("steps", w.sim.step)?;
                Ok(d)
            })
            .collect()
    }

    /// ``(N,)`` bool array: True where a world is running, False where it is frozen.
    #[getter]
    fn running<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        let r = self.r().worlds.iter();
        PyArray1::from_vec(py, r.map(|w| w.status == WorldStatus::Running).collect())
    }

    /// ``(N,)`` float64 array: each world's simulated time (s).
    #[getter]
    fn time<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.r().worlds.iter().map(|w| w.sim.time).collect())
    }

    /// ``(N,)`` uint64 array: frames each world has completed.
    #[getter]
    fn frame<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        PyArray1::from_vec(py, self.r().worlds.iter().map(|w| w.sim.frame).collect())
    }

    /// ``(N,)`` uint64 array: steps each world has taken.
    #[getter]
    fn steps<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        PyArray1::from_vec(py, self.r().worlds.iter().map(|w| w.sim.step).collect())
    }

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

    /// Pose rigid body ``body`` (its index in ``[[rigid_body]]`` or its name) in worlds
    /// ``worlds`` (default: all) from the next step on, as :meth:`Simulation.set_rigid_body`
    /// does in one: ``position`` (m), ``rotation`` (quaternion ``(x, y, z, w)``), ``velocity``
    /// (m/s), ``angular_velocity`` (rad/s), each one value for every world listed (shape
    /// ``(3,)``, ``(4,)``) or one row per world (``(k, 3)``, ``(k, 4)``). A kinematic body (a
    /// tool, a pusher) moves at the velocity given. Bad values raise ``ValueError`` naming the
    /// world; the worlds before it are already set.
    #[pyo3(signature = (body, *, worlds = None, position = None, rotation = None, velocity = None, angular_velocity = None))]
    #[allow(clippy::too_many_arguments)] // Python's keyword arguments
    fn set_rigid_body(
        &mut self,
        py: Python<'_>,
        body: &Bound<'_, PyAny>,
        worlds: Option<Vec<i64>>,
        position: Option<Bound<'_, PyAny>>,
        rotation: Option<Bound<'_, PyAny>>,
        velocity: Option<Bound<'_, PyAny>>,
        angular_velocity: Option<Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        self.usable()?;
        let list = self.world_list(worlds)?;
        let k = list.len();
        let position = per_world::<3>("position", position, k)?;
        let rotation = per_world::<4>("rotation", rotation, k)?;
        let velocity = per_world::<3>("velocity", velocity, k)?;
        let angular = per_world::<3>("angular_velocity", angular_velocity, k)?;
        for (j, &w) in list.iter().enumerate() {
            let sim = &mut self.r().worlds[w].sim;
            let i = body_index(body, &sim.scene.rigid_bodies)?;
            let update = BodyUpdate {
                position: position.as_ref().map(|p| p[j]),
                rotation: rotation.as_ref().map(|p| p[j]),
                velocity: velocity.as_ref().map(|p| p[j]),
                angular_velocity: angular.as_ref().map(|p| p[j]),
            };
            set_body(py, sim, i, &update).map_err(|e| {
                let msg = format!("world {w}: {}", e.value(py));
                PyErr::from_type(e.get_type(py), msg)
            })?;
        }
        Ok(())
    }

    /// World ``world``'s rigid bodies as :attr:`Simulation.rigid_bodies` gives them (dicts of
    /// ``position``, ``rotation``, ``velocity``, ``angular_velocity``).
    fn rigid_bodies<'py>(
        &mut self,
        py: Python<'py>,
        world: i64,
    ) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let w = self.world_list(Some(vec![world]))?[0];
        let backend = &mut self.r().worlds[w].sim.backend;
        backend
            .flush_rigid()
            .map_err(|e| crate::errors::sim_error(py, &e))?;
        crate::bodies::states(py, &backend.rigid_poses(), backend.rigid_loads())
    }

    /// ``(N, 3)`` float64 array: the force (N) the material put on rigid body ``body`` (index or
    /// name) in each world over its last step, for every kind of body (a kinematic tool's too):
    /// the momentum the grid's nodes lost to the body's boundary condition divided by dt, less
    /// the gravity on those nodes (rtmpm-rigid's exchange). Zero before a world's first step;
    /// NaN for a frozen world.
    fn rigid_force<'py>(
        &mut self,
        py: Python<'py>,
        body: &Bound<'_, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        self.loads(py, body, |l| l.force)
    }

    /// ``(N, 3)`` float64 array: the torque (N m) about rigid body ``body``'s centre of mass,
    /// as :meth:`rigid_force`.
    fn rigid_torque<'py>(
        &mut self,
        py: Python<'py>,
        body: &Bound<'_, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        self.loads(py, body, |l| l.torque)
    }

    /// Not supported: a batch writes no checkpoints yet (nor does ``rtmpm run`` of a batch,
    /// which refuses ``--checkpoint-every`` and ``--resume``). Raises :class:`rtmpm.RtmpmError`
    /// saying so; :meth:`reset` with given ``x`` and ``v`` restarts chosen worlds from a state
    /// kept in Python.
    #[pyo3(signature = (*_args, **_kwargs))]
    fn checkpoint(
        &self,
        _args: &Bound<'_, pyo3::types::PyTuple>,
        _kwargs: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<()> {
        Err(crate::errors::RtmpmError::new_err(
            "checkpoints of a batch are not supported: keep the worlds' arrays (x, v) and \
             restart worlds from them with reset(worlds, x=..., v=...), or checkpoint a world \
             run as its own rtmpm.Simulation",
        ))
    }

    fn __repr__(&mut self) -> String {
        let frozen = self.count() - self.r().running();
        let (worlds, particles) = (self.count(), self.counts().iter().sum::<usize>());
        format!(
            "BatchSimulation(scene={:?}, worlds={worlds}, frozen={frozen}, particles={particles})",
            self.scene.get().scene.name,
        )
    }
}

impl PyBatch {
    /// One load component of `body` in every world, `(N, 3)`.
    fn loads<'py>(
        &mut self,
        py: Python<'py>,
        body: &Bound<'_, PyAny>,
        part: impl Fn(&rtmpm_rigid::BodyLoad) -> [f64; 3],
    ) -> PyResult<Bound<'py, PyAny>> {
        let mut flat = Vec::with_capacity(3 * self.count());
        for world in &self.r().worlds {
            let i = body_index(body, &world.sim.scene.rigid_bodies)?;
            if world.status != WorldStatus::Running {
                flat.extend([f64::NAN; 3]);
                continue;
            }
            let loads = world.sim.backend.rigid_loads().ok_or_else(|| {
                BackendError::new_err(format!(
                    "the backend `{}` does not report the loads on rigid bodies",
                    world.sim.backend.name()
                ))
            })?;
            let l = loads.get(i).ok_or_else(|| {
                PyIndexError::new_err(format!("rigid body {i}: the backend holds no state for it"))
            })?;
            flat.extend(part(l));
        }
        Ok(PyArray1::from_vec(py, flat)
            .reshape([self.count(), 3])?
            .into_any())
    }
}
