//! Rigid bodies per world: kinematic bodies (tools, pushers) posed world by world, their
//! states, and the force and torque the material puts on them; on the CPU backend through each
//! world's own simulation, on the GPU through the batch's per-world bodies
//! (`rtmpm_sim::Worlds::world_rigid_poses` and the rest).

use super::PyBatch;
use super::arrays::f32_array;
use super::run::Run;
use crate::bodies::{BodyRef, BodyUpdate, set_body};
use crate::errors::{BackendError, sim_error};
use numpy::{PyArray1, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::{PyIndexError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rtmpm_cuda::batch::CudaBatch;
use rtmpm_driver::batch::WorldStatus;
use rtmpm_driver::batch::lockstep::LockstepRun;
use rtmpm_rigid::{BodyLoad, BodyPose};
use rtmpm_sim::Worlds;
use std::time::Instant;

/// `RTMPM_POSE_TIMING=1`: where `set_rigid_body`'s time goes on a GPU batch, printed to stderr
/// every 100 calls (the means of the arrays read, the checks of the new poses, and their putting
/// in); off by default (one check of a flag a call).
static TIMING: rtmpm_sim::timing::PartTimes<3> = rtmpm_sim::timing::PartTimes::new(
    "RTMPM_POSE_TIMING",
    "set_rigid_body",
    "worlds",
    ["arrays", "checks", "put"],
);

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
    /// Pose rigid body ``body`` (its index in ``[[rigid_body]]`` or its name) in worlds
    /// ``worlds`` (default: all) from the next step on, as :meth:`Simulation.set_rigid_body`
    /// does in one: ``position`` (m), ``rotation`` (quaternion ``(x, y, z, w)``), ``velocity``
    /// (m/s), ``angular_velocity`` (rad/s), each one value for every world listed (shape
    /// ``(3,)``, ``(4,)``) or one row per world (``(k, 3)``, ``(k, 4)``). A kinematic body (a
    /// tool, a pusher) moves at the velocity given. Bad values raise ``ValueError`` naming the
    /// world; the worlds before it are already set. One call for every world is the fast way
    /// to pose a tool in a loop: the arrays are read once and, on the GPU, every world's new
    /// pose is checked first and then set (no Python object, no vector, per world).
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
        let t0 = Instant::now();
        let list = self.world_list(worlds)?;
        let k = list.len();
        let body = BodyRef::from_py(body)?;
        let position = per_world::<3>("position", position, k)?;
        let rotation = per_world::<4>("rotation", rotation, k)?;
        let velocity = per_world::<3>("velocity", velocity, k)?;
        let angular = per_world::<3>("angular_velocity", angular_velocity, k)?;
        let t1 = Instant::now();
        let update = |j: usize| BodyUpdate {
            position: position.as_ref().map(|p| p[j]),
            rotation: rotation.as_ref().map(|p| p[j]),
            velocity: velocity.as_ref().map(|p| p[j]),
            angular_velocity: angular.as_ref().map(|p| p[j]),
        };
        let in_world = |w: usize, e: PyErr| {
            let msg = format!("world {w}: {}", e.value(py));
            PyErr::from_type(e.get_type(py), msg)
        };
        match self.r() {
            Run::Each(r) => {
                for (j, &w) in list.iter().enumerate() {
                    let sim = &mut r.worlds[w].sim;
                    let i = body.index(&sim.scene.rigid_bodies)?;
                    set_body(py, sim, i, &update(j)).map_err(|e| in_world(w, e))?;
                }
                Ok(())
            }
            Run::Lockstep(r) => {
                let (posed, failed) = new_poses(r, &body, &list, update, in_world);
                let t2 = Instant::now();
                for (i, run) in posed {
                    // Through the run: remembered while a step call's check is pending.
                    r.set_body_poses(i, run).map_err(super::run_error)?;
                }
                TIMING.record(k, [t0, t1, t2], Instant::now());
                failed.map_or(Ok(()), Err)
            }
        }
    }

    /// World ``world``'s rigid bodies as :attr:`Simulation.rigid_bodies` gives them (dicts of
    /// ``position``, ``rotation``, ``velocity``, ``angular_velocity``).
    fn rigid_bodies<'py>(
        &mut self,
        py: Python<'py>,
        world: i64,
    ) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let w = self.world_list(Some(vec![world]))?[0];
        self.settled(py)?;
        match self.r() {
            Run::Each(r) => {
                let backend = &mut r.worlds[w].sim.backend;
                backend.flush_rigid().map_err(|e| sim_error(py, &e))?;
                crate::bodies::states(py, &backend.rigid_poses(), backend.rigid_loads())
            }
            Run::Lockstep(r) => {
                let b = &r.sim.backend;
                let loads = b.world_rigid_loads(w).map_err(|e| sim_error(py, &e))?;
                crate::bodies::states(py, &b.world_rigid_poses(w), loads)
            }
        }
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
        self.loads(py, "rigid_force", body, |l| l.force)
    }

    /// ``(N, 3)`` float64 array: the torque (N m) about rigid body ``body``'s centre of mass,
    /// as :meth:`rigid_force`.
    fn rigid_torque<'py>(
        &mut self,
        py: Python<'py>,
        body: &Bound<'_, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        self.loads(py, "rigid_torque", body, |l| l.torque)
    }
}

impl PyBatch {
    /// One load component of `body` in every world, `(N, 3)`.
    fn loads<'py>(
        &mut self,
        py: Python<'py>,
        what: &str,
        body: &Bound<'_, PyAny>,
        part: impl Fn(&rtmpm_rigid::BodyLoad) -> [f64; 3],
    ) -> PyResult<Bound<'py, PyAny>> {
        let count = self.count();
        let body = BodyRef::from_py(body)?;
        self.settled(py)?;
        let mut flat = Vec::with_capacity(3 * count);
        for w in 0..count {
            let run = self.r();
            let specs = &run.scene(w).rigid_bodies;
            let i = body.index(specs)?;
            if *run.status(w) != WorldStatus::Running {
                flat.extend([f64::NAN; 3]);
                continue;
            }
            let (loads, backend) = match run {
                Run::Each(r) => {
                    let b = &r.worlds[w].sim.backend;
                    (b.rigid_loads(), b.name())
                }
                Run::Lockstep(r) => {
                    let b = &r.sim.backend;
                    let loads = b.world_rigid_loads(w).map_err(|e| sim_error(py, &e))?;
                    (loads, rtmpm_sim::Backend::name(b.as_ref()))
                }
            };
            let loads = loads.ok_or_else(|| {
                BackendError::new_err(format!(
                    "BatchSimulation.{what}: the backend `{backend}` does not report the loads \
                     on rigid bodies"
                ))
            })?;
            let l: &BodyLoad = loads.get(i).ok_or_else(|| {
                PyIndexError::new_err(format!("rigid body {i}: the backend holds no state for it"))
            })?;
            flat.extend(part(l));
        }
        Ok(PyArray1::from_vec(py, flat).reshape([count, 3])?.into_any())
    }
}

/// The new poses of `body` in the worlds `list` of a GPU batch (`update(j)`: the fields given
/// for the `j`th world listed; the checks of `Simulation.set_rigid_body`; the batch moves
/// bodies a step at a time, so the fields not given are the body's now), in runs of worlds
/// whose scenes give `body` the same index (every world's, unless their bodies' names differ),
/// up to the first world whose pose is refused, and the error for it (a body the world's scene
/// does not have as it is; a refused pose through `in_world`, which names the world).
#[allow(clippy::type_complexity)]
fn new_poses(
    run: &LockstepRun<CudaBatch>,
    body: &BodyRef,
    list: &[usize],
    update: impl Fn(usize) -> BodyUpdate,
    in_world: impl Fn(usize, PyErr) -> PyErr,
) -> (Vec<(usize, Vec<(usize, BodyPose)>)>, Option<PyErr>) {
    let mut runs: Vec<(usize, Vec<(usize, BodyPose)>)> = Vec::new();
    // The first world's index of the body, and every listed world's pose of that body read at
    // once (one lock, not one a world); a world whose scene gives the body another index reads
    // its own.
    let first = list
        .first()
        .and_then(|&w| body.index(&run.worlds[w].scene().rigid_bodies).ok());
    let mut now = Vec::new();
    if let Some(i) = first {
        run.sim.backend.world_body_poses(i, list, &mut now);
    }
    for (j, &w) in list.iter().enumerate() {
        let scene = run.worlds[w].scene();
        let i = match body.index(&scene.rigid_bodies) {
            Ok(i) => i,
            Err(e) => return (runs, Some(e)),
        };
        let read = match now.get(j) {
            Some(&pose) if first == Some(i) => pose,
            _ => run.sim.backend.world_body_pose(w, i),
        };
        let posed = read
            .ok_or_else(|| {
                PyIndexError::new_err(format!("rigid body {i}: the backend holds no state for it"))
            })
            .and_then(|mut pose| {
                update(j).apply(&scene.rigid_bodies[i], &mut pose, scene.interior())?;
                Ok(pose)
            });
        match posed {
            Ok(pose) => match runs.last_mut() {
                Some((at, poses)) if *at == i => poses.push((w, pose)),
                _ => runs.push((i, vec![(w, pose)])),
            },
            Err(e) => return (runs, Some(in_world(w, e))),
        }
    }
    (runs, None)
}
