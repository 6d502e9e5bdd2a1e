//! Particle-grid transfer schemes, chosen per scene in the `[solver]` table
//! (`docs/scene-format.md`).
//!
//! * [`Transfer::Mls`]: MLS-MPM with APIC (quadratic B-splines; Hu et al. 2018, Jiang et al.
//!   2015), the default. The stress enters P2G as part of the affine momentum; `C` is APIC's
//!   affine matrix.
//! * [`Transfer::Gimp`]: uGIMP (Bardenhagen & Kober 2004) with a particle half-size of dx/4 (the
//!   particle domain of 2 x 2 x 2 particles per cell), so that its support stays inside the same
//!   3x3x3 node stencil as the quadratic B-spline.
//! * [`Transfer::MpmLinear`]: classic MPM with linear hat functions (Sulsky et al. 1994).
//! * [`Transfer::CkMpm`] (experimental; the CUDA backend on one GPU only): the compact C2 kernel
//!   on two staggered grids with MLS-MPM/APIC (Liu, Wang & Li, "CK-MPM: A Compact-Kernel Material
//!   Point Method", ACM TOG 2025); see [`crate::compact_kernel`].
//!
//! Gimp and MpmLinear are the classic explicit MPM transfers: P2G of mass, momentum and internal
//! force `f_i = -sum_p V0_p tau_p grad w_ip`, a PIC/FLIP blend of the particle velocity, the
//! velocity gradient `L_p = sum_i v_i (x) grad w_ip` kept in the particle's `C`, and either the
//! USL or the MUSL stress update ([`Update`]).

/// The particle-grid transfer and its shape functions.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Transfer {
    /// MLS-MPM / APIC, quadratic B-splines (the default).
    #[default]
    Mls,
    /// uGIMP, particle half-size dx/4, PIC/FLIP velocity update.
    Gimp,
    /// Classic MPM, linear hat functions, PIC/FLIP velocity update.
    MpmLinear,
    /// CK-MPM: the compact kernel on two staggered grids, MLS-MPM/APIC (experimental; the CUDA
    /// backend runs it on one GPU only).
    CkMpm,
}

impl Transfer {
    /// The name used in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Transfer::Mls => "mls",
            Transfer::Gimp => "gimp",
            Transfer::MpmLinear => "mpm-linear",
            Transfer::CkMpm => "ck-mpm",
        }
    }

    /// Code passed to the CUDA kernels (`TRANSFER_*` of the generated `contract.cuh`).
    pub fn code(self) -> u32 {
        match self {
            Transfer::Mls => 0,
            Transfer::Gimp => 1,
            Transfer::MpmLinear => 2,
            Transfer::CkMpm => 3,
        }
    }

    /// Whether the transfer is MLS-MPM/APIC (stress folded into P2G, no PIC/FLIP blend, USL
    /// only): [`Transfer::Mls`] and [`Transfer::CkMpm`].
    pub fn is_apic(self) -> bool {
        matches!(self, Transfer::Mls | Transfer::CkMpm)
    }
}

/// When the deformation gradient (hence the stress) is updated in the classic MPM transfers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Update {
    /// Update stress last: the velocity gradient comes from the grid velocities of this step's
    /// grid update (Bardenhagen 2002).
    #[default]
    Usl,
    /// Modified USL (Sulsky et al. 1995): the updated particle momenta are mapped to the grid
    /// again (with the boundary conditions), and the velocity gradient comes from that grid.
    Musl,
}

impl Update {
    /// The name used in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Update::Usl => "usl",
            Update::Musl => "musl",
        }
    }
}

/// The `[solver]` settings of a scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolverSettings {
    pub transfer: Transfer,
    /// Ignored (always USL) for [`Transfer::Mls`] and [`Transfer::CkMpm`].
    pub update: Update,
    /// FLIP fraction alpha of the particle velocity update
    /// `v_p = (1 - alpha) v_PIC + alpha (v_p + sum_i w_ip (v_i - v_i_old))`; 0 for MLS and
    /// CK-MPM.
    pub flip: f32,
}

impl Default for SolverSettings {
    /// MLS-MPM / APIC.
    fn default() -> Self {
        SolverSettings {
            transfer: Transfer::Mls,
            update: Update::Usl,
            flip: 0.0,
        }
    }
}

impl SolverSettings {
    /// One line for summaries, e.g. `gimp, musl, flip 0.99`.
    pub fn describe(&self) -> String {
        match self.transfer {
            Transfer::Mls => "mls (APIC)".into(),
            Transfer::CkMpm => "ck-mpm (APIC, dual grid)".into(),
            t => format!("{}, {}, flip {}", t.name(), self.update.name(), self.flip),
        }
    }
}
