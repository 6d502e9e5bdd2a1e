//! `rtmpm.Simulation`: a scene running on a backend, stepped from Python.
//!
//! Stepping releases the interpreter lock (other Python threads run meanwhile) and returns to
//! the interpreter about every [`crate::state::CHUNK_SECONDS`] to check for Ctrl-C, which raises
//! `KeyboardInterrupt` between two steps and leaves the simulation usable. Panics are caught
//! at this boundary and become `rtmpm.SimulationError`.

use crate::backend::{BackendInfo, request};
use crate::errors::{backend_error, internal_error, sim_error};
use crate::frames::FrameIter;
use crate::scene::{PyScene, scene_arg};
use crate::state::{Inner, PySimulation, Sim};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rtmpm_backends::BackendRequest;
use rtmpm_driver::Simulation;
use rtmpm_io::checkpoint::Checkpoint;
use rtmpm_physics::Particles;
use rtmpm_scene::Precision;
use rtmpm_sim::{Backend, SimError};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Take exactly `k` steps (crossing frame ends as `rtmpm run --steps` does).
fn step_n(sim: &mut Sim, k: u64) -> Result<(), SimError> {
    let target = sim.step + k;
    while sim.step < target {
        sim.advance(target - sim.step)?;
    }
    Ok(())
}

impl PySimulation {
    fn build(
        py: Python<'_>,
        scene: Py<PyScene>,
        particles: Particles,
        request: BackendRequest,
        precision: Option<&str>,
    ) -> PyResult<PySimulation> {
        let mut s = scene.get().scene.clone();
        if let Some(p) = precision {
            s.precision = p.parse::<Precision>().map_err(PyValueError::new_err)?;
        }
        let req = request.clone();
        let s2 = s.clone();
        let created = py
            .detach(|| {
                catch_unwind(AssertUnwindSafe(|| {
                    rtmpm_backends::create(&req, &s2, particles)
                }))
            })
            .map_err(|p| internal_error(p.as_ref()))?
            .map_err(backend_error)?;
        Ok(PySimulation {
            inner: Mutex::new(Inner {
                sim: Simulation::with_backend(s, Box::new(created.backend)),
                request,
                reason: created.reason,
                scene,
                version: 0,
                host: None,
                chunk: 8,
                exported: false,
                broken: None,
            }),
        })
    }
}

#[pymethods]
impl PySimulation {
    #[new]
    #[pyo3(signature = (scene, backend = "auto", precision = None, threads = None, gpus = None, cuda_options = None))]
    fn new(
        py: Python<'_>,
        scene: &Bound<'_, PyAny>,
        backend: &str,
        precision: Option<&str>,
        threads: Option<usize>,
        gpus: Option<&Bound<'_, PyAny>>,
        cuda_options: Option<&str>,
    ) -> PyResult<PySimulation> {
        let one = 1usize.into_pyobject(py)?.into_any();
        let req = request(backend, threads, gpus.unwrap_or(&one), cuda_options)?;
        let scene = scene_arg(py, scene)?;
        let s = &scene.get().scene;
        crate::scene::warn(py, s)?;
        let particles = s
            .sample_particles()
            .map_err(|e| crate::errors::scene_error(py, &e, scene.get().origin == "<dict>"))?;
        if particles.is_empty() {
            return Err(crate::errors::SceneError::new_err(format!(
                "{}: the scene's bodies hold no particles (add a [[body]] or make it larger)",
                scene.get().origin
            )));
        }
        PySimulation::build(py, scene, particles, req, precision)
    }

    /// Continue from a checkpoint written by :meth:`checkpoint` or ``rtmpm run
    /// --checkpoint-every`` (the checkpoint holds its scene); the backend arguments are those
    /// of the constructor. On the CPU in f32 the resumed run continues bit for bit.
    #[staticmethod]
    #[pyo3(signature = (path, backend = "auto", precision = None, threads = None, gpus = None, cuda_options = None))]
    fn resume(
        py: Python<'_>,
        path: PathBuf,
        backend: &str,
        precision: Option<&str>,
        threads: Option<usize>,
        gpus: Option<&Bound<'_, PyAny>>,
        cuda_options: Option<&str>,
    ) -> PyResult<PySimulation> {
        let one = 1usize.into_pyobject(py)?.into_any();
        let req = request(backend, threads, gpus.unwrap_or(&one), cuda_options)?;
        let ckpt = Checkpoint::load(&path).map_err(|e| {
            crate::errors::RtmpmError::new_err(format!(
                "cannot resume from {}: {e}",
                path.display()
            ))
        })?;
        let base = Path::new(&ckpt.scene_origin)
            .parent()
            .unwrap_or(Path::new(""))
            .to_path_buf();
        let from_dict = ckpt.scene_origin == "<dict>";
        let scene = PyScene::parse(
            py,
            ckpt.scene_toml.clone(),
            ckpt.scene_origin.clone(),
            &base,
            from_dict,
        )?;
        let scene = Py::new(py, scene)?;
        let mut sim = PySimulation::build(py, scene, ckpt.particles, req, precision)?;
        let inner = sim.get();
        inner.sim.time = ckpt.time;
        inner.sim.step = ckpt.step;
        inner.sim.frame = ckpt.frame;
        inner
            .sim
            .backend
            .set_rigid_poses(&ckpt.bodies)
            .map_err(|e| {
                crate::errors::RtmpmError::new_err(format!(
                    "cannot resume from {}: {e}",
                    path.display()
                ))
            })?;
        Ok(sim)
    }

    /// Take ``n`` steps (frames end on their times as with ``rtmpm run``). Returns the number
    /// of steps taken. Ctrl-C stops between two steps (``KeyboardInterrupt``).
    #[pyo3(signature = (n = 1))]
    fn step(&mut self, py: Python<'_>, n: u64) -> PyResult<u64> {
        let inner = self.get();
        let start = inner.sim.step;
        let target = start.saturating_add(n);
        inner.drive(py, |sim, chunk| {
            let k = chunk.min(target - sim.step);
            step_n(sim, k)?;
            Ok(sim.step >= target)
        })?;
        Ok(inner.sim.step - start)
    }

    /// Simulate to the end of the current frame (the frame's time, exactly); returns the
    /// number of steps taken. One call per frame steps exactly as ``rtmpm run`` does.
    pub fn run_frame(&mut self, py: Python<'_>) -> PyResult<u64> {
        let inner = self.get();
        let start = inner.sim.step;
        inner.drive(py, |sim, chunk| sim.advance(chunk))?;
        Ok(inner.sim.step - start)
    }

    /// Simulate for ``seconds`` of simulated time: whole frames while they end before the
    /// target, then single steps until :attr:`time` reaches it (the last step is not shortened,
    /// so :attr:`time` may pass the target by less than one dt unless it is a frame time).
    /// Returns the number of steps taken.
    fn advance(&mut self, py: Python<'_>, seconds: f64) -> PyResult<u64> {
        if !(seconds.is_finite() && seconds >= 0.0) {
            return Err(PyValueError::new_err(format!(
                "seconds must be a finite time >= 0, got {seconds}"
            )));
        }
        let inner = self.get();
        let start = inner.sim.step;
        let target = inner.sim.time + seconds;
        let fd = inner.sim.frame_duration();
        inner.drive(py, |sim, chunk| {
            let mut taken = 0;
            loop {
                // Reached within a thousandth of a step (times are sums of f32 steps).
                let eps = 1e-9 * fd + 1e-3 * sim.last_dt as f64;
                if sim.time >= target - eps {
                    return Ok(true);
                }
                if taken >= chunk {
                    return Ok(false);
                }
                let frame_end = (sim.frame + 1) as f64 * fd;
                let s0 = sim.step;
                if frame_end <= target + eps {
                    sim.advance(chunk - taken)?;
                } else {
                    sim.advance(1)?;
                }
                taken += sim.step - s0;
            }
        })?;
        Ok(inner.sim.step - start)
    }

    /// Run ``frames`` frames (default: to the end of the scene's duration), calling
    /// ``callback(sim)`` after each; a callback that returns ``False`` stops the run. Returns
    /// the number of frames run.
    #[pyo3(signature = (frames = None, callback = None))]
    fn run(
        slf: &Bound<'_, Self>,
        py: Python<'_>,
        frames: Option<u64>,
        callback: Option<Py<PyAny>>,
    ) -> PyResult<u64> {
        let count = match frames {
            Some(f) => f,
            None => {
                let mut s = slf.borrow_mut();
                let i = s.get();
                i.sim.scene.time.frames().saturating_sub(i.sim.frame)
            }
        };
        for done in 0..count {
            slf.borrow_mut().run_frame(py)?;
            if let Some(cb) = &callback {
                let r = cb.call1(py, (slf.clone(),))?;
                if r.bind(py).is(pyo3::types::PyBool::new(py, false)) {
                    return Ok(done + 1);
                }
            }
        }
        Ok(count)
    }

    /// An iterator over frames: each iteration runs one frame and yields its number
    /// (:attr:`frame`). ``count`` frames (default: to the end of the scene's duration).
    ///
    /// ``for frame in sim.frames(): x = sim.particles.x``
    #[pyo3(signature = (count = None))]
    fn frames(slf: &Bound<'_, Self>, count: Option<u64>) -> PyResult<FrameIter> {
        let left = match count {
            Some(c) => c,
            None => {
                let mut s = slf.borrow_mut();
                let i = s.get();
                i.sim.scene.time.frames().saturating_sub(i.sim.frame)
            }
        };
        Ok(FrameIter {
            sim: slf.clone().unbind(),
            left,
        })
    }

    /// Simulated time (s).
    #[getter]
    fn time(&mut self) -> f64 {
        self.get().sim.time
    }

    /// Frames completed.
    #[getter]
    fn frame(&mut self) -> u64 {
        self.get().sim.frame
    }

    /// Steps taken.
    #[getter]
    fn steps(&mut self) -> u64 {
        self.get().sim.step
    }

    /// The time step (s): that of the last step, or before the first step the one the scene's
    /// rule gives now (fixed dt, or CFL from the current velocities).
    #[getter]
    fn dt(&mut self, py: Python<'_>) -> PyResult<f32> {
        let inner = self.get();
        if inner.sim.step > 0 {
            return Ok(inner.sim.last_dt);
        }
        let sim = &mut inner.sim;
        let r = catch_unwind(AssertUnwindSafe(|| sim.next_dt()));
        inner.settle(py, r)
    }

    /// Duration of one frame (s), ``1 / fps``.
    #[getter]
    fn frame_duration(&mut self) -> f64 {
        self.get().sim.frame_duration()
    }

    /// The backend picked and why (:class:`rtmpm.BackendInfo`; ``str()`` gives the reason).
    #[getter]
    fn backend(&mut self) -> BackendInfo {
        let inner = self.get();
        BackendInfo {
            kind: inner.sim.backend.kind().name().into(),
            name: inner.sim.backend.name(),
            reason: inner.reason.clone(),
        }
    }

    /// The scene (:class:`rtmpm.Scene`).
    #[getter]
    fn scene(&mut self, py: Python<'_>) -> Py<PyScene> {
        self.get().scene.clone_ref(py)
    }

    /// ``"f32"`` or ``"f64"``: the precision the backend computes in.
    #[getter]
    fn precision(&mut self) -> &'static str {
        self.get().sim.scene.precision.name()
    }

    /// The rigid bodies (``[[rigid_body]]``, in file order) as of the last step: a list of dicts
    /// with ``position`` (the body's centre, m), ``rotation`` (unit quaternion ``(x, y, z, w)``,
    /// body to world), ``velocity`` (m/s) and ``angular_velocity`` (rad/s); on the CPU and CUDA
    /// backends (one GPU or several) also ``force`` (N) and ``torque`` (N m, about its centre of
    /// mass) the material put on it over the last step, for a kinematic or fixed body too. Empty without
    /// bodies; scenes with bodies need a module built with the ``rigid`` feature
    /// (``rtmpm.features``).
    #[getter]
    fn rigid_bodies<'py>(&mut self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let backend = &mut self.get().sim.backend;
        backend.flush_rigid().map_err(|e| sim_error(py, &e))?;
        crate::bodies::states(py, &backend.rigid_poses(), backend.rigid_loads())
    }

    /// Move rigid body ``body`` (its index in ``[[rigid_body]]`` or its name) from the next step
    /// on: any of ``position`` (its centre, m), ``rotation`` (quaternion ``(x, y, z, w)``,
    /// normalised), ``velocity`` (m/s), ``angular_velocity`` (rad/s); what is not given stays.
    /// The body in its new pose must lie inside the domain minus the walls (its bounding box). A kinematic body keeps the velocities it is given, a
    /// dynamic one goes on from them, a fixed one takes only a pose. Bad values raise
    /// ``ValueError``; an unknown body ``KeyError`` or ``IndexError``.
    #[pyo3(signature = (body, *, position = None, rotation = None, velocity = None, angular_velocity = None))]
    fn set_rigid_body(
        &mut self,
        py: Python<'_>,
        body: &Bound<'_, PyAny>,
        position: Option<[f32; 3]>,
        rotation: Option<[f32; 4]>,
        velocity: Option<[f32; 3]>,
        angular_velocity: Option<[f32; 3]>,
    ) -> PyResult<()> {
        let update = crate::bodies::BodyUpdate {
            position,
            rotation,
            velocity,
            angular_velocity,
        };
        crate::bodies::set(py, self.get(), body, &update)
    }

    /// Number of particles.
    #[getter]
    fn num_particles(&mut self) -> usize {
        self.get().sim.backend.num_particles()
    }

    /// The particle state: NumPy arrays (and, on CUDA, device arrays); see
    /// :class:`rtmpm.Particles`.
    #[getter]
    fn particles(slf: &Bound<'_, Self>) -> crate::particles::PyParticles {
        crate::particles::PyParticles {
            sim: slf.clone().unbind(),
        }
    }

    /// Write a checkpoint (the scene, time, step, frame, every particle and rigid body; atomic). Resume with
    /// :meth:`Simulation.resume` or ``rtmpm run --resume``.
    fn checkpoint(&mut self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        crate::output::checkpoint(py, self.get(), &path)
    }

    /// Write the particles as one frame file in any of the formats of ``[output] formats``:
    /// ``"ply"`` (binary PLY), ``"bgeo"``, ``"bgeo.gz"`` (Houdini), ``"usda"`` (USD, with the
    /// rigid bodies) or ``"vtu"`` (VTK XML), by default from the file's extension; the bytes
    /// ``rtmpm run`` writes for a frame. ``fields``: extra columns among ``"J"`` and
    /// ``"stress"`` (default: the scene's ``[output] fields``). Atomic.
    #[pyo3(signature = (path, format = None, fields = None))]
    fn write_frame(
        &mut self,
        py: Python<'_>,
        path: PathBuf,
        format: Option<&str>,
        fields: Option<Vec<String>>,
    ) -> PyResult<()> {
        let inner = self.get();
        let scene = inner.sim.scene.clone();
        let bodies = inner.sim.backend.rigid_poses();
        let p = inner.host(py)?;
        crate::output::write_frame(py, &path, format, fields, p, &bodies, &scene)
    }

    /// Render the particles as shaded spheres (the renderer of ``rtmpm render``) and return
    /// the image as a NumPy ``uint8`` array of shape ``(height, width, 3)``.
    ///
    /// ``camera``/``target``: positions ``(x, y, z)`` (default: the scene's ``[render]``, else
    /// front-right-above framing the domain); ``size``: ``(width, height)`` (default 1280x720);
    /// ``fov`` in degrees; ``color_by``: ``"material"``, ``"speed"``, ``"J"``, ``"stress"`` or
    /// ``"plastic"``; ``range``: ``(lo, hi)`` of the colour bar; ``radius`` of the spheres (m);
    /// ``shadows``, ``colliders``: draw them; ``label``: text in the top-left corner (default:
    /// frame and time).
    #[pyo3(signature = (camera = None, target = None, size = None, fov = None, color_by = None, range = None, radius = None, shadows = true, colliders = true, label = None))]
    #[allow(clippy::too_many_arguments)]
    fn render<'py>(
        &mut self,
        py: Python<'py>,
        camera: Option<[f32; 3]>,
        target: Option<[f32; 3]>,
        size: Option<(u32, u32)>,
        fov: Option<f32>,
        color_by: Option<&str>,
        range: Option<(f32, f32)>,
        radius: Option<f32>,
        shadows: bool,
        colliders: bool,
        label: Option<String>,
    ) -> PyResult<Bound<'py, numpy::PyArray3<u8>>> {
        let inner = self.get();
        let (frame, time) = (inner.sim.frame, inner.sim.time);
        let view = crate::picture::View {
            camera,
            target,
            size,
            fov,
            color_by,
            range,
            radius,
            shadows,
            colliders,
            label: Some(label.unwrap_or_else(|| format!("FRAME {frame}  T = {time:.3} S"))),
            time: time as f32,
        };
        crate::picture::render(py, inner, &view)
    }

    /// The picture of :meth:`render` drawn by the backend's own renderer, the one of a live
    /// view (:meth:`view`): on the CUDA backend by kernels reading the particle state on the
    /// GPU (only the image comes back), elsewhere by the CPU renderer. Same arguments and
    /// result as :meth:`render` (a NumPy ``uint8`` array of shape ``(height, width, 3)``);
    /// the default ``radius`` comes from the scene (0.6 of its first body's particle spacing)
    /// instead of the particles.
    #[pyo3(signature = (camera = None, target = None, size = None, fov = None, color_by = None, range = None, radius = None, shadows = true, colliders = true, label = None))]
    #[allow(clippy::too_many_arguments)]
    fn render_gpu<'py>(
        &mut self,
        py: Python<'py>,
        camera: Option<[f32; 3]>,
        target: Option<[f32; 3]>,
        size: Option<(u32, u32)>,
        fov: Option<f32>,
        color_by: Option<&str>,
        range: Option<(f32, f32)>,
        radius: Option<f32>,
        shadows: bool,
        colliders: bool,
        label: Option<String>,
    ) -> PyResult<Bound<'py, numpy::PyArray3<u8>>> {
        let inner = self.get();
        let (frame, time) = (inner.sim.frame, inner.sim.time);
        let view = crate::picture::View {
            camera,
            target,
            size,
            fov,
            color_by,
            range,
            radius,
            shadows,
            colliders,
            label: Some(label.unwrap_or_else(|| format!("FRAME {frame}  T = {time:.3} S"))),
            time: time as f32,
        };
        crate::picture::render_gpu(py, inner, &view)
    }

    /// Watch and steer the simulation live, as ``rtmpm view`` does: in a window where there
    /// is a display (blocks until it is closed, returns a summary dict: ``pictures``,
    /// ``frames``, ``steps``, ``time``, ``error``), or in a browser (in a notebook, without a
    /// display, or with ``serve=True`` / ``serve="HOST:PORT"``; default ``127.0.0.1:8080``):
    /// returns a :class:`LiveView` at once, which a notebook shows as the page.
    ///
    /// The view runs a copy of the simulation from its state now, on the same backend (its
    /// pictures drawn by the renderer of :meth:`render_gpu`: on CUDA on the GPU); this object
    /// does not move on, and the view's reset goes back to this state. ``size``: the pictures'
    /// ``(width, height)``; ``color_by``: the first colour mode; ``paused``: start paused;
    /// ``frames``: end after that many simulated frames; ``shadows``: draw them. Controls:
    /// docs/viewer.md.
    #[pyo3(signature = (serve = None, size = (1280, 720), color_by = None, paused = false, frames = None, shadows = true))]
    #[allow(clippy::too_many_arguments)] // Python's keyword arguments
    fn view(
        &mut self,
        py: Python<'_>,
        serve: Option<Bound<'_, PyAny>>,
        size: (u32, u32),
        color_by: Option<String>,
        paused: bool,
        frames: Option<u64>,
        shadows: bool,
    ) -> PyResult<Py<PyAny>> {
        let inner = self.get();
        inner.usable()?;
        let args = crate::view::ViewArgs {
            serve,
            size,
            color_by,
            paused,
            frames,
            shadows,
        };
        crate::view::view(py, inner, args)
    }

    fn __repr__(&mut self) -> String {
        let inner = self.get();
        format!(
            "Simulation(scene={:?}, backend={:?}, particles={}, frame={}, time={:.6})",
            inner.sim.scene.name,
            inner.sim.backend.name(),
            inner.sim.backend.num_particles(),
            inner.sim.frame,
            inner.sim.time
        )
    }
}
