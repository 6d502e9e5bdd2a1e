//! Several GPUs (Fei, Huang & Gao, "Real-Time Simulation of MPM on Modern GPUs", GTC 2022: job
//! splitting by particles). Particles are assigned to GPUs in spatially coherent slabs
//! ([`partition`]); every GPU runs the one step sequence ([`crate::step`]) on its own
//! particles with its own block list; the only addition is the step's exchange hook
//! ([`exchange`]): after P2G the grid blocks present on several GPUs are summed across GPUs
//! ([`reduce_shared`]: NCCL all-reduce, or, between the GPUs of one process with peer access,
//! peer reads inside kernels after an inter-GPU barrier, [`barrier`]), then every GPU runs the
//! grid update and G2P on its own particles.
//!
//! Two ways to run: [`MultiGpuBackend`] ([`threaded`]), one process driving N GPUs (one thread
//! per GPU), and [`NcclRankBackend`] ([`process`]), one process per GPU (several machines),
//! meeting through a [`rendezvous::Rendezvous`]. Both are built of [`GpuRank`]s ([`rank`]).
//!
//! Sizes: the reduction moves a host-chosen number of shared blocks (`cap`, from the partition
//! with headroom, at most every block of the domain); the device checks the real count at every
//! change and stops with a clear error if it exceeds `cap`. At the end of each frame the host
//! grows `cap` when the count passed half of it, and re-partitions the particles (rebalancing)
//! when the shared blocks have grown well beyond those of the last partition (particles
//! drifted); see [`plan`].

pub mod barrier;
pub mod exchange;
pub mod nccl;
pub mod partition;
pub mod peer;
pub mod plan;
pub mod process;
pub mod rank;
pub mod reduce_shared;
pub mod rendezvous;
pub(crate) mod rigid;
pub mod threaded;

pub use plan::{check_supported, subset};
pub use process::NcclRankBackend;
pub use rank::{CommSource, GpuRank};
pub use threaded::MultiGpuBackend;
