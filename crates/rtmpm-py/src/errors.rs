//! rtmpm's Python exceptions and the conversions of Rust errors into them.
//!
//! Every error crosses into Python as an exception of this module (a Rust panic included: see
//! [`internal_error`]); the attributes carry the structured parts of the Rust error.

use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use rtmpm_scene::SceneError as RustSceneError;
use rtmpm_sim::SimError;

pyo3::create_exception!(
    rtmpm,
    RtmpmError,
    PyException,
    "Base class of every error raised by rtmpm."
);
pyo3::create_exception!(
    rtmpm,
    SceneError,
    RtmpmError,
    "A scene that does not parse or validate.\n\n\
     Attributes: ``file`` (the file, ``\"<string>\"`` or ``\"<dict>\"``), ``line`` and ``column``\n\
     (1-based, or None), ``field`` (dotted path such as ``material[1].poisson_ratio``, or None),\n\
     ``message`` and ``fix`` (how to fix it, or None). ``str(e)`` is the command line's message."
);
pyo3::create_exception!(
    rtmpm,
    SimulationError,
    RtmpmError,
    "A simulation that blew up or whose backend failed.\n\n\
     For a blow-up, ``kind == \"blowup\"`` and the attributes ``step``, ``time``, ``dt``,\n\
     ``particle`` (its original index), ``material``, ``position``, ``velocity``, ``reason`` and\n\
     ``advice`` say where and why; for a backend failure ``kind == \"backend\"``."
);
pyo3::create_exception!(
    rtmpm,
    BackendError,
    RtmpmError,
    "The backend asked for cannot run here (e.g. ``backend=\"cuda\"`` without a usable GPU),\n\
     or an operation the backend does not offer (e.g. device arrays on the CPU)."
);

/// A scene error as `rtmpm.SceneError`. `from_dict`: the generated TOML's line numbers mean
/// nothing to the user, so they are dropped.
pub fn scene_error(py: Python<'_>, e: &RustSceneError, from_dict: bool) -> PyErr {
    let mut e = e.clone();
    if from_dict {
        e.origin = "<dict>".into();
        e.line = None;
        e.column = None;
    }
    let err = SceneError::new_err(e.to_string());
    let v = err.value(py);
    let set = |name: &str, value: Py<PyAny>| {
        // Setting an attribute on a fresh exception instance cannot fail in practice; if it did,
        // the message (which holds everything) still reaches the user.
        let _ = v.setattr(name, value);
    };
    set(
        "file",
        e.origin
            .clone()
            .into_pyobject(py)
            .map(|o| o.into_any().unbind())
            .unwrap_or_else(|_| py.None()),
    );
    set("line", opt(py, e.line));
    set("column", opt(py, e.column));
    set("field", opt_str(py, e.field.as_deref()));
    set("message", opt_str(py, Some(&e.message)));
    set("fix", opt_str(py, e.hint.as_deref()));
    err
}

fn opt(py: Python<'_>, v: Option<usize>) -> Py<PyAny> {
    match v {
        Some(v) => v
            .into_pyobject(py)
            .map(|o| o.into_any().unbind())
            .unwrap_or_else(|_| py.None()),
        None => py.None(),
    }
}

fn opt_str(py: Python<'_>, v: Option<&str>) -> Py<PyAny> {
    match v {
        Some(v) => v
            .into_pyobject(py)
            .map(|o| o.into_any().unbind())
            .unwrap_or_else(|_| py.None()),
        None => py.None(),
    }
}

/// A simulation error as `rtmpm.SimulationError`, with the blow-up's details as attributes.
pub fn sim_error(py: Python<'_>, e: &SimError) -> PyErr {
    let err = SimulationError::new_err(e.to_string());
    let v = err.value(py);
    match e {
        SimError::Blowup(b) => {
            let _ = v.setattr("kind", "blowup");
            let _ = v.setattr("step", b.step);
            let _ = v.setattr("time", b.time);
            let _ = v.setattr("dt", b.dt);
            let _ = v.setattr("particle", b.particle);
            let _ = v.setattr("material", b.material.as_str());
            let _ = v.setattr("position", b.position.to_array());
            let _ = v.setattr("velocity", b.velocity.to_array());
            let _ = v.setattr("reason", b.reason.as_str());
            let _ = v.setattr(
                "advice",
                "use a smaller time step (lower `time.dt`, or `time.cfl` / `time.max_dt`), or a \
                 softer material (lower stiffness) at this resolution",
            );
        }
        SimError::Stall(b) => {
            let _ = v.setattr("kind", "stall");
            let _ = v.setattr("step", b.step);
            let _ = v.setattr("time", b.time);
            let _ = v.setattr("dt", b.dt);
            let _ = v.setattr("particle", b.particle);
            let _ = v.setattr("material", b.material.as_str());
            let _ = v.setattr("position", b.position.to_array());
            let _ = v.setattr("velocity", b.velocity.to_array());
            let _ = v.setattr("reason", b.reason.as_str());
            let _ = v.setattr(
                "advice",
                "the CFL step fell below time.min_dt: lower the body's velocity, use a fixed \
                 time.dt or a softer material; or lower time.min_dt if the speed is intended",
            );
        }
        SimError::Backend(m) => {
            let _ = v.setattr("kind", "backend");
            let _ = v.setattr("reason", m.as_str());
        }
    }
    err
}

/// A Rust panic caught at the boundary, as `rtmpm.SimulationError` (never a crash of the
/// interpreter or a `PanicException`).
pub fn internal_error(payload: &(dyn std::any::Any + Send)) -> PyErr {
    let what = payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into());
    SimulationError::new_err(format!(
        "internal error in rtmpm (a bug, please report it): {what}; this simulation can no \
         longer be used"
    ))
}

/// A message as `rtmpm.BackendError`.
pub fn backend_error(msg: impl Into<String>) -> PyErr {
    BackendError::new_err(msg.into())
}
