//! `Simulation.view()`: watch and steer a simulation live, in a window (where there is a display)
//! or in a browser (a notebook, a server without a display), with `rtmpm view`'s session
//! (crate rtmpm-view) and the backend's own renderer (the one of `render_gpu`).
//!
//! The view runs a copy of the simulation from its state at the call (on the same backend
//! kind, its pictures drawn by that backend: on CUDA on the GPU); the `Simulation` object itself
//! does not move on, and the view's reset goes back to that state. The copy holds a second set
//! of the particles (on the GPU for CUDA) while the view is open.

use crate::errors::RtmpmError;
use crate::state::Inner;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rtmpm_backends::BackendRequest;
use rtmpm_driver::Simulation;
use rtmpm_physics::Particles;
use rtmpm_rigid::BodyPose;
use rtmpm_scene::{ColorBy, Scene};
use rtmpm_sim::Backend;
use rtmpm_view::{Commands, FrameSlot, Session, SessionOptions, SimFactory, Summary};
use std::net::TcpListener;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// The state a view starts from (and resets to).
#[derive(Clone)]
struct Start {
    scene: Scene,
    request: BackendRequest,
    particles: Particles,
    bodies: Vec<BodyPose>,
    time: f64,
    step: u64,
    frame: u64,
}

/// The session's simulations: the copy of `start`, built again on every reset.
fn factory(start: Start) -> SimFactory {
    Box::new(move || {
        let s = &start;
        let created = rtmpm_backends::create(&s.request, &s.scene, s.particles.clone())?;
        let mut b = created.backend;
        b.set_rigid_poses(&s.bodies).map_err(|e| e.to_string())?;
        let mut sim = Simulation::new(s.scene.clone(), Box::new(b));
        (sim.time, sim.step, sim.frame) = (s.time, s.step, s.frame);
        Ok(sim)
    })
}

/// What a view ended with, as a dict.
fn summary_dict<'py>(py: Python<'py>, s: &Summary) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("pictures", s.displayed)?;
    d.set_item("frames", s.frames)?;
    d.set_item("steps", s.steps)?;
    d.set_item("time", s.time)?;
    d.set_item("error", s.error.clone())?;
    Ok(d)
}

/// Where the view goes: `serve` None picks a browser in a notebook or without a display, else a
/// window; True or an address serves; False opens a window.
fn wants_browser(py: Python<'_>, serve: &Option<Bound<'_, PyAny>>) -> PyResult<Option<String>> {
    let default = || rtmpm_view::serve::DEFAULT_ADDR.to_string();
    match serve {
        None => {
            let notebook = py
                .import("sys")?
                .getattr("modules")?
                .contains("ipykernel")?;
            Ok((notebook || !rtmpm_view::window::display_present()).then(default))
        }
        Some(v) => {
            if let Ok(b) = v.extract::<bool>() {
                return Ok(b.then(default));
            }
            let addr: String = v.extract().map_err(|_| {
                PyValueError::new_err("serve: True, False or an address \"HOST:PORT\"")
            })?;
            Ok(Some(addr))
        }
    }
}

/// A message of the command line's server in the words of `view()`'s argument.
fn python_words(msg: &str) -> String {
    msg.replace("for --serve:", "for serve:")
        .replace("e.g. --serve ", "e.g. serve=")
}

/// How `Simulation.view()` was asked to run.
pub struct ViewArgs<'py> {
    pub serve: Option<Bound<'py, PyAny>>,
    pub size: (u32, u32),
    pub color_by: Option<String>,
    pub paused: bool,
    pub frames: Option<u64>,
    pub shadows: bool,
}

/// Open a live view of `inner`'s simulation: a window (blocks until it is closed; returns the
/// summary dict) or a browser server (returns a [`LiveView`] at once).
pub fn view(py: Python<'_>, inner: &mut Inner, args: ViewArgs<'_>) -> PyResult<Py<PyAny>> {
    let browser = wants_browser(py, &args.serve)?;
    let color_by = match &args.color_by {
        Some(c) => c.parse::<ColorBy>().map_err(PyValueError::new_err)?,
        None => inner.sim.scene.render.color_by.unwrap_or_default(),
    };
    if args.frames == Some(0) {
        return Err(PyValueError::new_err("frames must be at least 1"));
    }
    let (w, h) = args.size;
    let most = rtmpm_render::MAX_VIEW_SIDE;
    if !(16..=most).contains(&w) || !(16..=most).contains(&h) {
        return Err(PyValueError::new_err(format!(
            "size ({w}, {h}) is out of range: 16 to {most} pixels a side"
        )));
    }
    // The front-end first: a bad address or a port in use is refused before the copy is made.
    let listener = match &browser {
        Some(addr) => {
            let addr = rtmpm_view::serve::parse_addr(addr)
                .map_err(|e| PyValueError::new_err(python_words(&e)))?;
            let bound = rtmpm_view::serve::bind(addr);
            Some(bound.map_err(|e| RtmpmError::new_err(python_words(&e)))?)
        }
        None if !rtmpm_view::window::display_present() => {
            return Err(RtmpmError::new_err(
                "no display here (DISPLAY and WAYLAND_DISPLAY are not set), so no window can \
                 open: view(serve=True) serves the view to a browser",
            ));
        }
        None => None,
    };
    let start = start_state(py, inner)?;
    let options = SessionOptions {
        width: w,
        height: h,
        color_by,
        paused: args.paused,
        // Frames of the view, counted from the state it starts at.
        max_frames: args.frames.map(|n| start.frame + n),
        shadows: args.shadows,
        ..Default::default()
    };
    let title = format!("rtmpm view: {}", start.scene.name);
    let session = py
        .detach(|| Session::start(factory(start), options, None))
        .map_err(RtmpmError::new_err)?;
    match listener {
        None => {
            let opts = rtmpm_view::window::WindowOptions { title };
            let summary = py
                .detach(|| rtmpm_view::window::run(session, opts))
                .map_err(RtmpmError::new_err)?;
            Ok(summary_dict(py, &summary)?.into_any().unbind())
        }
        Some(listener) => {
            let live = LiveView::serve(listener, session)?;
            let msg = format!("view: open {} to watch and steer\n", live.url);
            py.import("sys")?
                .getattr("stderr")?
                .call_method1("write", (msg,))?;
            Ok(Py::new(py, live)?.into_any())
        }
    }
}

/// The simulation's state now, on the host (rigid bodies flushed first).
fn start_state(py: Python<'_>, inner: &mut Inner) -> PyResult<Start> {
    inner
        .sim
        .backend
        .flush_rigid()
        .map_err(|e| crate::errors::sim_error(py, &e))?;
    Ok(Start {
        scene: inner.sim.scene.clone(),
        request: inner.request.clone(),
        particles: inner.host(py)?.clone(),
        bodies: inner.sim.backend.rigid_poses(),
        time: inner.sim.time,
        step: inner.sim.step,
        frame: inner.sim.frame,
    })
}

/// A live view served to a browser (from :meth:`Simulation.view`): open :attr:`url`; in a
/// notebook it shows itself as the page. :meth:`send` steers it as the page does,
/// :attr:`status` says where it is, :meth:`wait` waits for its end, :meth:`stop` ends it (so
/// does the end of the Python process, or the view's own frame limit).
#[pyclass(name = "LiveView", module = "rtmpm")]
pub struct LiveView {
    url: String,
    commands: Commands,
    frames: Arc<FrameSlot>,
    materials: Vec<String>,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<JoinHandle<Result<Summary, String>>>,
}

impl LiveView {
    /// Serve `session` on `listener` from a thread of its own.
    fn serve(listener: TcpListener, session: Session) -> PyResult<LiveView> {
        let addr = listener
            .local_addr()
            .map_err(|e| RtmpmError::new_err(format!("the server's address: {e}")))?;
        let (commands, frames) = (session.commands(), session.frames());
        let materials = session.info.materials.clone();
        let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
        let thread = std::thread::Builder::new()
            .name("rtmpm view server".into())
            .spawn(move || {
                let shutdown = async move {
                    let _ = stopped.await;
                };
                let opts = rtmpm_view::serve::ServeOptions::default();
                let served = rtmpm_view::serve::serve(listener, &session, &opts, shutdown);
                let summary = session.finish();
                served.and(summary)
            })
            .map_err(|e| RtmpmError::new_err(format!("cannot start the server: {e}")))?;
        Ok(LiveView {
            url: format!("http://{addr}/"),
            commands,
            frames,
            materials,
            stop: Some(stop),
            thread: Some(thread),
        })
    }

    fn running_now(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }
}

#[pymethods]
impl LiveView {
    /// The page's address, e.g. ``http://127.0.0.1:8080/``.
    #[getter]
    fn url(&self) -> String {
        self.url.clone()
    }

    /// True while the view runs.
    #[getter]
    fn running(&self) -> bool {
        self.running_now()
    }

    /// The latest picture's status as a dict (the page's heads-up line: ``time``, ``frame``,
    /// ``step``, ``particles``, ``steps_per_s``, ``fps``, ``paused``, ``color_by``, ``gravity``,
    /// ``tool``, ``error``, ...; docs/viewer.md lists them), or ``None`` before the first.
    #[getter]
    fn status<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let Some(f) = self.frames.latest() else {
            return Ok(None);
        };
        let text = serde_json::to_string(&f.status)
            .map_err(|e| RtmpmError::new_err(format!("status: {e}")))?;
        Ok(Some(py.import("json")?.getattr("loads")?.call1((text,))?))
    }

    /// Steer the view as the page does: a command as a dict or its JSON text, e.g.
    /// ``{"cmd": "pause"}``, ``{"cmd": "gravity", "value": [0, 0, -9.8]}``, ``{"cmd": "throw",
    /// "x": 640, "y": 300}`` (docs/viewer.md lists them). Raises ``ValueError`` for a command it
    /// does not take, ``RtmpmError`` once the view has ended.
    fn send(&self, py: Python<'_>, command: Bound<'_, PyAny>) -> PyResult<()> {
        let text: String = match command.extract::<String>() {
            Ok(s) => s,
            Err(_) => py
                .import("json")?
                .getattr("dumps")?
                .call1((command,))?
                .extract()?,
        };
        let max = rtmpm_view::serve::ServeOptions::default().max_size;
        let c = rtmpm_view::serve::protocol::parse(&text, &self.materials, max)
            .map_err(PyValueError::new_err)?;
        self.commands
            .send(c)
            .map_err(|e| RtmpmError::new_err(e.to_string()))
    }

    /// Wait until the view ends (at its frame limit; a blow-up stops the stepping, not the
    /// view) or ``timeout`` seconds pass: returns the summary (as :meth:`stop`) once it has
    /// ended, else ``None``. Ctrl-C raises ``KeyboardInterrupt`` and leaves the view running.
    #[pyo3(signature = (timeout = None))]
    fn wait<'py>(
        &mut self,
        py: Python<'py>,
        timeout: Option<f64>,
    ) -> PyResult<Option<Bound<'py, PyDict>>> {
        let t0 = Instant::now();
        while self.running_now() {
            if timeout.is_some_and(|t| t0.elapsed().as_secs_f64() >= t) {
                return Ok(None);
            }
            py.detach(|| std::thread::sleep(Duration::from_millis(20)));
            py.check_signals()?;
        }
        self.stop(py)
    }

    /// End the view: returns its summary (``pictures``, ``frames``, ``steps``, ``time``,
    /// ``error``); ``None`` when it was stopped already.
    fn stop<'py>(&mut self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        let Some(t) = self.thread.take() else {
            return Ok(None);
        };
        let r = py
            .detach(|| t.join())
            .map_err(|_| RtmpmError::new_err("the view's server panicked"))?;
        let summary = r.map_err(RtmpmError::new_err)?;
        Ok(Some(summary_dict(py, &summary)?))
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    fn __exit__(
        &mut self,
        py: Python<'_>,
        _t: Option<Bound<'_, PyAny>>,
        _v: Option<Bound<'_, PyAny>>,
        _tb: Option<Bound<'_, PyAny>>,
    ) -> PyResult<bool> {
        self.stop(py)?;
        Ok(false)
    }

    /// The page in a notebook.
    fn _repr_html_(&self) -> String {
        format!(
            "<iframe src=\"{0}\" width=\"100%\" height=\"620\" style=\"border:0\"></iframe>\
             <div><a href=\"{0}\" target=\"_blank\">{0}</a></div>",
            self.url
        )
    }

    fn __repr__(&self) -> String {
        format!(
            "LiveView(url={:?}, running={})",
            self.url,
            if self.running_now() { "True" } else { "False" }
        )
    }
}

impl Drop for LiveView {
    fn drop(&mut self) {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
