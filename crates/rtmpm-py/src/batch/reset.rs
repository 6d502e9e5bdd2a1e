//! Resets: chosen worlds back to time 0, from their initial state or from given positions
//! and velocities.

use super::arrays::f32_array;
use super::create::make_backend;
use super::{PyBatch, Run};
use numpy::PyUntypedArrayMethods;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rtmpm_physics::Particles;
use rtmpm_physics::math::Vec3;
use std::sync::Arc;
use std::time::Instant;

/// `RTMPM_RESET_TIMING=1`: where `reset`'s time goes, printed to stderr every 100 calls (the
/// means of the arrays and start states made on the host, and the driver's reset: on the GPU
/// the put, whose own parts `RTMPM_RESET_TIMING` prints from rtmpm-cuda, the bodies and
/// records); off by default (one check of a flag a call).
static TIMING: rtmpm_sim::timing::PartTimes<2> = rtmpm_sim::timing::PartTimes::new(
    "RTMPM_RESET_TIMING",
    "reset",
    "worlds",
    ["start states", "driver's reset"],
);

impl PyBatch {
    /// World `w`'s particles at time 0, with `x` / `v` (rows of `n` x 3) replacing theirs: its
    /// initial particles shared (no copy) when neither is given.
    fn start_state(
        &mut self,
        w: usize,
        x: Option<&[f32]>,
        v: Option<&[f32]>,
    ) -> PyResult<Arc<Particles>> {
        if x.is_none() && v.is_none() {
            return Ok(self.initial[w].clone());
        }
        let mut p = Particles::clone(&self.initial[w]);
        let (lo, hi) = {
            let scene = self.r().scene(w);
            (scene.domain_min, scene.domain_max)
        };
        for (name, given, target) in [("x", x, &mut p.x), ("v", v, &mut p.v)] {
            let Some(rows) = given else { continue };
            for (i, r) in rows.chunks_exact(3).enumerate() {
                let r = Vec3::new(r[0], r[1], r[2]);
                if !r.is_finite() {
                    return Err(PyValueError::new_err(format!(
                        "{name} of world {w}, particle {i}: {r} is not finite"
                    )));
                }
                if name == "x" && (r.cmplt(lo).any() || r.cmpgt(hi).any()) {
                    return Err(PyValueError::new_err(format!(
                        "x of world {w}, particle {i}: {r} is outside the domain [{lo}, {hi}]"
                    )));
                }
                target[i] = r;
            }
        }
        Ok(Arc::new(p))
    }
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

#[pymethods]
impl PyBatch {
    /// Put worlds ``worlds`` (default: all) back to time 0: to their initial state, or with
    /// positions ``x`` and/or velocities ``v`` given (``(k, n, 3)`` when the ``k`` worlds hold
    /// ``n`` particles each, or their rows one world after another; the other fields, and
    /// what is not given, as at time 0). The other worlds are not touched. A frozen world runs
    /// again. On the GPU the worlds share one clock: resetting every world puts it back to 0;
    /// resetting some starts their time, frames and steps from now, refused (before any world
    /// changes) when the scene's colliders move with the clock.
    #[pyo3(signature = (worlds = None, *, x = None, v = None))]
    fn reset(
        &mut self,
        py: Python<'_>,
        worlds: Option<Vec<i64>>,
        x: Option<Bound<'_, PyAny>>,
        v: Option<Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        self.usable()?;
        let t0 = Instant::now();
        let list = self.world_list(worlds)?;
        let k = list.len();
        // Every world's count, for the rows of `x` / `v` (none to split without them).
        let counts: Vec<usize> = match (&x, &v) {
            (None, None) => Vec::new(),
            _ => self.initial.iter().map(|p| p.len()).collect(),
        };
        let xs = split_rows("x", x, &list, &counts)?;
        let vs = split_rows("v", v, &list, &counts)?;
        let mut starts = Vec::with_capacity(list.len());
        for (k, &w) in list.iter().enumerate() {
            let x = xs.as_ref().map(|r| r[k].as_slice());
            let v = vs.as_ref().map(|r| r[k].as_slice());
            starts.push(self.start_state(w, x, v)?);
        }
        // Back to the initial state (no `x`, no `v`): on the GPU from the image of it the batch
        // keeps on the device.
        let initial = xs.is_none() && vs.is_none();
        let req = self.request.clone();
        let t1 = Instant::now();
        self.drive(py, move |run| {
            match run {
                Run::Each(run) => {
                    for (w, p) in list.into_iter().zip(starts) {
                        let p = Arc::unwrap_or_clone(p);
                        run.reset_world(w, |scene| make_backend(&req, scene, p))?;
                    }
                }
                Run::Lockstep(run) if initial => {
                    run.reset_worlds_initial(list.into_iter().zip(starts).collect())?
                }
                Run::Lockstep(run) => {
                    let starts = starts.into_iter().map(Arc::unwrap_or_clone);
                    run.reset_worlds(list.into_iter().zip(starts).collect())?
                }
            }
            Ok(Vec::new())
        })?;
        TIMING.record(k, [t0, t1], Instant::now());
        Ok(())
    }
}
