//! The kernel switches' own types: the P2G strategy, CK-MPM's P2G kernel, the instruction cuts
//! and the row unrolling of the fused kernels (resolved per kernel set: [`FusedSwitches`]), and
//! the defaults of the capacities they use.

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
/// zero_terms=skip,flat_checks=on`), each a compile-time define of the kernels, off unless given
/// or given by the kernel set (bench/RESULTS.md, "Fewer instructions, second round"; per kernel
/// set with `fused_defaults=auto`, the default: [`FusedSwitches`]).
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

/// The warp scatter's row loop (`row_unroll=off|planes|all`, [`FusedSwitches::row_unroll`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
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

/// The kernel set a backend compiles, as far as the fused kernels' code switches go
/// ([`FusedSwitches::resolve`]): one program per backend, whose fused G2P2G kernel is
/// `g2p2g_fluid` when every material is a fluid, `g2p2g` otherwise.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum KernelSet {
    /// Every material a fluid and the MLS-MPM transfer: the fluid kernels (`g2p2g_fluid`; the
    /// fluid dam's, the water scenes').
    Fluid,
    /// Every other scene: the general kernels (`g2p2g`; jelly, snow, mixed scenes, and CK-MPM
    /// and classic-MPM transfers whatever the materials).
    General,
}

impl KernelSet {
    /// The kernel set of a backend whose materials are all fluids (`all_fluid`) and whose
    /// transfer is `transfer`.
    pub fn of(all_fluid: bool, transfer: rtmpm_physics::transfer::Transfer) -> KernelSet {
        if all_fluid && transfer == rtmpm_physics::transfer::Transfer::Mls {
            KernelSet::Fluid
        } else {
            KernelSet::General
        }
    }
}

/// What the fused kernels' code switches that `--cuda-options` leaves unset become
/// (`fused_defaults=off|auto`, [`FusedSwitches::defaults`]); a switch given explicitly applies to
/// every kernel set whatever this says.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum FusedDefaults {
    /// Today's code in every kernel set: the row loop and no cut ([`FusedCode::default`]).
    #[default]
    Off,
    /// Per kernel set, the combination that was fastest on an H200 (bench/RESULTS.md, "Fewer
    /// instructions in the fused kernels, second round"): the fluid set
    /// [`FusedCode::FLUID_TUNED`] (`row_unroll=planes,seg_clamp=on,zero_terms=skip,
    /// flat_checks=on,state_index=wide`, -2.2 % on the fluid dam 2M), the general set today's
    /// code (every combination lost on the jelly and the snow, whose spills it raised).
    Auto,
}

impl FusedDefaults {
    /// The name used by `--cuda-options fused_defaults=NAME`.
    pub fn name(self) -> &'static str {
        match self {
            FusedDefaults::Off => "off",
            FusedDefaults::Auto => "auto",
        }
    }
}

/// The default of [`FusedSwitches::defaults`]: `Auto`, timed against `Off` in one binary on an
/// H200 (the fluid dam 2M -2.7 %, the jelly and the snow the same program; bench/RESULTS.md).
pub const DEFAULT_FUSED_DEFAULTS: FusedDefaults = FusedDefaults::Auto;

/// The fused kernels' code switches of one kernel set, resolved: the compile-time defines of
/// the program ([`crate::compile::KernelOptions`]'s `row_unroll`, `cuts` and `state64`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct FusedCode {
    /// The warp scatter's rows (`row_unroll`).
    pub row_unroll: RowUnroll,
    /// The instruction cuts (`lean_lanes`, `seg_clamp`, `zero_terms`, `flat_checks`).
    pub cuts: KernelCuts,
    /// The particle state's word index in 64 bits always (`state_index=wide`).
    pub wide_state_index: bool,
}

impl FusedCode {
    /// `fused_defaults=auto`'s code of the fluid kernel set: the three rows of a plane unrolled,
    /// `seg_clamp`, `zero_terms=skip`, `flat_checks` and the wide state index (not
    /// `lean_lanes`, which lost 2.4 % there).
    pub const FLUID_TUNED: FusedCode = FusedCode {
        row_unroll: RowUnroll::Planes,
        cuts: KernelCuts {
            lean_lanes: false,
            seg_clamp: true,
            zero_terms: true,
            flat_checks: true,
        },
        wide_state_index: true,
    };
}

/// The fused kernels' code switches as asked on the command line (`row_unroll`, `lean_lanes`,
/// `seg_clamp`, `zero_terms`, `flat_checks`, `state_index`): each one given applies to every
/// kernel set; each one left out (`None`) takes the value [`FusedSwitches::defaults`] gives it
/// for the backend's kernel set ([`KernelSet`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FusedSwitches {
    /// What the switches left out become (`fused_defaults=off|auto`; default
    /// [`DEFAULT_FUSED_DEFAULTS`]).
    pub defaults: FusedDefaults,
    /// `row_unroll=off|planes|all`.
    pub row_unroll: Option<RowUnroll>,
    /// `lean_lanes=on|off` ([`KernelCuts::lean_lanes`]).
    pub lean_lanes: Option<bool>,
    /// `seg_clamp=on|off` ([`KernelCuts::seg_clamp`]).
    pub seg_clamp: Option<bool>,
    /// `zero_terms=skip|keep` ([`KernelCuts::zero_terms`]).
    pub zero_terms: Option<bool>,
    /// `flat_checks=on|off` ([`KernelCuts::flat_checks`]).
    pub flat_checks: Option<bool>,
    /// `state_index=wide|auto` (`auto`, the name it had before the kernel sets: 32 bits unless
    /// the arrays hold 2^32 words or more; [`crate::CudaOptions::fused`]).
    pub wide_state_index: Option<bool>,
}

impl Default for FusedSwitches {
    fn default() -> Self {
        FusedSwitches {
            defaults: DEFAULT_FUSED_DEFAULTS,
            row_unroll: None,
            lean_lanes: None,
            seg_clamp: None,
            zero_terms: None,
            flat_checks: None,
            wide_state_index: None,
        }
    }
}

impl FusedSwitches {
    /// `code` for every kernel set, every switch given (tests and comparisons).
    pub fn all(code: FusedCode) -> FusedSwitches {
        let c = code.cuts;
        FusedSwitches {
            defaults: DEFAULT_FUSED_DEFAULTS,
            row_unroll: Some(code.row_unroll),
            lean_lanes: Some(c.lean_lanes),
            seg_clamp: Some(c.seg_clamp),
            zero_terms: Some(c.zero_terms),
            flat_checks: Some(c.flat_checks),
            wide_state_index: Some(code.wide_state_index),
        }
    }

    /// The code of kernel set `set`: each switch as given, else as [`FusedSwitches::defaults`]
    /// sets it for `set`.
    pub fn resolve(&self, set: KernelSet) -> FusedCode {
        let d = match (self.defaults, set) {
            (FusedDefaults::Auto, KernelSet::Fluid) => FusedCode::FLUID_TUNED,
            _ => FusedCode::default(),
        };
        FusedCode {
            row_unroll: self.row_unroll.unwrap_or(d.row_unroll),
            cuts: KernelCuts {
                lean_lanes: self.lean_lanes.unwrap_or(d.cuts.lean_lanes),
                seg_clamp: self.seg_clamp.unwrap_or(d.cuts.seg_clamp),
                zero_terms: self.zero_terms.unwrap_or(d.cuts.zero_terms),
                flat_checks: self.flat_checks.unwrap_or(d.cuts.flat_checks),
            },
            wide_state_index: self.wide_state_index.unwrap_or(d.wide_state_index),
        }
    }
}

/// Default of [`crate::options::CudaOptions::sort_scratch_fields`]: 4 words per particle of scratch instead of
/// 29 (f32: 16 instead of 116 bytes), for 8 passes of the sort's scatter and copy back.
pub const DEFAULT_SORT_SCRATCH_FIELDS: usize = 4;
