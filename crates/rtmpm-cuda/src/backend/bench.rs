//! Timing of each stage of the step with CUDA events (the step of a run, through its one
//! sequence, `crate::step`, with an event after each stage), and a device-to-device copy
//! bandwidth reference.

use crate::backend::CudaBackend;
use crate::error::err;
use crate::step::{Hooks, Stage};
use cudarc::driver::sys::CUevent_flags;
use cudarc::driver::{CudaEvent, CudaStream};
use rtmpm_sim::SimError;

/// Timings of the pipeline, averaged over the measured steps.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct KernelTimings {
    /// Milliseconds per whole step.
    pub ms_per_step: f64,
    /// Milliseconds per step in the rebuild stage (incl. grid clear; mostly early returns).
    pub rebuild_ms: f64,
    /// P2G (all its phases).
    pub p2g_ms: f64,
    /// The phases of the P2G strategy (e.g. reverse map: build, gather), ms per step each.
    pub p2g_phases: Vec<(&'static str, f64)>,
    /// Extra device memory of the P2G strategy (buffer, bytes); empty for the scatter.
    pub p2g_memory: Vec<(&'static str, usize)>,
    /// Grid update.
    pub grid_update_ms: f64,
    /// MUSL re-map (velocities, momenta to the grid again, their update); 0 for USL and MLS.
    pub musl_ms: f64,
    /// The stages timed, in step order (`pipeline::Stage`, as the step ran them; the phases of
    /// P2G count once).
    pub stages: Vec<&'static str>,
    /// G2P.
    pub g2p_ms: f64,
    /// Rebuilds of the mapping during the measured steps.
    pub rebuilds: u32,
    /// Steps measured.
    pub steps: u32,
    /// Bytes a step must move at least: particle state read in P2G (x, v, C, F, plastic, mass,
    /// vol0, material = 28 words) and read+written in G2P (x, F, plastic, material read;
    /// x, v, C, F, plastic written), grid nodes written by P2G, read+written by the update and
    /// read by G2P.
    pub bytes_per_step: u64,
    /// G2P2G: `g2p_ms` is the fused kernel and `p2g_ms` the P2G that runs after rebuilds only.
    pub g2p2g: bool,
}

/// The benchmark's hooks: an event after every stage of the step.
struct Probe {
    events: Vec<(Stage, CudaEvent)>,
    pool: Vec<CudaEvent>,
}

impl Hooks for Probe {
    fn after(&mut self, stage: Stage, s: &CudaStream) -> Result<(), SimError> {
        let e = self
            .pool
            .pop()
            .ok_or_else(|| SimError::Backend("benchmark: out of events".into()))?;
        e.record(s).map_err(err("record"))?;
        self.events.push((stage, e));
        Ok(())
    }
}

fn stage_name(s: Stage) -> &'static str {
    match s {
        Stage::Rebuild => "rebuild",
        Stage::P2g(_) => "p2g",
        Stage::GridUpdate => "grid_update",
        Stage::MuslRemap => "musl_remap",
        Stage::G2p => "g2p",
    }
}

/// Run `warmup` then `steps` steps of size `dt` without the graph, through the same step
/// sequence as a run ([`crate::step`]), timing each stage with events.
pub fn bench_kernels(
    b: &mut CudaBackend,
    dt: f32,
    warmup: u32,
    steps: u32,
) -> Result<KernelTimings, SimError> {
    use rtmpm_sim::Backend;
    for i in 0..warmup {
        b.step(dt, i as f32 * dt)?;
    }
    b.check()?;
    let r0 = b.rebuild_count()?;
    let ctx = b.stream.context().clone();
    let ev = || {
        ctx.new_event(Some(CUevent_flags::CU_EVENT_DEFAULT))
            .map_err(err("event"))
    };
    let stages = b.plan().stages(&b.step_ctx());
    let mut t = KernelTimings {
        steps,
        p2g_phases: b.p2g.phases().iter().map(|p| (*p, 0.0)).collect(),
        p2g_memory: b.p2g_memory(),
        stages: {
            let mut names: Vec<&'static str> = stages.iter().map(|s| stage_name(*s)).collect();
            names.dedup(); // the phases of a gather P2G are one stage
            names
        },
        ..Default::default()
    };
    let start = ev()?;
    let mut probe = Probe {
        events: Vec::new(),
        pool: (0..stages.len()).map(|_| ev()).collect::<Result<_, _>>()?,
    };
    for i in 0..steps {
        b.upload_params(dt, (warmup + i) as f32 * dt)?;
        start.record(&b.stream).map_err(err("record"))?;
        b.run_step(dt, &mut probe, false)?;
        let last = probe.events.last().map(|e| &e.1).unwrap_or(&start);
        last.synchronize().map_err(err("sync"))?;
        let mut prev = &start;
        for (stage, e) in &probe.events {
            let ms = prev.elapsed_ms(e).map_err(err("elapsed"))? as f64;
            match stage {
                Stage::Rebuild => t.rebuild_ms += ms,
                Stage::P2g(p) => {
                    t.p2g_phases[*p].1 += ms;
                    t.p2g_ms += ms;
                }
                Stage::GridUpdate => t.grid_update_ms += ms,
                Stage::MuslRemap => t.musl_ms += ms,
                Stage::G2p => t.g2p_ms += ms,
            }
            prev = e;
        }
        t.ms_per_step += start.elapsed_ms(prev).map_err(err("elapsed"))? as f64;
        probe.pool.extend(probe.events.drain(..).map(|e| e.1));
    }
    if b.check()?.is_some() {
        return Err(SimError::Backend(
            "a particle went bad during the timed steps".into(),
        ));
    }
    let d = steps.max(1) as f64;
    for v in [
        &mut t.rebuild_ms,
        &mut t.p2g_ms,
        &mut t.grid_update_ms,
        &mut t.musl_ms,
        &mut t.g2p_ms,
        &mut t.ms_per_step,
    ] {
        *v /= d;
    }
    for p in &mut t.p2g_phases {
        p.1 /= d;
    }
    t.rebuilds = b.rebuild_count()? - r0;
    let (_, pblocks, _) = b.block_counts()?;
    let n = b.ctx.n as u64;
    let node_bytes = 4 * b.real_bytes() as u64;
    let nodes = pblocks as u64 * 64;
    t.g2p2g = b.g2p2g();
    // Words per particle (the 29-word layout): P2G reads x, v, C, F, plastic, mass, vol0,
    // material (28); G2P reads x, F, plastic, material, id (15) and writes x, v, C, F, plastic
    // (25). G2P2G reads the G2P words, mass and vol0 (17) and writes 25. Grid: P2G's
    // read-modify-write counted once, the update reads and writes, G2P reads; G2P2G also clears
    // the second grid. Its fluid variant reads x, F's one word, material, mass, vol0 (7) and
    // writes x, v, C, F's diagonal (18; F's one word in the fluid layout: 16). The layout's word
    // counts of v, C, F and plastic replace 3, 9, 9 and 1.
    let l = b.layout;
    let (v, c, f) = (l.v_words() as u64, l.c_words() as u64, l.f_words() as u64);
    let pl = u64::from(l.plastic().is_some());
    let g2p_reads = 3 + f + pl + 2;
    let g2p_writes = 3 + v + c + f + pl;
    let (particle_words, grid_passes) = match (t.g2p2g, b.all_fluid) {
        (true, true) => (7 + 3 + v + c + if l.fluid() { 1 } else { 3 }, 5),
        (true, false) => (g2p_reads + 2 + g2p_writes, 5),
        (false, _) => ((3 + v + c + f + pl + 3) + g2p_reads + g2p_writes, 4),
    };
    t.bytes_per_step = n * 4 * particle_words + nodes * node_bytes * grid_passes;
    Ok(t)
}

/// Device-to-device copy bandwidth (GB/s, bytes read + written) of a 256 MiB buffer on device 0.
pub fn measure_copy_bandwidth() -> Result<f64, SimError> {
    crate::probe::probe().map_err(|e| SimError::Backend(format!("CUDA unavailable: {e}")))?;
    let ctx = cudarc::driver::CudaContext::new(0).map_err(err("context"))?;
    let s = ctx.new_stream().map_err(err("stream"))?;
    let n = 64 << 20;
    let a = s.alloc_zeros::<f32>(n).map_err(err("alloc"))?;
    let mut b = s.alloc_zeros::<f32>(n).map_err(err("alloc"))?;
    s.memcpy_dtod(&a, &mut b).map_err(err("copy"))?;
    let e0 = ctx
        .new_event(Some(CUevent_flags::CU_EVENT_DEFAULT))
        .map_err(err("event"))?;
    let e1 = ctx
        .new_event(Some(CUevent_flags::CU_EVENT_DEFAULT))
        .map_err(err("event"))?;
    let reps = 10;
    e0.record(&s).map_err(err("record"))?;
    for _ in 0..reps {
        s.memcpy_dtod(&a, &mut b).map_err(err("copy"))?;
    }
    e1.record(&s).map_err(err("record"))?;
    e1.synchronize().map_err(err("sync"))?;
    let ms = e0.elapsed_ms(&e1).map_err(err("elapsed"))? as f64;
    Ok(2.0 * (n * 4) as f64 * reps as f64 / (ms * 1e-3) / 1e9)
}
