//! The structs copied to the GPU, each the twin of a C struct of the kernels (field offsets
//! checked by [`super::layout_asserts`]).

use super::constants::{MATERIAL_PARAMS, MAX_COLLIDERS, MAX_PEER_GPUS, REDO_RANGES};
use bytemuck::{Pod, Zeroable};
use std::mem::size_of;

// Structs.

/// A floating-point type of the kernels' `real` (f32, or f64 with `RTMPM_F64`).
pub trait GpuReal:
    Pod
    + Default
    + Copy
    + std::fmt::Debug
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
    + 'static
{
    /// From an f32 scene value (exact).
    fn from_f32(x: f32) -> Self;
    /// From an f64 value (rounded for f32).
    fn from_f64(x: f64) -> Self;
}
impl GpuReal for f32 {
    fn from_f32(x: f32) -> Self {
        x
    }
    fn from_f64(x: f64) -> Self {
        x as f32
    }
}
impl GpuReal for f64 {
    fn from_f32(x: f32) -> Self {
        x as f64
    }
    fn from_f64(x: f64) -> Self {
        x
    }
}

/// Kernel context, passed by value to every kernel: device pointers, capacities and codes; no
/// precision-dependent value (those are in [`Scalars`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct Ctx {
    /// The state layout's words (`StateLayout::words`) per particle slot.
    pub state: u64,
    /// The rebuild's sort scratch: `CudaOptions::sort_scratch_fields` reals per particle slot
    /// (the state is permuted that many fields at a time).
    pub scratch: u64,
    /// 4 reals per node: mass, momentum (velocity after the grid update).
    pub grid: u64,
    /// G2P2G: the grid the fused kernel scatters the next step into (0: no G2P2G).
    pub grid_next: u64,
    /// Classic MPM transfers and CK-MPM (0 for MLS): 4 reals per node: unused, dt f_i after
    /// P2G, v_old after the grid update, MUSL re-mapped v; CK-MPM: its second grid's nodes
    /// (mass, momentum, then velocity).
    pub grid_aux: u64,
    /// CK-MPM with G2P2G: the second grid the fused kernel scatters the next step into (in the
    /// allocation of `grid_next`, after its first grid; 0 otherwise).
    pub grid_aux_next: u64,
    /// `CTL_WORDS` control words.
    pub ctl: u64,
    /// Global copies of the constant-memory parameters (read with `-DRTMPM_PARAMS_GLOBAL`).
    pub scalars: u64,
    /// See `scalars`.
    pub step: u64,
    /// See `scalars`.
    pub poses: u64,
    /// See `scalars`.
    pub materials: u64,
    /// See `scalars`.
    pub colliders: u64,
    /// Values of every mesh collider's signed distance grid (f32).
    pub mesh_values: u64,
    /// Block hash: keys (u64 block codes).
    pub hash_keys: u64,
    /// Block hash: values (dense ids).
    pub hash_values: u64,
    /// 3 ints per pblock.
    pub block_coords: u64,
    /// 27 pblock ids per gblock.
    pub neighbors: u64,
    /// `n_buckets` counts / offsets of the sort.
    pub hist: u64,
    /// Block sums of the scan.
    pub scan_sums: u64,
    /// Per particle: its bucket (the scratch's first field, free until the sort's scatter).
    pub pkey: u64,
    /// Per particle: its rank in the bucket, then its sorted slot.
    pub prank: u64,
    /// 3 words per warp: gblock, first particle, count.
    pub warps: u64,
    /// Per gblock: 1 when one of its 27 neighbours is shared with another GPU.
    pub boundary: u64,
    /// Per pblock: 1 when it is shared with another GPU (its grid update waits for the sum).
    pub shared_pblock: u64,
    /// Global copy of the rigid bodies' states (`c_bodies`, see `scalars`).
    pub bodies: u64,
    /// Rigid bodies: f64 impulse (3) and angular impulse (3) per body, in
    /// `BODY_EXCHANGE_SLOTS` copies summed by the host (`crate::step::rigid`).
    pub body_exchange: u64,
    /// Global copy of the user's tool (`c_tool`, see `scalars`).
    pub tool: u64,
    /// Cells of the domain per axis.
    pub n_cells: [i32; 3],
    /// Wall thickness (cells).
    pub wall_thickness: i32,
    /// Wall conditions (x min, x max, y min, ...).
    pub wall_cond: [u32; 6],
    /// Particles on this GPU.
    pub n: u32,
    /// Particle capacity (the state arrays' stride).
    pub cap: u32,
    /// Capacities of the mapping.
    pub gblock_cap: u32,
    /// See `gblock_cap`.
    pub pblock_cap: u32,
    /// See `gblock_cap`.
    pub hash_cap: u32,
    /// See `gblock_cap`.
    pub warp_cap: u32,
    /// Colliders in the tables.
    pub n_colliders: u32,
    /// Buckets of the sort (`gblock_cap * 64 + 1`).
    pub n_buckets: u32,
    /// Warp-level reduction in P2G.
    pub warp_reduce: u32,
    /// In-warp cell sort (mixed sorting).
    pub warp_sort: u32,
    /// `Transfer::code`.
    pub transfer: u32,
    /// [`update`] code.
    pub update: u32,
    /// Rebuild the mapping every step (free zone or mixed sorting off).
    pub always_rebuild: u32,
    /// Rigid bodies coupled in the grid update (`[[rigid_body]]`).
    pub n_bodies: u32,
}

// SAFETY: Pod, passed by value with the C layout the kernels declare (checked by layout_asserts).
unsafe impl cudarc::driver::DeviceRepr for Ctx {}

/// The precision-dependent constants of a run (constant memory `c_scalars`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct Scalars<R> {
    /// Grid origin: the domain minimum minus 4 cells.
    pub origin: [R; 3],
    /// Cell size.
    pub dx: R,
    /// 1 / dx.
    pub inv_dx: R,
    /// Domain (particles are clamped into it).
    pub domain_min: [R; 3],
    /// See `domain_min`.
    pub domain_max: [R; 3],
    /// Coulomb friction of each wall.
    pub wall_friction: [R; 6],
    /// FLIP fraction of the classic transfers.
    pub flip: R,
}

/// Parameters of one step (constant memory `c_step`, uploaded when they change).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepParams<R> {
    /// Time step.
    pub dt: R,
    /// Time at the start of the step (no kernel reads it; uploads compare without it).
    pub t: R,
    /// Gravity.
    pub gravity: [R; 3],
    /// Settling damping factor on the grid velocities (1 = off).
    pub damping: R,
}

/// One material: its model's parameters (`Model::gpu_params`, in the order of the model's
/// generated `<Name>Params` struct) and its kind code (`Model::code`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct MaterialGpu<R> {
    /// Parameters; the unused tail is zero.
    pub p: [R; MATERIAL_PARAMS],
    /// Kind code.
    pub kind: u32,
    /// Padding to the real's alignment.
    pub pad: u32,
}

// Proof of no padding for both precisions: every field's bytes add up to the struct's size.
const _: () = {
    assert!(size_of::<Scalars<f32>>() == 18 * 4 && size_of::<Scalars<f64>>() == 18 * 8);
    assert!(size_of::<StepParams<f32>>() == 6 * 4 && size_of::<StepParams<f64>>() == 6 * 8);
    assert!(size_of::<MaterialGpu<f32>>() == MATERIAL_PARAMS * 4 + 8);
    assert!(size_of::<MaterialGpu<f64>>() == MATERIAL_PARAMS * 8 + 8);
};
// SAFETY: repr(C), every field Pod, and no padding (asserted above) for both instantiations.
unsafe impl Zeroable for Scalars<f32> {}
unsafe impl Pod for Scalars<f32> {}
unsafe impl Zeroable for Scalars<f64> {}
unsafe impl Pod for Scalars<f64> {}
unsafe impl Zeroable for StepParams<f32> {}
unsafe impl Pod for StepParams<f32> {}
unsafe impl Zeroable for StepParams<f64> {}
unsafe impl Pod for StepParams<f64> {}
unsafe impl Zeroable for MaterialGpu<f32> {}
unsafe impl Pod for MaterialGpu<f32> {}
unsafe impl Zeroable for MaterialGpu<f64> {}
unsafe impl Pod for MaterialGpu<f64> {}

/// The pose of every collider at the step's time (constant memory `c_poses`; geometry is f32
/// in both precisions, as on the CPU).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct ColliderPoses {
    /// Rest-to-world rotation at t, column-major.
    pub rot: [[f32; 9]; MAX_COLLIDERS],
    /// Pivot at t.
    pub pivot: [[f32; 3]; MAX_COLLIDERS],
    /// Linear velocity of the pivot at t (constant, or from the keyframes).
    pub velocity: [[f32; 3]; MAX_COLLIDERS],
    /// Angular velocity at t (rad/s, world frame).
    pub omega: [[f32; 3]; MAX_COLLIDERS],
}

impl Default for ColliderPoses {
    fn default() -> Self {
        Zeroable::zeroed()
    }
}

/// One collider's pose and velocity at the step's time, as a row of a batch's per-world table
/// (`c_batch.poses`, `worlds x n_colliders` rows: [`crate::batch`]); the fields of one collider
/// of [`ColliderPoses`] (`crate::encode::collider_pose`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuColliderPose {
    /// Rest-to-world rotation at t, column-major.
    pub rot: [f32; 9],
    /// Pivot at t.
    pub pivot: [f32; 3],
    /// Linear velocity of the pivot at t.
    pub velocity: [f32; 3],
    /// Angular velocity at t (rad/s, world frame).
    pub omega: [f32; 3],
}

/// A collider (constant memory `c_colliders`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuCollider {
    /// [`collider_kind`].
    pub kind: u32,
    /// [`condition`].
    pub cond: u32,
    /// Coulomb friction.
    pub friction: f32,
    /// Offset of the mesh SDF in the concatenated values.
    pub mesh_offset: u32,
    /// Pivot in the rest pose (the velocities are in [`ColliderPoses`]).
    pub pivot: [f32; 3],
    /// Shape parameters in the rest pose.
    pub p: [f32; 8],
    /// Mesh grid dims.
    pub dims: [u32; 3],
    /// Padding.
    pub pad: u32,
}

/// A rigid body at the step's time (constant memory `c_bodies`, written before every step):
/// its shape about its centre of mass as a collider shape in the rest pose (pivot 0), its
/// boundary rule, pose and velocities (`rtmpm_rigid::BodyState`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuBody {
    /// Shape (`kind`, `p`), boundary rule (`cond`, `friction`) in the body frame.
    pub shape: GpuCollider,
    /// Rest-to-world rotation, column-major.
    pub rot: [f32; 9],
    /// Centre of mass (m).
    pub center: [f32; 3],
    /// Linear velocity of the centre (m/s).
    pub velocity: [f32; 3],
    /// Angular velocity (rad/s, world frame).
    pub omega: [f32; 3],
    /// Radius of a sphere about the centre that holds the body (a quick rejection).
    pub bound: f32,
    /// 1 when the material's impulses move the body (in the host's rapier world). The kernels
    /// do not read it: they sum every body's reaction, a kinematic or fixed body's being its
    /// load (`kernels/grid_update.cu`: `couple_body`).
    pub dynamic: u32,
}

/// The user's tool (a live view's drag, `rtmpm_geometry::Tool`; constant memory `c_tool`,
/// written when it changes): a separating collider moving at `velocity`, its shape in world
/// coordinates (pivot 0, not rotated), applied in the grid update after the scene's colliders.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuTool {
    /// Shape (`kind`: sphere or box, `p`), rule (`cond`: separate, `friction`).
    pub shape: GpuCollider,
    /// Velocity of the tool (m/s).
    pub velocity: [f32; 3],
    /// 1 when there is a tool (0: the grid update skips it).
    pub active: u32,
}

/// Several GPUs: the buffers of the shared-block reduction (`kernels/multi/reduce_shared.cu`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct SharedCtx {
    /// u8 per dense block + 1: this GPU's pblocks; last byte: rebuilt this step.
    pub mask: u64,
    /// u8 per dense block + 1: the masks summed over the GPUs.
    pub counts: u64,
    /// u32 per chunk of 1024 dense blocks.
    pub chunk: u64,
    /// u32 per shared block: this GPU's pblock id.
    pub shared_local: u64,
    /// 256 reals per shared block.
    pub buf: u64,
    /// u8 per shared block (`exchange=push`, else null): bit g set when GPU g holds it.
    pub holders: u64,
    /// Dense block array dimensions.
    pub dims: [i32; 3],
    /// Number of dense blocks.
    pub d: u32,
    /// Shared blocks the reduction holds.
    pub cap: u32,
    /// Padding.
    pub pad: u32,
}

// SAFETY: Pod, passed by value with the C layout the kernels declare.
unsafe impl cudarc::driver::DeviceRepr for SharedCtx {}

/// transport=p2p: every GPU's mask and packed buffer (this GPU's included, rank order), as
/// pointers this GPU can dereference through peer access.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct PeerCtx {
    /// `SharedCtx::mask` of every GPU.
    pub mask: [u64; MAX_PEER_GPUS],
    /// `SharedCtx::buf` of every GPU.
    pub buf: [u64; MAX_PEER_GPUS],
    /// Number of GPUs.
    pub n: u32,
    /// This GPU's rank.
    pub me: u32,
}

// SAFETY: Pod, passed by value with the C layout the kernels declare.
unsafe impl cudarc::driver::DeviceRepr for PeerCtx {}

/// `exchange=push` (transport=p2p): every GPU's inbox and arrival counter (this GPU's
/// included, rank order) as pointers this GPU can dereference, and this GPU's own counters
/// (`kernels/multi/reduce_shared.cu`, `sb_push` and `sb_gather`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct PushCtx {
    /// Every GPU's inbox: 2 x GPUs x capacity x 256 reals.
    pub inbox: [u64; MAX_PEER_GPUS],
    /// Every GPU's arrival counter (u64, in that GPU's memory).
    pub arrivals: [u64; MAX_PEER_GPUS],
    /// This GPU's exchange count (u64).
    pub calls: u64,
    /// This GPU's count of `sb_push` blocks done (u32).
    pub done: u64,
    /// Nanoseconds a GPU waits for the others before it reports the barrier timed out.
    pub timeout_ns: u64,
    /// Number of GPUs.
    pub n: u32,
    /// This GPU's rank.
    pub me: u32,
}

// SAFETY: Pod, passed by value with the C layout the kernels declare.
unsafe impl cudarc::driver::DeviceRepr for PushCtx {}

/// The spin-lock barrier between GPUs of Fei, Huang & Gao, "Real-Time Simulation of MPM on
/// Modern GPUs" (GTC 2022) (`kernels/multi/barrier.cu`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct SpinBarrier {
    /// u64 on GPU 0: arrivals so far.
    pub count: u64,
    /// u64 on this GPU: this GPU's barrier calls so far.
    pub calls: u64,
    /// A GPU waiting longer than this sets `ERR_BARRIER` and goes on.
    pub timeout_ns: u64,
    /// Number of GPUs.
    pub n: u32,
    /// Padding.
    pub pad: u32,
}

// SAFETY: Pod, passed by value with the C layout the kernels declare.
unsafe impl cudarc::driver::DeviceRepr for SpinBarrier {}

/// The worlds of a batch whose P2G is redone (`redo_clear`, `redo_p2g` and their `_lanes` forms in
/// `kernels/redo.cu`;
/// `crate::batch::CudaBatch::redo_puts`): `count` runs of consecutive worlds, run `i` the
/// worlds `lo[i]..hi[i]`. Passed by value (260 bytes of kernel arguments).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
pub struct RedoWorlds {
    /// Runs in use (at most [`REDO_RANGES`]).
    pub count: u32,
    /// First world of each run.
    pub lo: [u32; REDO_RANGES],
    /// One past the last world of each run.
    pub hi: [u32; REDO_RANGES],
}

impl Default for RedoWorlds {
    fn default() -> Self {
        bytemuck::Zeroable::zeroed()
    }
}

// SAFETY: Pod, passed by value with the C layout the kernels declare.
unsafe impl cudarc::driver::DeviceRepr for RedoWorlds {}

/// `p2g=reverse_map`: the replicated node-to-particle maps (`kernels/p2g/reverse_map.cu`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct RmapCtx {
    /// 27 x cap entries of 4 reals.
    pub contrib: u64,
    /// replicas x node_cap counters.
    pub counts: u64,
    /// replicas x slots x node_cap entries.
    pub entries: u64,
    /// Nodes covered (64 per pblock).
    pub node_cap: u32,
    /// Independent maps.
    pub replicas: u32,
    /// Entries per node and map.
    pub slots: u32,
    /// Padding.
    pub pad: u32,
}

// SAFETY: Pod, passed by value with the C layout the kernels declare.
unsafe impl cudarc::driver::DeviceRepr for RmapCtx {}

/// `p2g=sort`: the buffers of the per-step sort of the contributions (`kernels/p2g/sort.cu`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct SortCtx {
    /// 27 x cap entries of 4 reals.
    pub contrib: u64,
    /// Ping-pong keys, n_items each.
    pub keys: [u64; 2],
    /// Ping-pong values.
    pub vals: [u64; 2],
    /// Digits x tiles counts.
    pub tile_counts: u64,
    /// Block sums of their scan.
    pub scan_sums: u64,
    /// Per node: first entry.
    pub seg_start: u64,
    /// Per node: end of its entries.
    pub seg_end: u64,
    /// 27 n.
    pub n_items: u32,
    /// Tiles of the sort.
    pub n_tiles: u32,
    /// Nodes (pblock capacity x 64).
    pub node_cap: u32,
    /// Padding.
    pub pad: u32,
}

// SAFETY: Pod, passed by value with the C layout the kernels declare.
unsafe impl cudarc::driver::DeviceRepr for SortCtx {}
