//! Capture of a step in a CUDA graph and its replay, for every mode. A graph replays the same
//! kernels with the same arguments; the parameters of a step live in device memory (constant
//! symbols written before the replay), so a graph is valid for any time t. It is re-captured
//! when dt changes (the G2P2G parity and the scatter depend on it) and per grid parity with
//! G2P2G (the two grids swap roles every step).

use crate::error::err;
use cudarc::driver::sys::{CUgraphInstantiate_flags, CUstreamCaptureMode};
use cudarc::driver::{CudaGraph, CudaStream};
use rtmpm_sim::SimError;
use std::sync::Arc;

/// The captured steps of a backend: one per grid parity, each with the dt it was captured for.
#[derive(Default)]
pub struct StepGraphs {
    graphs: [Option<(CudaGraph, f32)>; 2],
}

impl StepGraphs {
    /// Run the step of `parity` and `dt`: replay its graph, else capture `enqueue` on `stream`
    /// (never the default stream) and launch the capture.
    pub fn run(
        &mut self,
        stream: &Arc<CudaStream>,
        parity: usize,
        dt: f32,
        enqueue: impl FnOnce() -> Result<(), SimError>,
    ) -> Result<(), SimError> {
        if let Some((g, gdt)) = &self.graphs[parity]
            && *gdt == dt
        {
            return g.launch().map_err(err("graph launch"));
        }
        self.graphs[parity] = None;
        stream
            .begin_capture(CUstreamCaptureMode::CU_STREAM_CAPTURE_MODE_THREAD_LOCAL)
            .map_err(err("begin capture"))?;
        let r = enqueue();
        let g = stream
            .end_capture(CUgraphInstantiate_flags(0))
            .map_err(err("end capture"))?;
        r?;
        let g = g.ok_or_else(|| SimError::Backend("CUDA: empty graph".into()))?;
        g.launch().map_err(err("graph launch"))?;
        self.graphs[parity] = Some((g, dt));
        Ok(())
    }

    /// Drop every captured graph (buffers were reallocated, or a communicator is about to go).
    pub fn clear(&mut self) {
        self.graphs = [None, None];
    }
}
