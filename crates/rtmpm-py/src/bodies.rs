//! Rigid bodies seen from Python: their states as dicts, and the cargo features the module was
//! built with (`rtmpm.features`: `rigid` simulates `[[rigid_body]]` tables).

use pyo3::prelude::*;
use pyo3::types::PyDict;
use rtmpm_core::rigid::BodyPose;

/// The optional cargo features of this build, by name.
pub fn features() -> Vec<&'static str> {
    let mut f = Vec::new();
    if cfg!(feature = "rigid") {
        f.push("rigid");
    }
    if cfg!(feature = "interop") {
        f.push("interop");
    }
    f
}

/// Each body's state as a dict: `position` (its centre, m), `rotation` (unit quaternion
/// `(x, y, z, w)`, body to world), `velocity` (m/s) and `angular_velocity` (rad/s).
pub fn states<'py>(py: Python<'py>, poses: &[BodyPose]) -> PyResult<Vec<Bound<'py, PyDict>>> {
    poses
        .iter()
        .map(|b| {
            let d = PyDict::new(py);
            d.set_item("position", b.position.to_array())?;
            d.set_item("rotation", b.rotation.to_array())?;
            d.set_item("velocity", b.velocity.to_array())?;
            d.set_item("angular_velocity", b.angular_velocity.to_array())?;
            Ok(d)
        })
        .collect()
}
