//! `#[repr(C)]` mirrors of the device structures in `kernels/common.cuh`.

/// Maximum number of colliders (`RTMPM_MAX_COLLIDERS`).
pub const MAX_COLLIDERS: usize = 16;
/// Maximum number of materials (`RTMPM_MAX_MATERIALS`, the constant-memory table).
pub const MAX_MATERIALS: usize = 64;
/// 32-bit fields per particle in the state arrays (`RTMPM_NFIELDS`).
pub const NFIELDS: usize = 29;
/// Field offsets (see `common.cuh`): x, v, C, F (column-major), plastic, mass, vol0,
/// material (u32 bits), original index (u32 bits).
pub const F_X: usize = 0;
/// Velocity.
pub const F_V: usize = 3;
/// APIC C.
pub const F_C: usize = 6;
/// Deformation gradient.
pub const F_F: usize = 15;
/// Plastic scalar.
pub const F_PLASTIC: usize = 24;
/// Mass.
pub const F_MASS: usize = 25;
/// Initial volume.
pub const F_VOL0: usize = 26;
/// Material id (bits).
pub const F_MAT: usize = 27;
/// Original particle index (bits).
pub const F_ID: usize = 28;
/// Control words: rebuild the mapping at the next step.
pub const CTL_NEED_REBUILD: usize = 0;
/// Gblock count.
pub const CTL_GBLOCKS: usize = 1;
/// Pblock count.
pub const CTL_PBLOCKS: usize = 2;
/// Error bits.
pub const CTL_ERROR: usize = 3;
/// First bad particle.
pub const CTL_BAD_INDEX: usize = 4;
/// Its reason (1 non-finite, 2 too fast).
pub const CTL_BAD_REASON: usize = 5;
/// Max speed (f32 bits).
pub const CTL_MAX_SPEED: usize = 6;
/// Rebuild count.
pub const CTL_REBUILDS: usize = 7;
/// Warp count.
pub const CTL_WARPS: usize = 8;
/// 1 when the mapping was rebuilt in this step (multi-GPU: the occupancy mask is redone).
pub const CTL_REBUILT_NOW: usize = 11;
/// Number of blocks shared with other GPUs (multi-GPU).
pub const CTL_SHARED: usize = 12;
/// Capacity of the shared-block reduction (blocks; multi-GPU).
pub const CTL_SHARED_CAP: usize = 13;
/// Grid barrier of the fused rebuild (`rb_fused`): blocks arrived, generation.
pub const CTL_BARRIER_COUNT: usize = 14;
/// See [`CTL_BARRIER_COUNT`].
pub const CTL_BARRIER_GEN: usize = 15;
/// Number of control words.
/// G2P2G: the grid of the coming step still needs its P2G (set by the host: first step, new dt).
pub const CTL_P2G_PENDING: usize = 16;
pub const CTL_WORDS: usize = 17;

/// Material parameters on the device: the mirror of `MaterialGpu` in
/// kernels/material/materials.cuh, with `R` the kernels' `real`: f32 (88 bytes, every field 4
/// bytes, no padding) or f64 (176 bytes, C padding after each i32). Only the parameters of the
/// model selected by `kind` are read.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct GpuMaterial<R = f32> {
    /// Model, in the order of `rtmpm_core::material::Model`: 0 fluid, 1 fixed corotated,
    /// 2 neo-Hookean, 3 snow, 4 Drucker-Prager, 5 von Mises.
    pub kind: i32,
    /// Fluid: bulk modulus.
    pub fluid_bulk_modulus: R,
    /// Fluid: 0 linear, 1 Tait.
    pub fluid_eos: i32,
    pub fluid_gamma: R,
    pub fluid_viscosity: R,
    /// Fixed corotated: mu, lambda.
    pub fixed_corotated: [R; 2],
    /// Neo-Hookean: mu, lambda.
    pub neo_hookean: [R; 2],
    /// Snow: mu, lambda, critical compression, critical stretch, hardening.
    pub snow: [R; 5],
    /// Drucker-Prager: mu, lambda, friction angle (degrees), cohesion.
    pub drucker_prager: [R; 4],
    /// von Mises: mu, lambda, yield stress, hardening modulus.
    pub von_mises: [R; 4],
}

const _: () = assert!(std::mem::size_of::<GpuMaterial>() == 88);
const _: () = assert!(std::mem::size_of::<GpuMaterial<f64>>() == 176);

impl GpuMaterial<f32> {
    /// The same parameters for kernels compiled with `RTMPM_F64` (exact widening).
    pub fn to_f64(&self) -> GpuMaterial<f64> {
        GpuMaterial {
            kind: self.kind,
            fluid_bulk_modulus: self.fluid_bulk_modulus.into(),
            fluid_eos: self.fluid_eos,
            fluid_gamma: self.fluid_gamma.into(),
            fluid_viscosity: self.fluid_viscosity.into(),
            fixed_corotated: self.fixed_corotated.map(f64::from),
            neo_hookean: self.neo_hookean.map(f64::from),
            snow: self.snow.map(f64::from),
            drucker_prager: self.drucker_prager.map(f64::from),
            von_mises: self.von_mises.map(f64::from),
        }
    }
}

/// Collider on the device.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct GpuCollider {
    /// 0 half-space, 1 box, 2 sphere, 3 cylinder, 4 mesh.
    pub kind: u32,
    /// 0 sticky, 1 slip, 2 separate.
    pub cond: u32,
    /// Coulomb friction.
    pub friction: f32,
    /// Offset of the mesh SDF in the concatenated values.
    pub mesh_offset: u32,
    /// Linear velocity.
    pub velocity: [f32; 3],
    /// Angular velocity.
    pub angular_velocity: [f32; 3],
    /// Pivot at t = 0.
    pub pivot: [f32; 3],
    /// Shape parameters.
    pub p: [f32; 8],
    /// Mesh grid dims.
    pub dims: [u32; 3],
    /// Padding.
    pub pad: u32,
}

/// Per-step parameters, copied to the device before each step.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StepParams {
    /// Time step.
    pub dt: f32,
    /// Time at the start of the step.
    pub t: f32,
    /// Gravity.
    pub gravity: [f32; 3],
    /// Force a rebuild this step (free zone off).
    pub always_rebuild: u32,
    /// Settling damping factor on the grid velocities this step (1 = off), from
    /// `rtmpm_core::scene::Damping::factor`.
    pub damping: f32,
    /// Padding.
    pub pad: [u32; 1],
    /// Collider rotations (rest to world) at t, column-major.
    pub rot: [[f32; 9]; MAX_COLLIDERS],
    /// Collider pivots at t.
    pub pivot_t: [[f32; 3]; MAX_COLLIDERS],
    /// `dt` and `gravity` in f64, read instead of the f32 ones by kernels compiled with
    /// `RTMPM_F64`.
    pub dt_f64: f64,
    /// See `dt_f64`.
    pub gravity_f64: [f64; 3],
}

/// Kernel context passed by value to every kernel.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct Ctx {
    pub state: u64,
    pub scratch: u64,
    pub grid: u64,
    pub ctl: u64,
    pub step: u64,
    pub materials: u64,
    pub colliders: u64,
    pub mesh_values: u64,
    pub hash_keys: u64,
    pub hash_values: u64,
    pub block_coords: u64,
    pub neighbors: u64,
    pub hist: u64,
    pub scan_sums: u64,
    pub pkey: u64,
    pub prank: u64,
    pub warps: u64,
    /// Second value per node for the classic MPM transfers (0 for MLS).
    pub grid_aux: u64,
    /// Per gblock: 1 when one of its 27 neighbours is shared with another GPU (multi-GPU).
    pub boundary: u64,
    pub origin: [f32; 3],
    pub dx: f32,
    pub inv_dx: f32,
    pub domain_min: [f32; 3],
    pub domain_max: [f32; 3],
    pub n_cells: [i32; 3],
    pub wall_thickness: i32,
    pub wall_cond: [u32; 6],
    pub wall_friction: [f32; 6],
    pub n: u32,
    pub cap: u32,
    pub gblock_cap: u32,
    pub pblock_cap: u32,
    pub hash_cap: u32,
    pub warp_cap: u32,
    pub n_colliders: u32,
    pub n_buckets: u32,
    pub warp_reduce: u32,
    pub warp_sort: u32,
    /// `rtmpm_core::transfer::Transfer::code` (`TRANSFER_*` in shape.cuh).
    pub transfer: u32,
    /// 0 USL, 1 MUSL.
    pub update: u32,
    /// FLIP fraction.
    pub flip: f32,
    /// G2P2G: the grid the fused kernel scatters the next step into (0: no G2P2G).
    pub grid_next: u64,
    /// The geometry in f64, read instead of the f32 fields above by kernels compiled with
    /// `RTMPM_F64` (`common.cuh` swaps the names).
    pub origin_f64: [f64; 3],
    /// See `origin_f64`.
    pub dx_f64: f64,
    /// See `origin_f64`.
    pub inv_dx_f64: f64,
    /// See `origin_f64`.
    pub domain_min_f64: [f64; 3],
    /// See `origin_f64`.
    pub domain_max_f64: [f64; 3],
    /// See `origin_f64`.
    pub wall_friction_f64: [f64; 6],
}

// One layout for both precisions, checked on both sides (`common.cuh` asserts the same sizes).
const _: () = assert!(std::mem::size_of::<Ctx>() == 456);
const _: () = assert!(std::mem::size_of::<StepParams>() == 832);

// SAFETY: plain old data with the C layout of the kernel structs.
unsafe impl cudarc::driver::DeviceRepr for Ctx {}

/// View a slice of plain-old-data as bytes.
pub fn as_bytes<T: Copy>(v: &[T]) -> &[u8] {
    // SAFETY: T is Copy plain data without padding-dependent invariants; reading bytes is fine.
    unsafe { std::slice::from_raw_parts(v.as_ptr() as *const u8, std::mem::size_of_val(v)) }
}
