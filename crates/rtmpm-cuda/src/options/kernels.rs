//! The kernel switches' own types: the P2G strategy, CK-MPM's P2G kernel, the instruction cuts
//! and the row unrolling of the fused kernels, and the defaults of the capacities they use.

/// P2G variant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum P2gMode {
    /// Warps of 32 particles, no shared memory (Fei, Huang & Gao, "Real-Time Simulation of MPM on Modern GPUs" (GTC 2022)).
    Warp,
    /// One CUDA block per gblock with a shared-memory node tile (earlier work), for ablation.
    Shared,
    /// Gather through replicated node-to-particle reverse maps built with atomicAdd (Chiang et al., "GPU Acceleration of the Generalized Interpolation Material Point Method" (SAAHPC 2009)).
    ReverseMap,
    /// Gather through one sort per step of the particle-node contributions (Chiang et al.).
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

/// Replicated reverse maps of `p2g=reverse_map` by default (Chiang et al.: "we maintain a set of
/// nine independent reverse maps").
pub const DEFAULT_RMAP_REPLICAS: usize = 9;

/// CK-MPM's P2G kernel (`[solver] transfer = "ck-mpm"`; `kernels/p2g/ck.cu`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CkP2g {
    /// `p2g_ck`: one lane per particle, 16 direct global atomics a particle.
    Direct,
    /// `p2g_ck_warp`: per grid, the in-warp sort, segmented warp reduction and one lane's atomics
    /// per segment of the MLS-MPM scatter (Fei, Huang & Gao, "Real-Time Simulation of MPM on
    /// Modern GPUs", GTC 2022).
    Warp,
    /// G2P2G for CK-MPM (`g2p2g_ck`, the default): the G2P of a step from both grids and, from the new
    /// state in registers, the warp scatter of `p2g_ck_warp` into both grids of the next step;
    /// `p2g_ck_warp` then runs only after a rebuild or a new dt. Where G2P2G does not apply
    /// ([`crate::options::CudaOptions::g2p2g`] off, no free zone or mixed sorting) it is `Warp`.
    Fused,
}

impl CkP2g {
    /// The name used by `--cuda-options ck_p2g=NAME`.
    pub fn name(self) -> &'static str {
        match self {
            CkP2g::Direct => "direct",
            CkP2g::Warp => "warp",
            CkP2g::Fused => "fused",
        }
    }
}

/// Instruction cuts of the fused G2P2G kernels (`--cuda-options lean_lanes=on,seg_clamp=on,
/// zero_terms=skip,flat_checks=on`), each a compile-time define of the kernels, off by default
/// until measured on a GPU (bench/RESULTS.md, "Fewer instructions, second round").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct KernelCuts {
    /// `lean_lanes=on` (`RTMPM_G2P2G_LEAN_LANES`, `kernels/g2p/g2p2g.cu`): the P2G quantities
    /// of a lane that does not scatter are left unset (its stencil base set) instead of zeroed
    /// in every warp entry; the same sums (such a lane's values reach no atomic).
    pub lean_lanes: bool,
    /// `seg_clamp=on` (`RTMPM_P2G_SEG_CLAMP`, `kernels/p2g/warp.cuh`): the segmented
    /// reduction's test "is lane + s in my segment" read from the shuffle's own in-range
    /// predicate (the segment's last lane as its clamp) instead of a comparison in every round
    /// of every row; the same additions in the same order.
    pub seg_clamp: bool,
    /// `zero_terms=skip` (`RTMPM_P2G_ZERO_TERMS`, `kernels/p2g/particle.cuh`): the affine
    /// term's products with a node offset of 0 left out of the scattered momentum instead of
    /// added (x + a 0); the same sums except for the sign of a zero and for a term that is not
    /// finite.
    pub zero_terms: bool,
    /// `flat_checks=on` (`RTMPM_G2P_FLAT_CHECKS`, `kernels/g2p/particle.cuh`): G2P's health and
    /// free-zone checks without branches between their terms and the gblock's coordinates read
    /// once per particle; the same predicates.
    pub flat_checks: bool,
}

impl KernelCuts {
    /// The kernels' defines of the cuts that are on.
    pub fn defines(self) -> Vec<&'static str> {
        [
            (self.lean_lanes, "-DRTMPM_G2P2G_LEAN_LANES=1"),
            (self.seg_clamp, "-DRTMPM_P2G_SEG_CLAMP=1"),
            (self.zero_terms, "-DRTMPM_P2G_ZERO_TERMS=1"),
            (self.flat_checks, "-DRTMPM_G2P_FLAT_CHECKS=1"),
        ]
        .into_iter()
        .filter_map(|(on, d)| on.then_some(d))
        .collect()
    }
}

/// The warp scatter's row loop ([`crate::options::CudaOptions::row_unroll`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RowUnroll {
    /// A loop over the nine rows (the default).
    #[default]
    Off,
    /// The three rows of a plane unrolled (`-DRTMPM_P2G_UNROLL=2`).
    Planes,
    /// All nine rows unrolled (`-DRTMPM_P2G_UNROLL=1`).
    All,
}

impl RowUnroll {
    /// The value of `RTMPM_P2G_UNROLL` (`kernels/p2g/warp.cuh`).
    pub fn define(self) -> u32 {
        match self {
            RowUnroll::Off => 0,
            RowUnroll::Planes => 2,
            RowUnroll::All => 1,
        }
    }
}

/// Default of [`crate::options::CudaOptions::sort_scratch_fields`]: 4 words per particle of scratch instead of
/// 29 (f32: 16 instead of 116 bytes), for 8 passes of the sort's scatter and copy back.
pub const DEFAULT_SORT_SCRATCH_FIELDS: usize = 4;
