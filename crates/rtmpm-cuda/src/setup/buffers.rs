//! The device memory of one GPU: every buffer of the pipeline, allocated once when the backend is
//! built (nothing is allocated inside a step), and the kernel context [`Ctx`] that points into
//! it.

use crate::contract::{self, CTL_BAD_INDEX, CTL_P2G_PENDING, CTL_WORDS, Ctx};
use crate::error::err;
use crate::setup::capacity::{BufferBytes, Capacity, GridCopies};
use cudarc::driver::{CudaSlice, CudaStream, DevicePtr};
use rtmpm_physics::transfer::Transfer;
use rtmpm_scene::Scene;
use rtmpm_sim::SimError;
use std::sync::Arc;

/// What a GPU's buffers hold besides the capacities: its particle count, the precision and the
/// optional buffers.
#[derive(Clone, Copy, Debug)]
pub struct Needs {
    /// Particles on this GPU.
    pub particles: usize,
    /// Bytes per `real` (4, or 8 in f64).
    pub real_bytes: usize,
    /// Words per particle of the state (`StateLayout::words`).
    pub state_words: usize,
    /// G2P2G: a second grid.
    pub grid_next: bool,
    /// Largest particle speed of the initial state (m/s): the CFL step of the first step, before
    /// any G2P has measured it (else a huge initial velocity runs one step at `max_dt`).
    pub initial_speed: f32,
}

/// The buffers of one GPU. The [`Ctx`] holds their device addresses; the slices keep them alive.
pub struct Buffers {
    /// Particle state, SoA with stride `Capacity::particles`, in the backend's precision.
    pub state: CudaSlice<u8>,
    /// 3 ints per pblock.
    pub block_coords: CudaSlice<u8>,
    /// The grid (4 reals per node).
    pub grid: CudaSlice<u8>,
    /// G2P2G: the second grid.
    pub grid_next: Option<CudaSlice<u8>>,
    /// Control words.
    pub ctl: CudaSlice<u32>,
    /// Global copies of the constant-memory parameters.
    pub scalars: CudaSlice<u8>,
    /// See `scalars`.
    pub step: CudaSlice<u8>,
    /// See `scalars`.
    pub poses: CudaSlice<u8>,
    /// See `scalars` (the user's tool, [`contract::GpuTool`]).
    pub tool: CudaSlice<u8>,
    /// Every other buffer (scratch, hash, lists, sort, tables).
    _rest: Vec<CudaSlice<u8>>,
    /// The planned bytes of each buffer (what was allocated, each at least 16 bytes).
    pub planned: BufferBytes,
}

impl Buffers {
    /// Bytes of every buffer (the device memory this GPU's pipeline allocated, P2G strategy's
    /// extra buffers aside).
    pub fn bytes(&self) -> usize {
        self.state.num_bytes()
            + self.block_coords.num_bytes()
            + self.grid.num_bytes()
            + self.grid_next.as_ref().map_or(0, |g| g.num_bytes())
            + self.ctl.num_bytes()
            + self.scalars.num_bytes()
            + self.step.num_bytes()
            + self.poses.num_bytes()
            + self.tool.num_bytes()
            + self._rest.iter().map(|b| b.num_bytes()).sum::<usize>()
    }
}

/// The bytes of every buffer [`allocate`] allocates for `cap`: `real_bytes` per real, a state of
/// `state_words` words, G2P2G's second grid when `grid_next` (the backend checks them against the
/// GPU's free memory first).
pub fn sizes(
    scene: &Scene,
    cap: &Capacity,
    real_bytes: usize,
    state_words: usize,
    grid_next: bool,
    options: &crate::options::CudaOptions,
) -> BufferBytes {
    cap.bytes(
        real_bytes,
        state_words,
        options.sort_scratch_fields,
        GridCopies {
            next: grid_next,
            aux: scene.solver.transfer != Transfer::Mls,
        },
    )
}

/// Allocate every buffer of a GPU for `cap`, upload the particle state (`state`: the particles
/// packed by [`crate::state::pack`] with stride `needs.particles`, placed field by field into the
/// arrays of stride `cap.particles`, so the host never holds the capacity's empty slots; `None`:
/// the state stays zero, for the device to fill, [`crate::setup::fill`]) and the scene's tables,
/// and build the context.
pub fn allocate(
    stream: &Arc<CudaStream>,
    scene: &Scene,
    state: Option<&[u8]>,
    cap: &Capacity,
    needs: Needs,
    tables: &crate::encode::Tables,
    options: &crate::options::CudaOptions,
) -> Result<(Buffers, Ctx), SimError> {
    let s = stream;
    let sizes = sizes(
        scene,
        cap,
        needs.real_bytes,
        needs.state_words,
        needs.grid_next,
        options,
    );
    let mut rest = Vec::new();
    let unnamed = Unnamed::allocate(s, cap, &sizes, tables, &mut rest)?;
    let state = upload_state(s, state, cap, &sizes, needs)?;
    let grid = s.alloc_zeros::<u8>(sizes.grid).map_err(err("alloc grid"))?;
    let grid_next = if needs.grid_next {
        Some(
            s.alloc_zeros::<u8>(sizes.grid_next)
                .map_err(err("alloc second grid (G2P2G)"))?,
        )
    } else {
        None
    };
    let block_coords = s
        .alloc_zeros::<u8>(sizes.block_coords)
        .map_err(err("alloc block coordinates"))?;
    let ctl = control_words(s, needs)?;
    let scalars = s
        .clone_htod(&tables.scalars)
        .map_err(err("upload scalars"))?;
    let step = s
        .alloc_zeros::<u8>(std::mem::size_of::<contract::StepParams<f64>>())
        .map_err(err("alloc step parameters"))?;
    let poses = s
        .alloc_zeros::<u8>(std::mem::size_of::<contract::ColliderPoses>())
        .map_err(err("alloc collider poses"))?;
    let tool = s
        .alloc_zeros::<u8>(std::mem::size_of::<contract::GpuTool>())
        .map_err(err("alloc the tool"))?;
    debug_assert_eq!(state.len(), sizes.state);
    let buffers = Buffers {
        state,
        block_coords,
        grid,
        grid_next,
        ctl,
        scalars,
        step,
        poses,
        tool,
        _rest: rest,
        planned: sizes,
    };
    let ctx = context(s, scene, cap, needs, options, tables, &unnamed, &buffers);
    Ok((buffers, ctx))
}

/// The device addresses of the buffers that only the kernels use (the host keeps them alive in
/// [`Buffers`]' `_rest`): the sort scratch, hash, lists, sort, flags, the second node values and
/// the tables.
struct Unnamed {
    scratch: u64,
    hash_keys: u64,
    hash_values: u64,
    neighbors: u64,
    hist: u64,
    scan_sums: u64,
    prank: u64,
    warps: u64,
    boundary: u64,
    shared_pblock: u64,
    grid_aux: u64,
    materials: u64,
    colliders: u64,
    mesh_values: u64,
}

impl Unnamed {
    /// Allocate them (zeros) and upload the tables, each buffer pushed onto `rest`.
    fn allocate(
        s: &Arc<CudaStream>,
        cap: &Capacity,
        sizes: &BufferBytes,
        tables: &crate::encode::Tables,
        rest: &mut Vec<CudaSlice<u8>>,
    ) -> Result<Unnamed, SimError> {
        let mut zeros = |len: usize, what: &'static str| -> Result<u64, SimError> {
            let b = s.alloc_zeros::<u8>(len.max(16)).map_err(err(what))?;
            let p = b.device_ptr(s).0;
            rest.push(b);
            Ok(p)
        };
        // The sort scratch: `sort_scratch_fields` fields, permuted a chunk at a time (rebuild.cu);
        // its first field holds the sort keys between the histogram and the ranks (Ctx::pkey).
        let scratch = zeros(sizes.scratch, "alloc sort scratch")?;
        let hash_keys = zeros(cap.hash * 8, "alloc hash")?;
        let hash_values = zeros(cap.hash * 4, "alloc hash")?;
        debug_assert_eq!(sizes.hash, cap.hash * 12);
        let neighbors = zeros(sizes.neighbors, "alloc neighbour lists")?;
        let hist = zeros(sizes.hist, "alloc histogram")?;
        let scan_sums = zeros(sizes.scan_sums, "alloc scan")?;
        // Sized to the capacity: emitters add particles up to it during the run.
        let prank = zeros(sizes.prank, "alloc sort ranks")?;
        let warps = zeros(sizes.warps, "alloc warp list")?;
        let boundary = zeros(sizes.boundary, "alloc boundary flags")?;
        let shared_pblock = zeros(sizes.shared_pblock, "alloc shared-block flags")?;
        // The classic MPM transfers keep a second value per node (force, v_old, MUSL re-map),
        // CK-MPM its second grid.
        let grid_aux = if sizes.grid_aux == 0 {
            0
        } else {
            zeros(sizes.grid_aux, "alloc second node values")?
        };
        let mut upload = |bytes: &[u8], what: &'static str| -> Result<u64, SimError> {
            let mut v = bytes.to_vec();
            v.resize(v.len().max(16), 0);
            let b = s.clone_htod(&v).map_err(err(what))?;
            let p = b.device_ptr(s).0;
            rest.push(b);
            Ok(p)
        };
        let materials = upload(&tables.materials, "upload materials")?;
        let colliders = upload(bytemuck::cast_slice(&tables.colliders), "upload colliders")?;
        let mesh_values = upload(bytemuck::cast_slice(&tables.mesh), "upload meshes")?;
        Ok(Unnamed {
            scratch,
            hash_keys,
            hash_values,
            neighbors,
            hist,
            scan_sums,
            prank,
            warps,
            boundary,
            shared_pblock,
            grid_aux,
            materials,
            colliders,
            mesh_values,
        })
    }
}

/// The state arrays (zeros), with the packed `state` (stride `needs.particles`) copied field by
/// field to its offsets of stride `cap.particles`.
fn upload_state(
    s: &Arc<CudaStream>,
    state: Option<&[u8]>,
    cap: &Capacity,
    sizes: &BufferBytes,
    needs: Needs,
) -> Result<CudaSlice<u8>, SimError> {
    let rb = needs.real_bytes;
    let mut state_buf = s
        .alloc_zeros::<u8>(sizes.state)
        .map_err(err("alloc particle state"))?;
    let row = needs.particles * rb;
    for f in 0..needs.state_words {
        let Some(state) = state else { break };
        let at = f * cap.particles * rb;
        s.memcpy_htod(
            &state[f * row..(f + 1) * row],
            &mut state_buf.slice_mut(at..at + row),
        )
        .map_err(err("upload particles"))?;
    }
    Ok(state_buf)
}

/// The control words at the start: a rebuild and a P2G pending at the first step, no bad
/// particle, and the initial speed.
fn control_words(s: &Arc<CudaStream>, needs: Needs) -> Result<CudaSlice<u32>, SimError> {
    let mut ctl_host = [0u32; CTL_WORDS];
    ctl_host[contract::CTL_NEED_REBUILD] = 1; // rebuild at the first step
    ctl_host[CTL_P2G_PENDING] = 1;
    ctl_host[CTL_BAD_INDEX] = u32::MAX;
    ctl_host[contract::CTL_MAX_SPEED] = needs.initial_speed.to_bits();
    s.clone_htod(&ctl_host).map_err(err("alloc control words"))
}

/// The kernel context: every buffer's device address, the capacities, the scene's grid and
/// walls, and the switches of `options`.
#[allow(clippy::too_many_arguments)]
fn context(
    s: &Arc<CudaStream>,
    scene: &Scene,
    cap: &Capacity,
    needs: Needs,
    options: &crate::options::CudaOptions,
    tables: &crate::encode::Tables,
    u: &Unnamed,
    b: &Buffers,
) -> Ctx {
    let ptr = |b: &CudaSlice<u8>| b.device_ptr(s).0;
    let w = &scene.walls;
    Ctx {
        state: ptr(&b.state),
        scratch: u.scratch,
        grid: ptr(&b.grid),
        grid_next: b.grid_next.as_ref().map_or(0, ptr),
        grid_aux: u.grid_aux,
        // CK-MPM with G2P2G: the next step's second grid follows its first in grid_next.
        grid_aux_next: match &b.grid_next {
            Some(g) if u.grid_aux != 0 => ptr(g) + b.planned.grid as u64,
            _ => 0,
        },
        ctl: b.ctl.device_ptr(s).0,
        scalars: ptr(&b.scalars),
        step: ptr(&b.step),
        poses: ptr(&b.poses),
        materials: u.materials,
        colliders: u.colliders,
        mesh_values: u.mesh_values,
        hash_keys: u.hash_keys,
        hash_values: u.hash_values,
        block_coords: ptr(&b.block_coords),
        neighbors: u.neighbors,
        hist: u.hist,
        scan_sums: u.scan_sums,
        // The scratch's first field holds the sort keys (see `Unnamed::allocate`).
        pkey: u.scratch,
        prank: u.prank,
        warps: u.warps,
        boundary: u.boundary,
        shared_pblock: u.shared_pblock,
        // Set by the backend when the scene has rigid bodies (crate::step::rigid).
        bodies: 0,
        body_exchange: 0,
        tool: ptr(&b.tool),
        n_cells: scene.n_cells().map(|c| c as i32),
        wall_thickness: w.thickness as i32,
        wall_cond: w.faces.map(|f| contract::condition(f.condition)),
        n: needs.particles as u32,
        cap: cap.particles as u32,
        gblock_cap: cap.gblocks as u32,
        pblock_cap: cap.pblocks as u32,
        hash_cap: cap.hash as u32,
        warp_cap: cap.warps as u32,
        n_colliders: tables.colliders.len() as u32,
        n_buckets: cap.buckets as u32,
        warp_reduce: options.warp_reduce as u32,
        warp_sort: (options.warp_reduce && options.mixed_sort) as u32,
        transfer: scene.solver.transfer.code(),
        update: contract::update(scene.solver.update),
        always_rebuild: (!options.free_zone || !options.mixed_sort) as u32,
        n_bodies: 0,
    }
}
