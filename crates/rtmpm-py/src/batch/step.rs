//! Stepping the worlds: steps, a frame, or frames, every running world at once.

use super::PyBatch;
use pyo3::prelude::*;
use rtmpm_driver::batch::chunk::next_chunk;

#[pymethods]
impl PyBatch {
    /// Take ``n`` steps in every running world, each of its own time step (on the GPU: the one
    /// step of every world; frames end on their times as with ``rtmpm run``). Returns the
    /// worlds frozen by a blow-up during the call.
    #[pyo3(signature = (n = 1))]
    fn step(&mut self, py: Python<'_>, n: u64) -> PyResult<Vec<usize>> {
        // In driver calls of at most `self.chunk` steps, with Ctrl-C checked between them: a
        // huge `n` can be interrupted. The chunk is learnt from the calls' times and kept
        // between calls (`step(10)` called again and again is one driver call each).
        let mut left = n;
        let mut frozen = Vec::new();
        while left > 0 && self.r().running() > 0 {
            let k = self.chunk.min(left);
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
}
