//! rtmpm CUDA backend: the single-GPU pipeline of seed 000 ("Real-time MPM on modern GPUs").
//!
//! Loaded at run time (cudarc with dynamic loading): the default build needs no CUDA, and
//! [`probe`] says why CUDA is unusable instead of panicking.
//!
//! # Pipeline (one step, all launches on one non-default stream, no host synchronisation)
//! 1. [`rebuild`] (`kernels/rebuild.cu`), **merged**: one persistent kernel launched every step
//!    (`rb_fused`, cooperative, phases separated by a grid barrier; `rebuild=kernels`: fifteen
//!    kernels); it only clears the grid unless the device rebuild flag is set (free zone; with
//!    G2P2G not even that). Block codes, GPU hash table (block code -> dense
//!    id, atomicCAS open addressing), gblocks, pblocks with explicit 3x3x3 neighbour lists, complete
//!    block+cell counting sort (histogram, our own scan, scatter into scratch arrays and copy back,
//!    so device pointers never change and a step can be captured in a CUDA graph), warp list.
//! 2. [`p2g`] (`kernels/p2g.cu`), **merged**: Kirchhoff stress + in-warp cell-code sort (mixed
//!    sorting) + warp-level segmented reduction + global atomics. Or one of the two gather
//!    strategies of seed 001 (`p2g=reverse_map`, `p2g=sort`): [`p2g_reverse_map`]
//!    (`kernels/p2g_reverse_map.cu`), [`p2g_sort`] (`kernels/p2g_sort.cu`). Every strategy takes
//!    the per-particle quantities from the same device function (`kernels/p2g_particle.cuh`).
//! 3. [`grid_update`] (`kernels/grid_update.cu`), **merged**: velocity + gravity + walls + colliders.
//! 4. [`g2p`] (`kernels/g2p.cu`), **merged**: interpolation + F update + plasticity + advection +
//!    domain clamp + free-zone check + health check (first bad particle, max speed).
//!
//! **G2P2G** (default on one GPU with the MLS transfer, `g2p2g=off` to compare): stage 4 and the
//! next step's stage 2 run as ONE kernel (`kernels/g2p2g.cu`, seed 000's "merge kernels" across
//! the step boundary, the G2P2G of Wang et al. 2020): while a particle's new state is in
//! registers it is scattered into a second grid, which the next step's grid update reads; the
//! two grids alternate (one CUDA graph per parity). The P2G kernel then runs only after a
//! rebuild (new mapping; a particle that left its free zone is not scattered by the fused
//! kernel) or when dt changed. A step is then rebuild (gated) + P2G (gated) + grid update +
//! G2P2G. Scenes whose materials are all fluids run `g2p2g_fluid`, which moves one word of F in
//! and three out (a fluid's F is J^(1/3) I) and skips the material dispatch. The per-particle
//! code is shared: `kernels/g2p_particle.cuh` (G2P) and `kernels/p2g_warp.cuh` (in-warp sort,
//! segmented reduction, atomics).
//!
//! Particle state: structure of arrays of `real` fields (f32, or f64 with `precision = "f64"`),
//! field `f` of particle `i` at `state[f * capacity + i]` ([`layout`] lists the fields,
//! [`state`] converts at upload and download); particles are physically reordered at every
//! rebuild and carry their original index, [`CudaBackend`] returns them in original order.
//! Grid nodes: 4 reals (mass, momentum/velocity) per node, 64 nodes per pblock.
//!
//! Read-only parameters (step parameters, materials, colliders) are read from constant memory
//! (seed 001), see `kernels/common.cuh`.
//!
//! Precision: with `[solver] precision = "f64"` (or `--precision f64`) the kernels are compiled
//! with `RTMPM_F64` (`real` = double, NVRTC output cached per option set) and the particle
//! state, the grid, the material parameters and the per-step scalars (dx, origin, dt, gravity,
//! wall friction) are f64. Collider geometry stays f32, as on the CPU.
//!
//! Materials: every model of rtmpm-core, ported line for line in `kernels/material/*.cuh` (with
//! `kernels/svd.cuh`), dispatched on `MaterialGpu::kind`.

pub mod backend;
pub mod barrier;
pub mod bench;
pub mod compile;
pub mod export;
pub mod g2p;
pub mod grid_update;
pub mod layout;
pub mod multi_gpu;
pub mod nccl;
pub mod p2g;
pub mod p2g_reverse_map;
pub mod p2g_sort;
pub mod partition;
pub mod peer;
pub mod rebuild;
pub mod reduce_shared;
pub mod rendezvous;
pub mod state;

pub use backend::CudaBackend;
pub use bench::{KernelTimings, bench_kernels, measure_copy_bandwidth};
pub use export::DeviceParticles;
pub use multi_gpu::{MultiGpuBackend, NcclRankBackend};

use std::fmt;

/// What the device is.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceInfo {
    /// Device name.
    pub name: String,
    /// Compute capability (major, minor).
    pub compute_capability: (i32, i32),
    /// Total memory (bytes).
    pub memory: usize,
    /// Streaming multiprocessors.
    pub sm_count: i32,
    /// Driver version, e.g. 13000.
    pub driver_version: i32,
}

/// Why CUDA cannot be used.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Unavailable {
    /// libcuda.so could not be loaded.
    NoDriverLibrary,
    /// libnvrtc.so.13 could not be loaded.
    NoNvrtc,
    /// The driver reports no device.
    NoDevice,
    /// A driver call failed.
    Driver(String),
}

impl fmt::Display for Unavailable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Unavailable::NoDriverLibrary => {
                write!(f, "libcuda.so not found (no NVIDIA driver installed)")
            }
            Unavailable::NoNvrtc => write!(
                f,
                "libnvrtc.so.13 not found (pip install nvidia-cuda-nvrtc==13.0.*, set RTMPM_NVRTC_LIB or LD_LIBRARY_PATH)"
            ),
            Unavailable::NoDevice => write!(f, "no CUDA device found"),
            Unavailable::Driver(m) => write!(f, "CUDA driver error: {m}"),
        }
    }
}

impl std::error::Error for Unavailable {}

fn driver_present() -> bool {
    std::panic::catch_unwind(|| unsafe { cudarc::driver::sys::is_culib_present() }).unwrap_or(false)
}

/// Probe CUDA device 0. Never panics.
pub fn probe() -> Result<DeviceInfo, Unavailable> {
    probe_device(0)
}

/// Number of CUDA devices (0 when the driver or NVRTC is missing). Never panics.
pub fn device_count() -> usize {
    if !driver_present() || !compile::nvrtc_available() {
        return 0;
    }
    std::panic::catch_unwind(|| cudarc::driver::CudaContext::device_count().unwrap_or(0))
        .unwrap_or(0)
        .max(0) as usize
}

/// Probe CUDA device `ordinal`. Never panics.
pub fn probe_device(ordinal: usize) -> Result<DeviceInfo, Unavailable> {
    if !driver_present() {
        return Err(Unavailable::NoDriverLibrary);
    }
    if !compile::nvrtc_available() {
        return Err(Unavailable::NoNvrtc);
    }
    let r = std::panic::catch_unwind(|| -> Result<DeviceInfo, Unavailable> {
        use cudarc::driver::{CudaContext, sys::CUdevice_attribute};
        let n = CudaContext::device_count().map_err(|e| Unavailable::Driver(format!("{e:?}")))?;
        if n < 1 || ordinal >= n as usize {
            return Err(Unavailable::NoDevice);
        }
        let ctx = CudaContext::new(ordinal).map_err(|e| Unavailable::Driver(format!("{e:?}")))?;
        let d = |e| Unavailable::Driver(format!("{e:?}"));
        let mut driver_version = 0;
        // SAFETY: out-parameter.
        unsafe { cudarc::driver::sys::cuDriverGetVersion(&mut driver_version) };
        Ok(DeviceInfo {
            name: ctx.name().map_err(d)?,
            compute_capability: ctx.compute_capability().map_err(d)?,
            memory: ctx.total_mem().map_err(d)?,
            sm_count: ctx
                .attribute(CUdevice_attribute::CU_DEVICE_ATTRIBUTE_MULTIPROCESSOR_COUNT)
                .map_err(d)?,
            driver_version,
        })
    });
    match r {
        Ok(r) => r,
        Err(_) => Err(Unavailable::Driver(
            "the CUDA driver panicked during probing".into(),
        )),
    }
}

/// P2G variant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum P2gMode {
    /// Warps of 32 particles, no shared memory (seed 000).
    Warp,
    /// One CUDA block per gblock with a shared-memory node tile (earlier work), for ablation.
    Shared,
    /// Gather through replicated node-to-particle reverse maps built with atomicAdd (seed 001).
    ReverseMap,
    /// Gather through one sort per step of the particle-node contributions (seed 001).
    Sort,
}

impl P2gMode {
    /// The name used by `--cuda-options p2g=NAME`.
    pub fn name(self) -> &'static str {
        match self {
            P2gMode::Warp => "warp",
            P2gMode::Shared => "shared",
            P2gMode::ReverseMap => "reverse_map",
            P2gMode::Sort => "sort",
        }
    }
}

/// Several GPUs of one process: how the shared blocks are summed across GPUs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transport {
    /// Each GPU's kernel reads the peers' packed shared blocks through peer pointers (seed 000).
    P2p,
    /// NCCL all-reduce.
    Nccl,
}

/// Several GPUs with `transport=p2p`: the inter-GPU synchronisation of a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BarrierKind {
    /// The seed's spin-lock barrier: a one-block kernel with system-scope atomics.
    Spin,
    /// Events: every GPU's stream waits on the peers' events (no CUDA graph).
    Events,
}

/// Ablation switches of the seed-000 principles. `Default` = all on.
#[derive(Clone, Debug, PartialEq)]
pub struct CudaOptions {
    /// Rebuild the mapping only when a particle leaves its free zone (else every step).
    pub free_zone: bool,
    /// Mixed sorting: in-warp cell sort between rebuilds. Off: complete sort (rebuild) every step.
    pub mixed_sort: bool,
    /// Warp-level segmented reduction in P2G (off: every lane issues its own atomics).
    pub warp_reduce: bool,
    /// P2G variant.
    pub p2g: P2gMode,
    /// `p2g=reverse_map`: number of replicated maps (the paper's nine by default).
    pub rmap_replicas: usize,
    /// `p2g=reverse_map`: entries per node and map; `None`: twice the initial largest node load.
    pub rmap_slots: Option<usize>,
    /// `p2g=reverse_map`: pblocks the maps cover; `None`: four times the initial pblocks.
    pub rmap_pblocks: Option<usize>,
    /// `--use_fast_math`.
    pub fast_math: bool,
    /// Capture one step in a CUDA graph and replay it (used while dt stays fixed).
    pub graph: bool,
    /// Double precision: the whole pipeline in f64 (also set by the scene's
    /// `[solver] precision = "f64"`).
    pub f64: bool,
    /// Capacity overrides (gblocks, pblocks); `None`: from the initial layout with headroom.
    pub gblock_capacity: Option<usize>,
    /// See `gblock_capacity`.
    pub pblock_capacity: Option<usize>,
    /// Several GPUs: blocks the shared-block reduction holds (`None`: from the partition, grown
    /// at frame ends).
    pub shared_capacity: Option<usize>,
    /// Several GPUs: re-partition the particles at a frame end when they have drifted.
    pub rebalance: bool,
    /// Several GPUs: overlap the shared-block reduction with the P2G of the interior gblocks
    /// (off: P2G of every particle, then the reduction).
    pub overlap: bool,
    /// Several GPUs of one process: transport of the shared-block reduction (`None`: p2p when
    /// every pair of GPUs has peer access, else NCCL).
    pub transport: Option<Transport>,
    /// Several GPUs with `transport=p2p`: the synchronisation (`None`: spin).
    pub barrier: Option<BarrierKind>,
    /// The rebuild as one persistent kernel with grid-wide barriers (`rb_fused`, one launch per
    /// step) instead of fifteen kernels that return at once when nothing is rebuilt.
    pub fused_rebuild: bool,
    /// G2P2G: the G2P of a step and the P2G of the next in one kernel (`kernels/g2p2g.cu`), the
    /// P2G kernel running only after a rebuild. One GPU, MLS transfer, `p2g=warp`, the free zone
    /// and mixed sorting only (not when every step rebuilds); elsewhere ignored.
    pub g2p2g: bool,
}

impl Default for CudaOptions {
    fn default() -> Self {
        CudaOptions {
            free_zone: true,
            mixed_sort: true,
            warp_reduce: true,
            p2g: P2gMode::Warp,
            rmap_replicas: p2g_reverse_map::DEFAULT_REPLICAS,
            rmap_slots: None,
            rmap_pblocks: None,
            fast_math: true,
            graph: true,
            f64: false,
            gblock_capacity: None,
            pblock_capacity: None,
            shared_capacity: None,
            rebalance: true,
            overlap: true,
            transport: None,
            barrier: None,
            fused_rebuild: true,
            g2p2g: true,
        }
    }
}

impl std::str::FromStr for CudaOptions {
    type Err = String;
    /// Comma separated `key=value`: `free_zone`, `mixed_sort`, `warp_reduce`, `fast_math`,
    /// `graph`, `f64`, `rebalance`, `overlap`, `g2p2g` (on/off/true/false/1/0), `rebuild` (fused/kernels), `p2g`
    /// (warp/shared/reverse_map/sort), `transport` (p2p/nccl), `barrier` (spin/events), `gblocks`, `pblocks`, `rmap_replicas`, `rmap_slots`,
    /// `rmap_pblocks`, `shared` (counts).
    fn from_str(s: &str) -> Result<Self, String> {
        let mut o = CudaOptions::default();
        for item in s.split(',').map(str::trim).filter(|t| !t.is_empty()) {
            let (k, v) = item
                .split_once('=')
                .ok_or_else(|| format!("`{item}`: expected key=value"))?;
            let b = || match v {
                "on" | "true" | "1" | "yes" => Ok(true),
                "off" | "false" | "0" | "no" => Ok(false),
                _ => Err(format!("`{item}`: expected on/off")),
            };
            let n = || v.parse::<usize>().map_err(|e| format!("`{item}`: {e}"));
            match k {
                "free_zone" => o.free_zone = b()?,
                "mixed_sort" => o.mixed_sort = b()?,
                "warp_reduce" => o.warp_reduce = b()?,
                "fast_math" => o.fast_math = b()?,
                "graph" => o.graph = b()?,
                "f64" => o.f64 = b()?,
                "p2g" => {
                    o.p2g = match v {
                        "warp" => P2gMode::Warp,
                        "shared" => P2gMode::Shared,
                        "reverse_map" => P2gMode::ReverseMap,
                        "sort" => P2gMode::Sort,
                        _ => {
                            return Err(format!(
                                "`{item}`: expected warp, shared, reverse_map or sort"
                            ));
                        }
                    }
                }
                "gblocks" => o.gblock_capacity = Some(n()?),
                "pblocks" => o.pblock_capacity = Some(n()?),
                "rmap_replicas" => {
                    o.rmap_replicas = n()?;
                    if o.rmap_replicas == 0 {
                        return Err(format!("`{item}`: at least 1 map"));
                    }
                }
                "rmap_slots" => o.rmap_slots = Some(n()?),
                "rmap_pblocks" => o.rmap_pblocks = Some(n()?),
                "shared" => o.shared_capacity = Some(n()?),
                "rebalance" => o.rebalance = b()?,
                "g2p2g" => o.g2p2g = b()?,
                "overlap" => o.overlap = b()?,
                "rebuild" => {
                    o.fused_rebuild = match v {
                        "fused" => true,
                        "kernels" => false,
                        _ => return Err(format!("`{item}`: expected fused or kernels")),
                    }
                }
                "transport" => {
                    o.transport = Some(match v {
                        "p2p" => Transport::P2p,
                        "nccl" => Transport::Nccl,
                        _ => return Err(format!("`{item}`: expected p2p or nccl")),
                    })
                }
                "barrier" => {
                    o.barrier = Some(match v {
                        "spin" => BarrierKind::Spin,
                        "events" => BarrierKind::Events,
                        _ => return Err(format!("`{item}`: expected spin or events")),
                    })
                }
                _ => return Err(format!("unknown CUDA option `{k}`")),
            }
        }
        Ok(o)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn probe_never_panics() {
        match probe() {
            Ok(d) => println!("CUDA device: {d:?}"),
            Err(e) => println!("CUDA unavailable: {e}"),
        }
    }

    #[test]
    fn options_parse() {
        let o: CudaOptions = "free_zone=off, p2g=shared, gblocks=10".parse().unwrap();
        assert!(!o.free_zone && o.p2g == P2gMode::Shared && o.gblock_capacity == Some(10));
        assert!("bogus=1".parse::<CudaOptions>().is_err());
        let o: CudaOptions = "p2g=reverse_map,rmap_replicas=1,rmap_slots=40"
            .parse()
            .unwrap();
        assert!(o.p2g == P2gMode::ReverseMap && o.rmap_replicas == 1 && o.rmap_slots == Some(40));
        let o: CudaOptions = "p2g=sort".parse().unwrap();
        assert_eq!(o.p2g, P2gMode::Sort);
        assert!("p2g=gather".parse::<CudaOptions>().is_err());
        assert!("rmap_replicas=0".parse::<CudaOptions>().is_err());
        let o: CudaOptions = "transport=p2p,barrier=events".parse().unwrap();
        assert_eq!(o.transport, Some(Transport::P2p));
        assert_eq!(o.barrier, Some(BarrierKind::Events));
        assert!("transport=mpi".parse::<CudaOptions>().is_err());
        assert!("barrier=sleep".parse::<CudaOptions>().is_err());
        assert!(CudaOptions::default().fused_rebuild);
        assert!(
            !"rebuild=kernels"
                .parse::<CudaOptions>()
                .unwrap()
                .fused_rebuild
        );
        assert!("rebuild=maybe".parse::<CudaOptions>().is_err());
        assert!(CudaOptions::default().g2p2g);
        assert!(!"g2p2g=off".parse::<CudaOptions>().unwrap().g2p2g);
    }
}
