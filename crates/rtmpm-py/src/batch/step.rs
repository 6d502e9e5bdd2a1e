//! Stepping the worlds: steps, a frame, or frames, every running world at once.

use super::{PyBatch, Run};
use pyo3::IntoPyObjectExt;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rtmpm_driver::batch::chunk::next_chunk;

/// With `overlap`, the steps of a `step(n)` call queued by one driver call up to this many (or
/// the learnt chunk, when larger); `RTMPM_BATCH_WAITS=old` cuts them into learnt chunks as
/// without `overlap`.
const OVERLAP_CALL_STEPS: u64 = 64;

#[pymethods]
impl PyBatch {
    /// Take ``n`` steps in every running world, each of its own time step (on the GPU: the one
    /// step of every world; frames end on their times as with ``rtmpm run``). Returns the
    /// worlds frozen by a blow-up found during the call. On the GPU, with :attr:`overlap` (the
    /// default there, for a fixed time step), the call returns with its steps queued, before
    /// their health check: a blow-up in them is returned by the next ``step()`` (or seen by
    /// reading :attr:`running`, :attr:`status` or the particles, which wait for the check);
    /// ``overlap = False`` (or ``RTMPM_BATCH_OVERLAP=0`` in the environment) returns it from
    /// the call whose steps failed, as on the CPU.
    #[pyo3(signature = (n = 1))]
    fn step(&mut self, py: Python<'_>, n: u64) -> PyResult<Vec<usize>> {
        // In driver calls of at most `self.chunk` steps, with Ctrl-C checked between them: a
        // huge `n` can be interrupted. The chunk is learnt from the calls' times and kept
        // between calls (`step(10)` called again and again is one driver call each).
        // With `overlap` the steps are only queued: a call of up to `OVERLAP_CALL_STEPS` steps
        // is one driver call (cut into chunks, each chunk's check would be made, waiting for
        // the device, as the next chunk begins: the blow-up of a call's first steps found and
        // returned by that same call).
        let whole = self.r().overlap() && !rtmpm_cuda::waits::old_waits();
        let mut left = n;
        let mut frozen = Vec::new();
        while left > 0 && self.r().running() > 0 {
            let k = if whole {
                left.min(self.chunk.max(OVERLAP_CALL_STEPS))
            } else {
                self.chunk.min(left)
            };
            let t0 = std::time::Instant::now();
            frozen.extend(self.drive(py, |run| run.advance_steps(k))?);
            left -= k;
            self.chunk = next_chunk(self.chunk, k, t0.elapsed().as_secs_f64());
            py.check_signals()?;
        }
        Ok(frozen)
    }

    /// Simulate every running world to the end of its current frame (on the CPU exactly as one
    /// call of :meth:`Simulation.run_frame` per world; on the GPU to the end of the shared
    /// clock's frame). Returns the worlds frozen during the call.
    fn run_frame(&mut self, py: Python<'_>) -> PyResult<Vec<usize>> {
        self.drive(py, |run| run.advance_frame())
    }

    /// Run ``frames`` frames in every running world (default: to the end of the scene's
    /// duration), checking for Ctrl-C between frames. Returns the worlds frozen during the run.
    #[pyo3(signature = (frames = None))]
    fn run(&mut self, py: Python<'_>, frames: Option<u64>) -> PyResult<Vec<usize>> {
        let count = frames.unwrap_or_else(|| self.r().frames_left());
        let mut frozen = Vec::new();
        for _ in 0..count {
            frozen.extend(self.drive(py, |run| run.advance_frame())?);
            py.check_signals()?;
        }
        Ok(frozen)
    }

    /// Wait until the GPU has done all the work the batch queued (every stream of its context:
    /// PyTorch's or CuPy's work on the device arrays too); nothing to do on the CPU. Every call
    /// that steps or resets returns with its work queued and, where it read anything back (the
    /// end of :meth:`step` with :attr:`overlap` off), done; this is for timing a loop's parts on
    /// their own (``bench/python_batch_gpu.py --breakdown``).
    fn synchronize(&mut self, py: Python<'_>) -> PyResult<()> {
        self.detached(py, Run::synchronize)
    }

    /// On the GPU: whether :meth:`step` returns with its steps queued, before the health check
    /// of its last step (default ``True`` on the GPU, as GPU simulators step asynchronously;
    /// ``RTMPM_BATCH_OVERLAP=0`` in the environment as the batch is made turns the default off;
    /// always ``False`` on the CPU). On, the script's resets, poses and own work for the next
    /// call run while the device steps. The check is made as the next call that steps,
    /// reads the particles (``x``, ``v``, a checkpoint), :attr:`status`, :attr:`running` or the
    /// rigid bodies begins (waiting for the steps then); a blow-up it finds is handled as
    /// before (the world frozen, every world put back and stepped again without it), the
    /// resets and poses made since made again, and the world is returned by the next
    /// :meth:`step` rather than by the call whose steps failed (set ``False`` for the old
    /// behaviour: each call returns after its check, its blow-ups returned by it).
    /// :attr:`time`, :attr:`frame`, :attr:`steps` and the device arrays do not wait: a world
    /// that check then freezes goes back to its frame. Only for a fixed time step
    /// (``time.dt``); otherwise each call checks as before (``overlap`` still reads ``True``).
    /// Setting ``False`` makes a pending check first. The CPU batch refuses ``True``.
    /// A call of up to 64 steps is then one driver call; the check waits for its steps alone
    /// (its control words copied behind them, and behind each frame end inside the call), not for
    /// the resets made since (:attr:`host_waits` counts the waits; ``RTMPM_BATCH_WAITS=old``
    /// in the environment: as before, for comparisons).
    #[getter]
    fn overlap(&mut self) -> bool {
        self.r().overlap()
    }

    #[setter]
    fn set_overlap(&mut self, py: Python<'_>, on: bool) -> PyResult<()> {
        self.detached(py, move |run| run.set_overlap(on))
    }

    /// The host's waits for the GPU since the batch was made, by reason (``None`` on the CPU): a
    /// diagnostic, a dict of counts, ``{"check": ..., "control": ..., "read": ..., "sums": ...,
    /// "staging": ..., "pageable": ..., "alloc": ..., "sync": ...}``: the health check's control
    /// words (a step call's check, or with :attr:`overlap` the check made as the next call
    /// begins), other control words, particles read back, rigid-body sums, page-locked upload
    /// memory still in use, copies from pageable memory (which may wait), allocations, and
    /// synchronisations. Counted where the host blocks whether or not the GPU was already done;
    /// with ``RTMPM_SYNC_TRACE=1`` in the environment :attr:`host_wait_seconds` says how long
    /// they took. Reading it waits for nothing. Take the difference of two reads for a loop's
    /// waits per call (``bench/python_batch_gpu.py`` prints them).
    #[getter]
    fn host_waits<'py>(&mut self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        self.waits_dict(py, |n, _| n.into_bound_py_any(py))
    }

    /// The seconds the host spent in each reason's waits of :attr:`host_waits` (``None`` on the
    /// CPU): zeros unless ``RTMPM_SYNC_TRACE=1`` was in the environment as the module was
    /// first used (timing every wait costs a clock read).
    #[getter]
    fn host_wait_seconds<'py>(&mut self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        self.waits_dict(py, |_, s| s.into_bound_py_any(py))
    }

    /// Rebuilds of the GPU's particle-to-block mapping since the batch was made (``None`` on the
    /// CPU): a diagnostic, read from the device after its queued work (a wait). A step rebuilds
    /// the mapping when a particle left the part of the grid it was mapped to, and the step
    /// after a reset when a reset world's particles left it (see :meth:`reset`).
    #[getter]
    fn rebuilds(&mut self, py: Python<'_>) -> PyResult<Option<u32>> {
        self.detached(py, Run::rebuilds)
    }

    /// How the GPU redid the grid's P2G after resets since the batch was made, ``(worlds put
    /// alone, every world)`` (``None`` on the CPU): a diagnostic. With the fused G2P2G step the
    /// step after a reset (or another put) redoes the P2G of the worlds put alone, or of every
    /// world where more than half were put, where the step also rebuilds the mapping, or with
    /// ``RTMPM_BATCH_REDO=old`` in the environment (as before).
    #[getter]
    fn p2g_redos(&mut self, py: Python<'_>) -> PyResult<Option<(u64, u64)>> {
        self.detached(py, |run| Ok(run.p2g_redos()))
    }
}

impl PyBatch {
    /// The host's waits by reason as a dict, each reason's value `value(count, seconds)` (`None`
    /// on the CPU): what [`PyBatch::host_waits`] and [`PyBatch::host_wait_seconds`] give.
    fn waits_dict<'py>(
        &mut self,
        py: Python<'py>,
        value: impl Fn(u64, f64) -> PyResult<Bound<'py, PyAny>>,
    ) -> PyResult<Option<Bound<'py, PyDict>>> {
        self.usable()?;
        self.r()
            .host_waits()
            .map(|w| {
                let d = PyDict::new(py);
                for (name, n, s) in w.rows() {
                    d.set_item(name, value(n, s)?)?;
                }
                Ok(d)
            })
            .transpose()
    }
}
