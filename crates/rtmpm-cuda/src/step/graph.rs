//! Capture of a step in a CUDA graph and its replay, for every mode. A graph replays the same
//! kernels with the same arguments; the parameters of a step live in device memory (constant
//! symbols written before the replay), so a graph is valid for any time t. It is re-captured
//! when dt changes (the G2P2G parity and the scatter depend on it), per grid parity with
//! G2P2G (the two grids swap roles every step) and per body table of a batch (its rigid bodies'
//! tables taken in turn, `crate::batch::bodies`: the step's context points at one of them).

use crate::error::err;
use cudarc::driver::sys::{CUgraphInstantiate_flags, CUstreamCaptureMode};
use cudarc::driver::{CudaGraph, CudaStream};
use rtmpm_sim::SimError;
use std::sync::Arc;

/// Graphs a backend keeps at most: [`GRAPH_PARITIES`] grid parities x [`GRAPH_TABLES`] body
/// tables.
const GRAPH_PARITIES: usize = 2;
/// Body tables a step's context may point at ([`StepGraphs::run`]'s `table`).
pub const GRAPH_TABLES: usize = 2;

/// The captured steps of a backend: one per grid parity and body table, each with the dt it was
/// captured for.
#[derive(Default)]
pub struct StepGraphs {
    graphs: [Option<(CudaGraph, f32)>; GRAPH_PARITIES * GRAPH_TABLES],
}

impl StepGraphs {
    /// Run the step of `parity`, body table `table` (0 but in a batch whose bodies' tables are
    /// taken in turn) and `dt`: replay its graph, else capture `enqueue` on `stream` (never the
    /// default stream) and launch the capture.
    pub fn run(
        &mut self,
        stream: &Arc<CudaStream>,
        (parity, table): (usize, usize),
        dt: f32,
        enqueue: impl FnOnce() -> Result<(), SimError>,
    ) -> Result<(), SimError> {
        assert!(
            parity < GRAPH_PARITIES && table < GRAPH_TABLES,
            "a step graph of parity {parity}, table {table}"
        );
        let key = parity + GRAPH_PARITIES * table;
        if let Some((g, gdt)) = &self.graphs[key]
            && *gdt == dt
        {
            return g.launch().map_err(err("graph launch"));
        }
        self.graphs[key] = None;
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
        self.graphs[key] = Some((g, dt));
        Ok(())
    }

    /// Drop every captured graph (buffers were reallocated, or a communicator is about to go).
    pub fn clear(&mut self) {
        self.graphs = Default::default();
    }
}
