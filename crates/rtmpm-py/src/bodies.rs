//! Rigid bodies seen from Python: their states as dicts, a script moving them
//! (`Simulation.set_rigid_body`), and the cargo features the module was built with
//! (`rtmpm.features`: `rigid` simulates `[[rigid_body]]` tables).

use crate::errors::sim_error;
use crate::state::Inner;
use pyo3::exceptions::{PyIndexError, PyKeyError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rtmpm_driver::Simulation;
use rtmpm_physics::math::Vec3;
use rtmpm_rigid::{BodyLoad, BodyPose, RigidBodySpec, RigidKind};
use rtmpm_sim::Backend;

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
/// `(x, y, z, w)`, body to world), `velocity` (m/s) and `angular_velocity` (rad/s); with
/// `loads` (where the backend reports them) also `force` (N) and `torque` (N m) the material put
/// on it over the last step.
pub fn states<'py>(
    py: Python<'py>,
    poses: &[BodyPose],
    loads: Option<Vec<BodyLoad>>,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    poses
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let d = PyDict::new(py);
            d.set_item("position", b.position.to_array())?;
            d.set_item("rotation", b.rotation.to_array())?;
            d.set_item("velocity", b.velocity.to_array())?;
            d.set_item("angular_velocity", b.angular_velocity.to_array())?;
            if let Some(l) = loads.as_ref().and_then(|l| l.get(i)) {
                d.set_item("force", l.force)?;
                d.set_item("torque", l.torque)?;
            }
            Ok(d)
        })
        .collect()
}

/// The index among `specs` of `body`: an int (negative counts from the end) or a body's name.
pub fn body_index(body: &Bound<'_, PyAny>, specs: &[RigidBodySpec]) -> PyResult<usize> {
    BodyRef::from_py(body)?.index(specs)
}

/// A rigid body as a script names it: its index in `[[rigid_body]]` (negative counts from the
/// end) or its name, read from Python once and looked up in each scene (a batch's worlds).
pub enum BodyRef {
    /// An index.
    Index(i64),
    /// A name.
    Name(String),
}

impl BodyRef {
    /// `body` as Python gave it: a str or an int, else `TypeError`.
    pub fn from_py(body: &Bound<'_, PyAny>) -> PyResult<BodyRef> {
        if let Ok(name) = body.extract::<String>() {
            return Ok(BodyRef::Name(name));
        }
        let i: i64 = body.extract().map_err(|_| {
            PyTypeError::new_err("body: an int (its index in [[rigid_body]]) or a str (its name)")
        })?;
        Ok(BodyRef::Index(i))
    }

    /// Its index among `specs` (`KeyError` for an unknown name, `IndexError` past the end).
    pub fn index(&self, specs: &[RigidBodySpec]) -> PyResult<usize> {
        match self {
            BodyRef::Name(name) => specs.iter().position(|s| s.name == *name).ok_or_else(|| {
                let names: Vec<&str> = specs.iter().map(|s| s.name.as_str()).collect();
                PyKeyError::new_err(format!(
                    "no rigid body named `{name}`; the scene's are {names:?}"
                ))
            }),
            &BodyRef::Index(i) => {
                let n = specs.len() as i64;
                let j = if i < 0 { i + n } else { i };
                if (0..n).contains(&j) {
                    Ok(j as usize)
                } else {
                    Err(PyIndexError::new_err(format!(
                        "rigid body {i} does not exist: the scene has {n} rigid bodies"
                    )))
                }
            }
        }
    }
}

/// What `Simulation.set_rigid_body` changes; `None` keeps the body's own.
pub struct BodyUpdate {
    pub position: Option<[f32; 3]>,
    pub rotation: Option<[f32; 4]>,
    pub velocity: Option<[f32; 3]>,
    pub angular_velocity: Option<[f32; 3]>,
}

impl BodyUpdate {
    /// `pose` with the given fields of `spec`'s body changed: finite values, the body's bounding
    /// box in its new pose inside `interior` (the domain minus the walls), a non-zero
    /// quaternion (normalised), and no velocities for a fixed body. On an error `pose` may be
    /// half changed: the caller drops it.
    pub(crate) fn apply(
        &self,
        spec: &RigidBodySpec,
        pose: &mut BodyPose,
        interior: (Vec3, Vec3),
    ) -> PyResult<()> {
        let name = &spec.name;
        let finite = |field: &str, v: &[f32]| {
            if v.iter().all(|x| x.is_finite()) {
                Ok(())
            } else {
                Err(PyValueError::new_err(format!(
                    "rigid body `{name}`: {field} {v:?} is not finite"
                )))
            }
        };
        if let Some(p) = self.position {
            finite("position", &p)?;
            pose.position = Vec3::from_array(p);
        }
        if let Some(q) = self.rotation {
            finite("rotation", &q)?;
            let q = glam::Quat::from_array(q);
            if q.length() < 1e-6 {
                return Err(PyValueError::new_err(format!(
                    "rigid body `{name}`: rotation {q} is not a rotation (a unit quaternion \
                     [x, y, z, w], e.g. [0, 0, 0, 1])"
                )));
            }
            pose.rotation = q.normalize();
        }
        if self.position.is_some() || self.rotation.is_some() {
            // As at the start (the scene's check): the body's bounding box in its new pose
            // inside the domain minus the walls, where the rigid-body engine keeps it.
            let half = spec
                .shape
                .half_extents(glam::Mat3::from_quat(pose.rotation));
            let (lo, hi) = interior;
            let (a, b) = (pose.position - half, pose.position + half);
            if a.cmplt(lo).any() || b.cmpgt(hi).any() {
                return Err(PyValueError::new_err(format!(
                    "rigid body `{name}` at {} would span {a} .. {b}, outside the domain minus \
                     the walls, {lo} .. {hi}",
                    pose.position
                )));
            }
        }
        for (field, value, target) in [
            ("velocity", self.velocity, &mut pose.velocity),
            (
                "angular_velocity",
                self.angular_velocity,
                &mut pose.angular_velocity,
            ),
        ] {
            let Some(v) = value else { continue };
            finite(field, &v)?;
            if spec.kind == RigidKind::Fixed && v != [0.0; 3] {
                return Err(PyValueError::new_err(format!(
                    "rigid body `{name}` is fixed and cannot be given a {field}: give it \
                     type = \"kinematic\" (moved by its velocity) or \"dynamic\""
                )));
            }
            *target = Vec3::from_array(v);
        }
        Ok(())
    }
}

/// Set the fields of `update` on rigid body `body` of `inner`'s simulation, from the next step
/// on: the bodies first take every impulse the grid has sent them, so the fields not given are
/// the body's at the current time.
pub fn set(
    py: Python<'_>,
    inner: &mut Inner,
    body: &Bound<'_, PyAny>,
    update: &BodyUpdate,
) -> PyResult<()> {
    inner.usable()?;
    let i = body_index(body, &inner.sim.scene.rigid_bodies)?;
    set_body(py, &mut inner.sim, i, update)
}

/// [`set`] on rigid body `i` of any simulation (a world of a batch too).
pub fn set_body<B: Backend + ?Sized>(
    py: Python<'_>,
    sim: &mut Simulation<B>,
    i: usize,
    update: &BodyUpdate,
) -> PyResult<()> {
    sim.backend.flush_rigid().map_err(|e| sim_error(py, &e))?;
    let mut poses = sim.backend.rigid_poses();
    let pose = poses.get_mut(i).ok_or_else(|| {
        PyIndexError::new_err(format!("rigid body {i}: the backend holds no state for it"))
    })?;
    update.apply(&sim.scene.rigid_bodies[i], pose, sim.scene.interior())?;
    sim.backend
        .set_rigid_poses(&poses)
        .map_err(|e| sim_error(py, &e))
}
