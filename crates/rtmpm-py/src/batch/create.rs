//! Making a batch: the worlds asked for (the scene's `[batch]` or copies of the scene), the
//! memory check before any particle is made, the backend the worlds run on, and
//! `BatchSimulation(...)` itself.

use super::{PyBatch, Worlds};
use crate::backend::request;
use crate::errors::{BackendError, RtmpmError, SceneError, internal_error, scene_error};
use crate::scene::{PyScene, scene_arg};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rtmpm_backends::{BackendKind, BackendRequest};
use rtmpm_driver::batch::{BatchOptions, BatchRun};
use rtmpm_physics::Particles;
use rtmpm_scene::batch::{MAX_WORLDS, memory_refusal, scaled_budget};
use rtmpm_scene::{BatchScene, Budget, Precision, Scene};
use rtmpm_sim::Backend;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;
use std::sync::Mutex;

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
pub(super) fn make_backend(
    req: &BackendRequest,
    scene: &Scene,
    particles: Particles,
) -> anyhow::Result<Box<dyn Backend>> {
    let created = rtmpm_backends::create(req, scene, particles).map_err(anyhow::Error::msg)?;
    Ok(Box::new(created.backend))
}

/// What a batch is made from: the worlds, their backend and initial particles.
struct Start {
    request: BackendRequest,
    reason: String,
    scene: Py<PyScene>,
    worlds: BatchScene,
    initial: Vec<Particles>,
}

/// The constructor's backend arguments: `backend`, `threads`, `gpus`, `cuda_options`.
type BackendArgs<'a, 'py> = (
    &'a str,
    Option<usize>,
    Option<&'a Bound<'py, PyAny>>,
    Option<&'a str>,
);

impl Start {
    /// The worlds of `scene` (`batch` copies or its `[batch]`), checked, and every world's
    /// particles at time 0 (what a reset starts from).
    fn new(
        py: Python<'_>,
        scene: &Bound<'_, PyAny>,
        batch: Option<i64>,
        precision: Option<&str>,
        (backend, threads, gpus, cuda_options): BackendArgs<'_, '_>,
    ) -> PyResult<Start> {
        let (request, reason) = batch_request(py, backend, threads, gpus, cuda_options)?;
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
        Ok(Start {
            request,
            reason,
            scene,
            worlds,
            initial,
        })
    }

    /// The batch `build` makes (with the interpreter lock released, panics caught).
    fn finish(
        self,
        py: Python<'_>,
        build: impl FnOnce(&Start) -> anyhow::Result<BatchRun> + Send,
        error: fn(String) -> PyErr,
    ) -> PyResult<PyBatch> {
        let me = &self;
        let built = py.detach(|| catch_unwind(AssertUnwindSafe(|| build(me).map(Worlds))));
        let run = built
            .map_err(|p| internal_error(p.as_ref()))?
            .map_err(|e| error(format!("{e:#}")))?;
        Ok(PyBatch {
            run: Mutex::new(run),
            scene: self.scene,
            request: self.request,
            reason: self.reason,
            initial: self.initial,
            broken: None,
        })
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
        let args = (backend, threads, gpus, cuda_options);
        let start = Start::new(py, scene, batch, precision, args)?;
        start.finish(
            py,
            |s| {
                BatchRun::new(
                    &s.worlds,
                    &s.scene.get().text,
                    |scene, w| make_backend(&s.request, scene, s.initial[w].clone()),
                    &BatchOptions::default(),
                )
                .and_then(|mut run| run.write_first_frame().map(|_| run))
            },
            BackendError::new_err,
        )
    }

    /// Continue a batch from the checkpoint folder ``path`` written by :meth:`checkpoint`:
    /// ``scene`` and ``batch`` as given to the batch that wrote it (the checkpoint is refused
    /// when they make other worlds, or the scene's text differs), the backend arguments those of
    /// the constructor. Every world takes up its clock, particles, rigid bodies and status (a
    /// frozen world stays frozen); on the CPU the batch then goes on bit for bit as the one
    /// that wrote it. :meth:`reset` still starts a world from its scene's time 0.
    #[staticmethod]
    #[pyo3(signature = (path, scene, batch = None, backend = "auto", precision = None, threads = None, gpus = None, cuda_options = None))]
    #[allow(clippy::too_many_arguments)] // Python's keyword arguments
    fn resume(
        py: Python<'_>,
        path: PathBuf,
        scene: &Bound<'_, PyAny>,
        batch: Option<i64>,
        backend: &str,
        precision: Option<&str>,
        threads: Option<usize>,
        gpus: Option<&Bound<'_, PyAny>>,
        cuda_options: Option<&str>,
    ) -> PyResult<PyBatch> {
        let args = (backend, threads, gpus, cuda_options);
        let start = Start::new(py, scene, batch, precision, args)?;
        start.finish(
            py,
            |s| {
                BatchRun::resume(
                    &s.worlds,
                    &s.scene.get().text,
                    &path,
                    |scene, _, p| make_backend(&s.request, scene, p),
                    &BatchOptions::default(),
                )
            },
            RtmpmError::new_err,
        )
    }
}
