//! rtmpm CUDA backend: the real-time MPM pipeline of Fei, Huang & Gao, "Real-Time Simulation of
//! MPM on Modern GPUs" (GTC 2022), on one GPU or several.
//!
//! Loaded at run time (cudarc with dynamic loading): the default build needs no CUDA, and
//! [`probe`] says why CUDA is unusable instead of panicking.
//!
//! # Where things are
//! Each folder holds one concept; a host file is named after the kernels it launches.
//! * [`step`]: the step, once (rebuild, P2G, grid update, MUSL re-map, G2P; hooks for the
//!   modes), captured and replayed by [`step::graph`]; one host file per stage next to its
//!   kernels: [`step::rebuild`] + `kernels/rebuild.cu`, [`step::p2g`] + `kernels/p2g/`,
//!   [`step::grid_update`] + `kernels/grid_update.cu`, [`step::g2p`] + `kernels/g2p/`; the rigid
//!   bodies the grid update couples, [`step::rigid`].
//! * [`contract`]: the host/device contract, once (constants, struct layouts, the generated
//!   headers and layout checks); [`kernels`]: the kernel list, once (from `build.rs`), and the
//!   constant symbols; [`compile`]: the program (NVRTC, PTX cache); [`encode`]: the scene as
//!   GPU parameters; [`options`]: `--cuda-options`; [`Unavailable`] and the driver errors: one
//!   error module.
//! * [`setup`]: what a GPU is built from: the initial mapping, [`setup::capacity`],
//!   [`setup::buffers`], the device fill ([`setup::fill`] + `kernels/fill.cu`) and the bodies
//!   drawn on the GPU ([`setup::sample`] + `kernels/sample.cu`, `sample.cuh`).
//! * [`state`]: the particle state's words, packed on the host and read back (`kernels/state.cuh`),
//!   and the compact state's codec ([`state::codec`] + `kernels/codec.cuh`).
//! * [`backend`]: [`CudaBackend`], one GPU: its build, its step, the simulation's `Backend`,
//!   reads ([`backend::readback`]), emitted particles ([`backend::emit`]), per-stage timing
//!   ([`backend::bench`]).
//! * [`export`]: the state for other libraries (`kernels/export.cu`): zero-copy views, frame
//!   chunks ([`export::chunks`]), positions in original order ([`export::ordered`]).
//! * [`multi`]: several GPUs (`kernels/multi/`).
//! * [`waits`]: the host's waits for the device, counted by reason (`RTMPM_SYNC_TRACE`).
//! * [`view`]: a live view (the picture drawn from the state on the GPU, `kernels/render/`;
//!   gravity and the user's tool changed between steps).
//!
//! # The step (all launches on one non-default stream, no host synchronisation)
//! 1. **rebuild**, merged: one persistent kernel launched every step (`rb_fused`, cooperative,
//!    phases separated by a grid barrier; `rebuild=kernels`: fifteen kernels); it only clears
//!    the grid unless the device rebuild flag is set (free zone; with G2P2G not even that).
//!    Block codes, GPU hash table (block code -> dense id, atomicCAS open addressing), gblocks,
//!    pblocks with explicit 3x3x3 neighbour lists, complete block+cell counting sort, warp list.
//! 2. **P2G**, merged: Kirchhoff stress + in-warp cell-code sort (mixed sorting) + warp-level
//!    segmented reduction + global atomics; or one of the two gathers of Chiang et al., "GPU
//!    Acceleration of the Generalized Interpolation Material Point Method" (SAAHPC 2009)
//!    (`p2g=reverse_map`, `p2g=sort`). Every strategy takes the per-particle quantities from
//!    one device function (`kernels/p2g/particle.cuh`).
//! 3. **grid update**, merged: velocity + gravity + walls + colliders.
//! 4. **G2P**, merged: interpolation + F update + plasticity + advection + domain clamp +
//!    free-zone check + health check (first bad particle, max speed).
//!
//! **G2P2G** (default on one GPU with the MLS transfer, `g2p2g=off` to compare): stage 4 and the
//! next step's stage 2 run as ONE kernel (`kernels/g2p/g2p2g.cu`, the "merged kernels" taken
//! across the step boundary, the G2P2G of Wang et al. 2020): while a particle's new state is in
//! registers it is scattered into a second grid, which the next step's grid update reads; the
//! two grids alternate (one CUDA graph per parity). The P2G kernel then runs only after a
//! rebuild or when dt changed. Scenes whose materials are all fluids run `g2p2g_fluid`, which
//! moves one word of F in and three out (a fluid's F is J^(1/3) I) and skips the material
//! dispatch.
//!
//! Particle state: structure of arrays of `real` words (f32, or f64 with `precision = "f64"`),
//! word `w` of particle `i` at `state[w * capacity + i]`, each field at the words of the
//! backend's [`contract::StateLayout`] (29 words; 20 when every material is a fluid; 24 and 15
//! with the compact C of [`state::codec`]); [`state`] converts at upload and download;
//! particles are physically reordered at every rebuild and carry their original index,
//! [`CudaBackend`] returns them in original order.
//! Grid nodes: 4 reals (mass, momentum/velocity) per node, 64 nodes per pblock.
//!
//! Read-only parameters (scalars, step parameters, collider poses, materials, colliders) are
//! read from constant memory, see `kernels/common.cuh`.
//!
//! Precision: with `[solver] precision = "f64"` (or `--precision f64`) the program is compiled
//! with `RTMPM_F64` (`real` = double, PTX cached per option set) and every `real` struct of the
//! contract is f64 (the host's twin is generic over the precision). Collider geometry stays f32,
//! as on the CPU.
//!
//! Materials: every model of rtmpm-physics's registry, ported formula by formula in
//! `kernels/material/<name>.cuh`, dispatched by the switch generated from the registry
//! ([`contract::material_registry`]).

pub mod backend;
pub mod batch;
pub mod compile;
pub mod contract;
pub mod encode;
mod error;
pub mod export;
pub mod kernels;
pub mod multi;
pub mod options;
mod probe;
pub mod setup;
mod staging;
pub mod state;
pub mod step;
pub mod view;
pub mod waits;

pub use backend::CudaBackend;
pub use backend::bench::{KernelTimings, bench_kernels, measure_copy_bandwidth};
/// Page-locked host memory (see [`CudaBackend::host_buffer`]).
pub use cudarc::driver::PinnedHostSlice;
pub use error::Unavailable;
pub use export::DeviceParticles;
pub use multi::{MultiGpuBackend, NcclRankBackend, nccl, peer, rendezvous};
pub use options::{
    BarrierKind, BodyPoses, CkP2g, CudaOptions, ExchangeMode, FusedCode, FusedDefaults,
    FusedSwitches, KernelCuts, KernelSet, P2gMode, PartitionKind, RowUnroll, Transport,
};
pub use probe::{DeviceInfo, device_count, probe, probe_device};
pub use waits::{HostWaits, WaitCounts, WaitReason};
