//! Making a batch: the worlds asked for (the scene's `[batch]` or copies of the scene), the
//! memory check before any particle is made, the backend the worlds run on, and
//! `BatchSimulation(...)` itself.

use super::{PyBatch, Run, Worlds};
use crate::backend::request;
use crate::errors::{BackendError, RtmpmError, SceneError, internal_error, scene_error};
use crate::scene::{PyScene, scene_arg};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rtmpm_backends::batch::{BatchChoice, choose_for};
use rtmpm_backends::{BackendKind, BackendRequest};
use rtmpm_cuda::batch::CudaBatch;
use rtmpm_driver::batch::lockstep::LockstepRun;
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

/// The backend request of the constructor's arguments for a batch: one GPU at most, no
/// `threads` (the worlds share the process's worker threads).
fn batch_request(
    py: Python<'_>,
    backend: &str,
    threads: Option<usize>,
    gpus: Option<&Bound<'_, PyAny>>,
    cuda_options: Option<&str>,
) -> PyResult<BackendRequest> {
    if threads.is_some() {
        return Err(PyValueError::new_err(
            "threads: the worlds of a batch share the process's worker threads (one per core); \
             leave threads out",
        ));
    }
    let one = 1usize.into_pyobject(py)?.into_any();
    let req = request(backend, None, gpus.unwrap_or(&one), cuda_options)?;
    if req.gpus > 1 {
        return Err(BackendError::new_err(format!(
            "gpus={}: a batch runs on one GPU (every world in the same kernels) or on the CPU \
             backend; leave gpus out",
            req.gpus
        )));
    }
    Ok(req)
}

/// The worlds of a batch on one GPU, every world in the same kernels, their state at the start
/// read.
fn lockstep_run(s: &Start) -> anyhow::Result<Run> {
    let mut batch = CudaBatch::new(&s.worlds.worlds, &s.initial, s.request.cuda.clone())
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    // What `reset` puts back, kept on the device (where it has the memory).
    batch
        .keep_initial(&s.initial)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let scene = batch.scene().clone();
    let text = &s.scene.get().text;
    let options = BatchOptions::default();
    let mut run = LockstepRun::new(&s.worlds, text, scene, Box::new(batch), &options)?;
    run.write_first_frame()?;
    // Step calls return before their check (`BatchSimulation.overlap`): on by default,
    // `RTMPM_BATCH_OVERLAP=0` in the environment turns the default off.
    run.set_deferred_checks(overlap_default(
        std::env::var("RTMPM_BATCH_OVERLAP").ok().as_deref(),
    ))?;
    Ok(Run::Lockstep(Box::new(run)))
}

/// `BatchSimulation.overlap` as a GPU batch is made, from `RTMPM_BATCH_OVERLAP`: on unless it is
/// `0`, `off` or `false` (any other value, `1` included, or none: on).
fn overlap_default(var: Option<&str>) -> bool {
    !matches!(
        var.map(|v| v.trim().to_ascii_lowercase()).as_deref(),
        Some("0" | "off" | "false")
    )
}

/// The worlds on the backend chosen: on the GPU when chosen, falling back to the CPU backend
/// (the reason updated) when `auto` chose a GPU that cannot make them (its memory, say).
fn new_run(s: &mut Start) -> anyhow::Result<Run> {
    if s.choice.kind == BackendKind::Cuda {
        match lockstep_run(s) {
            Ok(run) => return Ok(run),
            Err(e) if s.request.kind == BackendKind::Auto => {
                s.choice = BatchChoice {
                    kind: BackendKind::Cpu,
                    reason: format!("auto -> cpu (the GPU batch could not be made: {e:#})"),
                };
            }
            Err(e) => return Err(e),
        }
    }
    let cpu = BackendRequest {
        kind: BackendKind::Cpu,
        ..s.request.clone()
    };
    let mut run = BatchRun::new(
        &s.worlds,
        &s.scene.get().text,
        |scene, w| make_backend(&cpu, scene, s.initial[w].clone()),
        &BatchOptions::default(),
    )?;
    run.write_first_frame()?;
    Ok(Run::Each(run))
}

/// The worlds taken up from the checkpoint folder `path`, on the backend chosen (on the GPU
/// every world in the same kernels at the checkpoint's shared clock).
fn resumed_run(s: &mut Start, path: &std::path::Path) -> anyhow::Result<Run> {
    let text = &s.scene.get().text;
    let options = BatchOptions::default();
    if s.choice.kind == BackendKind::Cuda {
        let make = |p: &[Particles]| {
            let mut batch = CudaBatch::new(&s.worlds.worlds, p, s.request.cuda.clone())
                .map_err(|e| anyhow::anyhow!("{e}"))?;
            // A reset puts a world back to its time 0, not to the checkpoint.
            batch
                .keep_initial(&s.initial)
                .map_err(|e| anyhow::anyhow!("{e}"))?;
            Ok((batch.scene().clone(), Box::new(batch)))
        };
        let run = LockstepRun::resume(&s.worlds, text, path, make, &options)?;
        return Ok(Run::Lockstep(Box::new(run)));
    }
    let cpu = BackendRequest {
        kind: BackendKind::Cpu,
        ..s.request.clone()
    };
    let make = |scene: &Scene, _, p| make_backend(&cpu, scene, p);
    Ok(Run::Each(BatchRun::resume(
        &s.worlds, text, path, make, &options,
    )?))
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
    choice: BatchChoice,
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
    /// The worlds of `scene` (`batch` copies or its `[batch]`), checked, the backend they run
    /// on, and every world's particles at time 0 (what a reset starts from).
    fn new(
        py: Python<'_>,
        scene: &Bound<'_, PyAny>,
        (batch, precision): (Option<i64>, Option<&str>),
        (backend, threads, gpus, cuda_options): BackendArgs<'_, '_>,
    ) -> PyResult<Start> {
        let request = batch_request(py, backend, threads, gpus, cuda_options)?;
        let scene = scene_arg(py, scene)?;
        let s = scene.get();
        crate::scene::warn(py, &s.scene)?;
        let worlds = worlds_of(s, batch, precision)?;
        let choice = py
            .detach(|| choose_for(request.kind, &worlds.worlds, &request.cuda))
            .map_err(BackendError::new_err)?;
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
            choice,
            scene,
            worlds,
            initial,
        })
    }

    /// The batch `build` makes (with the interpreter lock released, panics caught).
    fn finish(
        mut self,
        py: Python<'_>,
        build: impl FnOnce(&mut Start) -> anyhow::Result<Run> + Send,
        error: fn(String) -> PyErr,
    ) -> PyResult<PyBatch> {
        let me = &mut self;
        let built = py.detach(|| catch_unwind(AssertUnwindSafe(|| build(me).map(Worlds))));
        let run = built
            .map_err(|p| internal_error(p.as_ref()))?
            .map_err(|e| error(format!("{e:#}")))?;
        // What a reset on the CPU builds a world's backend with: the backend chosen.
        let request = BackendRequest {
            kind: self.choice.kind,
            ..self.request
        };
        Ok(PyBatch {
            run: Mutex::new(run),
            scene: self.scene,
            request,
            reason: self.choice.reason,
            initial: self.initial.into_iter().map(std::sync::Arc::new).collect(),
            broken: None,
            device: Default::default(),
            chunk: 1,
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
        let start = Start::new(py, scene, (batch, precision), args)?;
        start.finish(py, new_run, BackendError::new_err)
    }

    /// Continue a batch from the checkpoint folder ``path`` written by :meth:`checkpoint`:
    /// ``scene`` and ``batch`` as given to the batch that wrote it (the checkpoint is refused
    /// when they make other worlds, or the scene's text differs), the backend arguments those of
    /// the constructor. Every world takes up its clock, particles, rigid bodies and status (a
    /// frozen world stays frozen); on the CPU the batch then goes on bit for bit as the one
    /// that wrote it, on the GPU within what its atomic sums allow (a GPU batch resumes worlds
    /// at one clock: a checkpoint of worlds reset at different times is refused). :meth:`reset` still starts a world from its scene's time 0.
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
        let start = Start::new(py, scene, (batch, precision), args)?;
        start.finish(py, |s| resumed_run(s, &path), RtmpmError::new_err)
    }
}
