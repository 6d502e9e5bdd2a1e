//! Per-kernel timing with CUDA events and a device-to-device copy bandwidth reference.

use crate::backend::CudaBackend;
use crate::layout::NFIELDS;
use cudarc::driver::sys::CUevent_flags;
use rtmpm_core::sim::SimError;

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

fn err(what: &'static str) -> impl Fn(cudarc::driver::DriverError) -> SimError {
    move |e| SimError::Backend(format!("CUDA: {what}: {e:?}"))
}

/// Run `warmup` then `steps` steps of size `dt` (no graph), timing each stage with events.
pub fn bench_kernels(
    b: &mut CudaBackend,
    dt: f32,
    warmup: u32,
    steps: u32,
) -> Result<KernelTimings, SimError> {
    use rtmpm_core::sim::Backend;
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
    let phases = b.p2g.phases();
    let np = phases.len();
    // Events: start, after rebuild, after each P2G phase, after the grid update, after G2P.
    let e: Vec<_> = (0..np + 4).map(|_| ev()).collect::<Result<_, _>>()?;
    let mut t = KernelTimings {
        steps,
        p2g_phases: phases.iter().map(|p| (*p, 0.0)).collect(),
        p2g_memory: b.p2g_memory(),
        ..Default::default()
    };
    for i in 0..steps {
        b.upload_params(dt, (warmup + i) as f32 * dt)?;
        let (k, s, c) = (&b.kernels, &b.stream, &b.step_ctx());
        e[0].record(s).map_err(err("record"))?;
        crate::rebuild::enqueue(k, s, c).map_err(err("rebuild"))?;
        e[1].record(s).map_err(err("record"))?;
        for p in 0..np {
            b.p2g.enqueue_phase(p, k, s, c).map_err(err("p2g"))?;
            e[2 + p].record(s).map_err(err("record"))?;
        }
        crate::grid_update::enqueue(k, s, c).map_err(err("grid"))?;
        e[np + 2].record(s).map_err(err("record"))?;
        crate::g2p::enqueue(k, s, c, b.all_fluid).map_err(err("g2p"))?;
        e[np + 3].record(s).map_err(err("record"))?;
        b.end_step();
        e[np + 3].synchronize().map_err(err("sync"))?;
        let ms = |a: usize, z: usize| {
            e[a].elapsed_ms(&e[z])
                .map(|v| v as f64)
                .map_err(err("elapsed"))
        };
        t.rebuild_ms += ms(0, 1)?;
        for p in 0..np {
            t.p2g_phases[p].1 += ms(1 + p, 2 + p)?;
        }
        t.p2g_ms += ms(1, np + 1)?;
        t.grid_update_ms += ms(np + 1, np + 2)?;
        t.g2p_ms += ms(np + 2, np + 3)?;
        t.ms_per_step += ms(0, np + 3)?;
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
    let node_bytes = 4 * if b.options.f64 { 8 } else { 4 } as u64;
    let nodes = pblocks as u64 * 64;
    let _ = NFIELDS;
    t.g2p2g = b.g2p2g();
    // Words per particle: P2G reads x, v, C, F, plastic, mass, vol0, material (28); G2P reads x,
    // F, plastic, material, id (15) and writes x, v, C, F, plastic (25). G2P2G reads the G2P
    // words, mass and vol0 (17) and writes 25. Grid: P2G's read-modify-write counted once, the
    // update reads and writes, G2P reads; G2P2G also clears the second grid. Its fluid variant
    // reads x, F's one word, material, mass, vol0 (7) and writes x, v, C, F's diagonal (18).
    let (particle_words, grid_passes) = match (t.g2p2g, b.all_fluid) {
        (true, true) => (7 + 18, 5),
        (true, false) => (17 + 25, 5),
        (false, _) => (28 + 15 + 25, 4),
    };
    t.bytes_per_step = n * 4 * particle_words + nodes * node_bytes * grid_passes;
    Ok(t)
}

/// Device-to-device copy bandwidth (GB/s, bytes read + written) of a 256 MiB buffer on device 0.
pub fn measure_copy_bandwidth() -> Result<f64, SimError> {
    crate::probe().map_err(|e| SimError::Backend(format!("CUDA unavailable: {e}")))?;
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
