//! [`CudaBackend`]: device memory, the step driver and read-back.

use crate::CudaOptions;
use crate::P2gMode;
use crate::compile::{KernelOptions, compile};
use crate::layout::*;
use crate::p2g::P2gPlan;
use crate::p2g_reverse_map::{ReverseMap, ReverseMapSize};
use crate::p2g_sort::SortMap;
use cudarc::driver::{
    CudaContext, CudaFunction, CudaGraph, CudaModule, CudaSlice, CudaStream, DevicePtr,
    LaunchConfig,
};
use rtmpm_core::boundary::Condition;
use rtmpm_core::boundary::sdf::Shape;
use rtmpm_core::grid::BlockLayout;
use rtmpm_core::material::{Eos, Model};
use rtmpm_core::math::{IVec3, Mat3, Vec3};
use rtmpm_core::sim::{Backend, BadParticle, BadReason, SimError};
use rtmpm_core::transfer::{Transfer, Update};
use rtmpm_core::{Particles, Scene};
use std::sync::Arc;

/// Launch configuration covering `n` threads.
pub(crate) fn cfg(n: usize, block: u32) -> LaunchConfig {
    LaunchConfig {
        grid_dim: ((n.max(1)).div_ceil(block as usize) as u32, 1, 1),
        block_dim: (block, 1, 1),
        shared_mem_bytes: 0,
    }
}

/// Like [`cfg`], but with at most `wave_threads` threads in all (kernels with grid-stride loops).
pub(crate) fn cfg_wave(n: usize, block: u32, wave_threads: usize) -> LaunchConfig {
    cfg(n.min(wave_threads.max(block as usize)), block)
}

pub(crate) fn err(what: &str) -> impl Fn(cudarc::driver::DriverError) -> SimError + '_ {
    move |e| SimError::Backend(format!("CUDA: {what}: {e:?}"))
}

/// The kernels of the pipeline.
pub(crate) struct Kernels {
    /// Threads of one full wave of the device (SMs x 2048).
    pub wave_threads: usize,
    /// The rebuild as one persistent kernel (`rebuild=fused`).
    pub rb_fused: CudaFunction,
    /// Its grid (blocks of 1024 threads that fit on the device at once); `None`: the rebuild
    /// runs as separate kernels (`rebuild=kernels`).
    pub rb_fused_grid: Option<u32>,
    pub rb_begin: CudaFunction,
    pub rb_clear: CudaFunction,
    pub rb_insert_gblocks: CudaFunction,
    pub rb_assign: CudaFunction,
    pub rb_insert_neighbors: CudaFunction,
    pub rb_neighbor_lists: CudaFunction,
    pub rb_histogram: CudaFunction,
    pub rb_scan_blocks: CudaFunction,
    pub rb_scan_sums: CudaFunction,
    pub rb_scan_add: CudaFunction,
    pub rb_scatter: CudaFunction,
    pub rb_copy_back: CudaFunction,
    pub rb_end: CudaFunction,
    pub grid_clear: CudaFunction,
    pub grid_clear_aux: CudaFunction,
    pub p2g: CudaFunction,
    pub p2g_shared: CudaFunction,
    pub p2g_mpm: CudaFunction,
    pub p2g_musl: CudaFunction,
    pub grid_update: CudaFunction,
    pub grid_update_musl: CudaFunction,
    pub g2p: CudaFunction,
    pub g2p2g: CudaFunction,
    pub g2p2g_fluid: CudaFunction,
    pub g2p_mpm: CudaFunction,
    pub g2p_mpm_velocity: CudaFunction,
    pub sb_clear_mask: CudaFunction,
    pub sb_mark: CudaFunction,
    pub sb_chunk_count: CudaFunction,
    pub sb_chunk_scan: CudaFunction,
    pub sb_list: CudaFunction,
    pub sb_boundary: CudaFunction,
    pub sb_pack: CudaFunction,
    pub sb_unpack: CudaFunction,
    pub sb_counts_peers: CudaFunction,
    pub sb_sum_peers: CudaFunction,
    pub barrier_spin: CudaFunction,
}

/// The CUDA backend (one GPU).
pub struct CudaBackend {
    pub(crate) stream: Arc<CudaStream>,
    pub(crate) kernels: Kernels,
    pub(crate) ctx: Ctx,
    pub(crate) options: CudaOptions,
    /// The P2G strategy and its buffers.
    pub(crate) p2g: P2gPlan,
    module: Arc<CudaModule>,
    /// Particle state in the backend's precision (see [`crate::state`]).
    pub(crate) state: CudaSlice<u8>,
    block_coords: CudaSlice<u8>,
    _scratch: CudaSlice<u8>,
    pub(crate) grid: CudaSlice<u8>,
    /// G2P2G: the second grid (the steps alternate: one grid is read by G2P while the fused
    /// kernel scatters the next step into the other).
    grid_next: Option<CudaSlice<u8>>,
    /// Every material is a fluid: G2P2G runs its fluid variant (`g2p2g_fluid`).
    pub(crate) all_fluid: bool,
    /// G2P2G: which grid the coming step reads (0: `grid`, 1: `grid_next`).
    parity: usize,
    /// The grid the last step (or P2G) wrote, read back by [`CudaBackend::grid_nodes`].
    last_grid: usize,
    /// G2P2G: dt of the last upload (a new dt asks for a P2G, the fused scatter used the old one).
    last_dt: Option<f32>,
    ctl: CudaSlice<u32>,
    step_buf: CudaSlice<u8>,
    /// The step parameters last uploaded, with `t` zeroed (see [`CudaBackend::upload_params`]).
    last_params: Option<Vec<u8>>,
    _bufs: Vec<CudaSlice<u8>>,
    scene: Scene,
    pub(crate) n: usize,
    /// Pinned host memory of [`CudaBackend::read_fields`] (crate::export).
    pub(crate) staging: crate::export::Staging,
    /// The captured step per grid parity (one without G2P2G), with its dt.
    graph: [Option<(CudaGraph, f32)>; 2],
    device_name: String,
    real_bytes: usize,
}

/// Write `bytes` to the `__constant__` symbol `name` of the module (async on the stream).
fn write_symbol(
    module: &Arc<CudaModule>,
    stream: &Arc<CudaStream>,
    name: &str,
    bytes: &[u8],
) -> Result<(), SimError> {
    if bytes.is_empty() {
        return Ok(());
    }
    let mut sym = module
        .get_global(name, stream)
        .map_err(|e| SimError::Backend(format!("CUDA: constant symbol {name}: {e:?}")))?;
    let len = bytes.len().min(sym.len());
    let mut view = sym.slice_mut(..len);
    stream
        .memcpy_htod(&bytes[..len], &mut view)
        .map_err(|e| SimError::Backend(format!("CUDA: write constant {name}: {e:?}")))
}

/// Largest grid allocated by default for the whole domain (bytes).
const GRID_BUDGET_BYTES: usize = 4 << 30;

fn material(m: &Model) -> Result<GpuMaterial, String> {
    let mut g = GpuMaterial::default();
    match m {
        Model::Fluid(f) => {
            g.kind = 0;
            g.fluid_bulk_modulus = f.bulk_modulus;
            g.fluid_viscosity = f.viscosity;
            (g.fluid_eos, g.fluid_gamma) = match f.eos {
                Eos::Linear => (0, 1.0),
                Eos::Tait { gamma } => (1, gamma),
            };
        }
        Model::FixedCorotated(e) => {
            g.kind = 1;
            g.fixed_corotated = [e.mu, e.lambda];
        }
        Model::NeoHookean(e) => {
            g.kind = 2;
            g.neo_hookean = [e.mu, e.lambda];
        }
        Model::Snow(s) => {
            g.kind = 3;
            g.snow = [
                s.mu,
                s.lambda,
                s.critical_compression,
                s.critical_stretch,
                s.hardening,
            ];
        }
        Model::DruckerPrager(d) => {
            g.kind = 4;
            // The cone slope from its one formula, DruckerPrager::alpha.
            g.drucker_prager = [d.mu, d.lambda, d.alpha(), d.cohesion];
        }
        Model::VonMises(v) => {
            g.kind = 5;
            g.von_mises = [v.mu, v.lambda, v.yield_stress, v.hardening];
        }
    }
    Ok(g)
}

fn cond(c: Condition) -> u32 {
    match c {
        Condition::Sticky => 0,
        Condition::Slip => 1,
        Condition::Separate => 2,
    }
}

fn collider(c: &rtmpm_core::boundary::Collider, mesh: &mut Vec<f32>) -> GpuCollider {
    let mut g = GpuCollider {
        cond: cond(c.rule.condition),
        friction: c.rule.friction,
        velocity: c.velocity.to_array(),
        angular_velocity: c.angular_velocity.to_array(),
        pivot: c.pivot.to_array(),
        ..Default::default()
    };
    let put =
        |g: &mut GpuCollider, at: usize, v: Vec3| g.p[at..at + 3].copy_from_slice(&v.to_array());
    match &c.shape {
        Shape::HalfSpace { point, normal } => {
            g.kind = 0;
            put(&mut g, 0, *point);
            put(&mut g, 3, *normal);
        }
        Shape::Box {
            center,
            half_extents,
        } => {
            g.kind = 1;
            put(&mut g, 0, *center);
            put(&mut g, 3, *half_extents);
        }
        Shape::Sphere { center, radius } => {
            g.kind = 2;
            put(&mut g, 0, *center);
            g.p[3] = *radius;
        }
        Shape::Cylinder {
            center,
            axis,
            radius,
            half_height,
        } => {
            g.kind = 3;
            put(&mut g, 0, *center);
            put(&mut g, 3, *axis);
            g.p[6] = *radius;
            g.p[7] = *half_height;
        }
        Shape::Mesh(m) => {
            g.kind = 4;
            put(&mut g, 0, m.origin);
            g.p[3] = m.spacing;
            g.dims = m.dims;
            g.mesh_offset = mesh.len() as u32;
            mesh.extend_from_slice(&m.values);
        }
    }
    g
}

/// Where a [`CudaBackend`] runs and which particles it holds, when it is one GPU of several.
#[derive(Clone, Debug, Default)]
pub struct Part {
    /// CUDA device ordinal.
    pub device: usize,
    /// Original (global) index of each particle given to [`CudaBackend::new_part`]; `None`: 0..n.
    pub ids: Option<Vec<u32>>,
    /// Particle capacity of the state arrays (at least the particle count; 0: the count).
    pub capacity: usize,
}

impl CudaBackend {
    /// Upload the scene and particles to CUDA device 0 and compile the kernels.
    pub fn new(
        scene: &Scene,
        particles: &Particles,
        options: CudaOptions,
    ) -> Result<CudaBackend, SimError> {
        Self::new_part(scene, particles, &Part::default(), options)
    }

    /// Upload `particles` (one GPU's share of a multi-GPU run, or all of them) to device
    /// `part.device`.
    pub fn new_part(
        scene: &Scene,
        particles: &Particles,
        part: &Part,
        options: CudaOptions,
    ) -> Result<CudaBackend, SimError> {
        let info = crate::probe_device(part.device).map_err(|e| {
            SimError::Backend(format!("CUDA device {} unavailable: {e}", part.device))
        })?;
        // The scene's precision, or the `f64` switch: the whole pipeline in f64.
        let options = CudaOptions {
            f64: options.f64 || scene.precision == rtmpm_core::scene::Precision::F64,
            ..options
        };
        if options.f64 && options.p2g == crate::P2gMode::Shared {
            return Err(SimError::Backend(
                "CUDA backend: p2g=shared is single precision only (a 12^3 tile of f64 nodes \
                 exceeds the 48 KiB of static shared memory); use p2g=warp with f64"
                    .into(),
            ));
        }
        let n = particles.len();
        if n == 0 {
            return Err(SimError::Backend(format!(
                "CUDA backend (device {}): no particles",
                part.device
            )));
        }
        let cap = part.capacity.max(n);
        if let Some(ids) = &part.ids
            && ids.len() != n
        {
            return Err(SimError::Backend(
                "CUDA backend: one id per particle".into(),
            ));
        }
        let mats = scene
            .materials
            .iter()
            .map(|m| material(&m.model))
            .collect::<Result<Vec<_>, _>>()
            .map_err(SimError::Backend)?;
        if mats.len() > MAX_MATERIALS {
            return Err(SimError::Backend(format!(
                "CUDA backend: at most {MAX_MATERIALS} materials (the scene has {})",
                mats.len()
            )));
        }
        if scene.colliders.len() > MAX_COLLIDERS {
            return Err(SimError::Backend(format!(
                "CUDA backend: at most {MAX_COLLIDERS} colliders"
            )));
        }
        if matches!(options.p2g, P2gMode::ReverseMap | P2gMode::Sort)
            && scene.solver.transfer != rtmpm_core::transfer::Transfer::Mls
        {
            return Err(SimError::Backend(format!(
                "CUDA backend: p2g={} gathers MLS-MPM contributions only; the scene's [solver] \
                 transfer is \"{}\": use p2g=warp (the default) or p2g=shared",
                options.p2g.name(),
                scene.solver.transfer.name()
            )));
        }
        let ptx = compile(&KernelOptions {
            arch: info.compute_capability,
            fast_math: options.fast_math,
            f64: options.f64,
        })
        .map_err(SimError::Backend)?;
        let context = CudaContext::new(part.device).map_err(err("context"))?;
        // Single stream: no cross-stream event tracking (keeps launches capturable).
        // SAFETY: all our buffers are used on `stream` only.
        unsafe { context.disable_event_tracking() };
        let stream = context.new_stream().map_err(err("stream"))?;
        let module = context
            .load_module(cudarc::nvrtc::Ptx::from_src(ptx))
            .map_err(err("load module"))?;
        let f = |name: &str| {
            module
                .load_function(name)
                .map_err(|e| SimError::Backend(format!("CUDA: kernel {name}: {e:?}")))
        };
        // The fused rebuild runs as many 1024-thread blocks as fit on the device at once
        // (a cooperative launch: all resident, so its grid barrier cannot deadlock).
        let rb_fused = f("rb_fused")?;
        let rb_fused_grid = if options.fused_rebuild {
            let per_sm = rb_fused
                .occupancy_max_active_blocks_per_multiprocessor(1024, 0, None)
                .map_err(err("occupancy of rb_fused"))?;
            Some(per_sm * info.sm_count.max(1) as u32).filter(|&g| g > 0)
        } else {
            None
        };
        let kernels = Kernels {
            wave_threads: info.sm_count.max(1) as usize * 2048,
            rb_fused,
            rb_fused_grid,
            rb_begin: f("rb_begin")?,
            rb_clear: f("rb_clear")?,
            rb_insert_gblocks: f("rb_insert_gblocks")?,
            rb_assign: f("rb_assign")?,
            rb_insert_neighbors: f("rb_insert_neighbors")?,
            rb_neighbor_lists: f("rb_neighbor_lists")?,
            rb_histogram: f("rb_histogram")?,
            rb_scan_blocks: f("rb_scan_blocks")?,
            rb_scan_sums: f("rb_scan_sums")?,
            rb_scan_add: f("rb_scan_add")?,
            rb_scatter: f("rb_scatter")?,
            rb_copy_back: f("rb_copy_back")?,
            rb_end: f("rb_end")?,
            grid_clear: f("grid_clear")?,
            grid_clear_aux: f("grid_clear_aux")?,
            p2g: f("p2g")?,
            p2g_shared: f("p2g_shared")?,
            p2g_mpm: f("p2g_mpm")?,
            p2g_musl: f("p2g_musl")?,
            grid_update: f("grid_update")?,
            grid_update_musl: f("grid_update_musl")?,
            g2p: f("g2p")?,
            g2p2g: f("g2p2g")?,
            g2p2g_fluid: f("g2p2g_fluid")?,
            g2p_mpm: f("g2p_mpm")?,
            g2p_mpm_velocity: f("g2p_mpm_velocity")?,
            sb_clear_mask: f("sb_clear_mask")?,
            sb_mark: f("sb_mark")?,
            sb_chunk_count: f("sb_chunk_count")?,
            sb_chunk_scan: f("sb_chunk_scan")?,
            sb_list: f("sb_list")?,
            sb_boundary: f("sb_boundary")?,
            sb_pack: f("sb_pack")?,
            sb_unpack: f("sb_unpack")?,
            sb_counts_peers: f("sb_counts_peers")?,
            sb_sum_peers: f("sb_sum_peers")?,
            barrier_spin: f("barrier_spin")?,
        };

        let dx = scene.dx;
        let origin = scene.domain_min - 4.0 * dx;
        let bases: Vec<IVec3> = particles
            .x
            .iter()
            .map(|x| ((*x - origin) / dx - 0.5).floor().as_ivec3())
            .collect();
        let mut l = BlockLayout::default();
        l.rebuild(&bases);
        // Default capacity: every block the domain can hold (particles are clamped into the
        // domain, so the layout can never outgrow it), unless that grid would exceed
        // GRID_BUDGET_BYTES; then 8x the initial layout, and an overflow is reported as an error.
        let n_cells = scene.n_cells();
        let domain_blocks: usize = n_cells
            .iter()
            .map(|&c| (c as usize + 8).div_ceil(4) + 1)
            .product();
        let real_bytes_grid = if options.f64 { 8 } else { 4 };
        let fits = domain_blocks * 64 * 4 * real_bytes_grid <= GRID_BUDGET_BYTES;
        let gblock_cap = options.gblock_capacity.unwrap_or(if fits {
            domain_blocks.min(n.max(64))
        } else {
            (8 * l.gblock_count).max(64)
        });
        let pblock_cap = options.pblock_capacity.unwrap_or(if fits {
            domain_blocks
        } else {
            (8 * l.pblock_count()).max(4 * gblock_cap).max(256)
        });
        let hash_cap = (2 * pblock_cap).next_power_of_two();
        let warp_cap = n.div_ceil(32) + gblock_cap + 1;
        let n_buckets = gblock_cap * 64 + 1;
        let real_bytes = if options.f64 { 8 } else { 4 };

        // Particle state, SoA with stride `cap`, in the backend's precision.
        let fluid: Vec<bool> = scene
            .materials
            .iter()
            .map(|m| matches!(m.model, rtmpm_core::material::Model::Fluid(_)))
            .collect();
        let host = crate::state::pack(particles, &fluid, options.f64, cap, part.ids.as_deref())
            .map_err(SimError::Backend)?;
        let state = stream.clone_htod(&host).map_err(err("upload particles"))?;
        let scratch = stream
            .alloc_zeros::<u8>(host.len())
            .map_err(err("alloc scratch"))?;
        let grid = stream
            .alloc_zeros::<u8>(pblock_cap * 64 * 4 * real_bytes)
            .map_err(err("alloc grid"))?;
        let mut ctl_host = [0u32; CTL_WORDS];
        ctl_host[0] = 1; // rebuild at the first step
        ctl_host[CTL_P2G_PENDING] = 1;
        ctl_host[CTL_BAD_INDEX] = u32::MAX;
        let ctl = stream.clone_htod(&ctl_host).map_err(err("alloc control"))?;
        let step_buf = stream
            .alloc_zeros::<u8>(std::mem::size_of::<StepParams>())
            .map_err(err("alloc params"))?;
        let mut mesh = Vec::new();
        let cols: Vec<GpuCollider> = scene
            .colliders
            .iter()
            .map(|c| collider(c, &mut mesh))
            .collect();
        mesh.push(0.0);
        let mut bufs = Vec::new();
        let mut bytes = |b: &[u8]| -> Result<u64, SimError> {
            let mut v = b.to_vec();
            v.resize(b.len().max(16), 0);
            let s = stream.clone_htod(&v).map_err(err("upload"))?;
            let p = s.device_ptr(&stream).0;
            bufs.push(s);
            Ok(p)
        };
        // The material table in the kernels' precision (global copy and constant memory alike).
        let material_bytes: Vec<u8> = if options.f64 {
            let mats: Vec<_> = mats.iter().map(GpuMaterial::to_f64).collect();
            as_bytes(&mats).to_vec()
        } else {
            as_bytes(&mats).to_vec()
        };
        let materials = bytes(&material_bytes)?;
        let colliders = bytes(as_bytes(&cols))?;
        let mesh_values = bytes(as_bytes(&mesh))?;
        let mut zeros = |len: usize| -> Result<u64, SimError> {
            let s = stream
                .alloc_zeros::<u8>(len.max(16))
                .map_err(err("alloc"))?;
            let p = s.device_ptr(&stream).0;
            bufs.push(s);
            Ok(p)
        };
        let hash_keys = zeros(hash_cap * 8)?;
        let hash_values = zeros(hash_cap * 4)?;
        let block_coords_buf = stream
            .alloc_zeros::<u8>(pblock_cap * 12)
            .map_err(err("alloc block coordinates"))?;
        let block_coords = block_coords_buf.device_ptr(&stream).0;
        let neighbors = zeros(gblock_cap * 27 * 4)?;
        let hist = zeros(n_buckets * 4)?;
        let scan_sums = zeros(n_buckets.div_ceil(1024) * 4)?;
        let pkey = zeros(n * 4)?;
        let prank = zeros(n * 4)?;
        let warps = zeros(warp_cap * 12)?;
        // The classic MPM transfers keep a second value per node (force, v_old, MUSL re-map).
        let solver = scene.solver;
        let grid_aux = if solver.transfer == Transfer::Mls {
            0
        } else {
            zeros(pblock_cap * 64 * 4 * real_bytes)?
        };
        let boundary = zeros(gblock_cap * 4)?;
        // G2P2G where it applies (see CudaOptions::g2p2g): not when every step rebuilds (the
        // fused scatter would always be redone); the second grid.
        let g2p2g = options.g2p2g
            && solver.transfer == Transfer::Mls
            && options.p2g == P2gMode::Warp
            && options.free_zone
            && options.mixed_sort;
        let grid_next = if g2p2g {
            Some(
                stream
                    .alloc_zeros::<u8>(pblock_cap * 64 * 4 * real_bytes)
                    .map_err(err("alloc second grid (G2P2G)"))?,
            )
        } else {
            None
        };
        let w = &scene.walls;
        let n_cells = scene.n_cells();
        let ctx = Ctx {
            state: state.device_ptr(&stream).0,
            scratch: scratch.device_ptr(&stream).0,
            grid: grid.device_ptr(&stream).0,
            ctl: ctl.device_ptr(&stream).0,
            step: step_buf.device_ptr(&stream).0,
            materials,
            colliders,
            mesh_values,
            hash_keys,
            hash_values,
            block_coords,
            neighbors,
            hist,
            scan_sums,
            pkey,
            prank,
            warps,
            grid_aux,
            boundary,
            origin: origin.to_array(),
            dx,
            inv_dx: 1.0 / dx,
            domain_min: scene.domain_min.to_array(),
            domain_max: scene.domain_max.to_array(),
            n_cells: n_cells.map(|c| c as i32),
            wall_thickness: w.thickness as i32,
            wall_cond: w.faces.map(|f| cond(f.condition)),
            wall_friction: w.faces.map(|f| f.friction),
            n: n as u32,
            cap: cap as u32,
            gblock_cap: gblock_cap as u32,
            pblock_cap: pblock_cap as u32,
            hash_cap: hash_cap as u32,
            warp_cap: warp_cap as u32,
            n_colliders: cols.len() as u32,
            n_buckets: n_buckets as u32,
            warp_reduce: options.warp_reduce as u32,
            warp_sort: (options.warp_reduce && options.mixed_sort) as u32,
            transfer: solver.transfer.code(),
            update: (solver.update == Update::Musl) as u32,
            flip: solver.flip,
            grid_next: grid_next.as_ref().map_or(0, |g| g.device_ptr(&stream).0),
            // The same geometry in f64 (computed in f64 like rtmpm-f64's StepConstants).
            origin_f64: (scene.domain_min.as_dvec3() - 4.0 * dx as f64).to_array(),
            dx_f64: dx as f64,
            inv_dx_f64: 1.0 / dx as f64,
            domain_min_f64: scene.domain_min.as_dvec3().to_array(),
            domain_max_f64: scene.domain_max.as_dvec3().to_array(),
            wall_friction_f64: w.faces.map(|f| f.friction as f64),
        };
        // Read-only parameters in constant memory (kernels/common.cuh); the global copies above
        // serve kernels compiled with -DRTMPM_PARAMS_GLOBAL.
        write_symbol(&module, &stream, "c_materials", &material_bytes)?;
        write_symbol(&module, &stream, "c_colliders", as_bytes(&cols))?;
        let p2g = match options.p2g {
            P2gMode::Warp => P2gPlan::Warp,
            P2gMode::Shared => P2gPlan::Shared,
            P2gMode::ReverseMap => {
                let mut size = ReverseMapSize::for_particles(
                    &bases,
                    options.rmap_replicas,
                    l.pblock_count(),
                    pblock_cap,
                );
                if let Some(s) = options.rmap_slots {
                    size.slots = s.max(1);
                }
                if let Some(p) = options.rmap_pblocks {
                    size.pblocks = p.clamp(1, pblock_cap);
                }
                P2gPlan::ReverseMap(ReverseMap::new(&module, &stream, &ctx, real_bytes, size)?)
            }
            P2gMode::Sort => P2gPlan::Sort(SortMap::new(&module, &stream, &ctx, real_bytes)?),
        };
        Ok(CudaBackend {
            stream,
            kernels,
            ctx,
            options,
            p2g,
            module,
            state,
            block_coords: block_coords_buf,
            _scratch: scratch,
            grid,
            grid_next,
            all_fluid: fluid.iter().all(|f| *f),
            parity: 0,
            last_grid: 0,
            last_dt: None,
            ctl,
            step_buf,
            last_params: None,
            _bufs: bufs,
            scene: scene.clone(),
            n,
            staging: Default::default(),
            graph: [None, None],
            device_name: info.name,
            real_bytes,
        })
    }

    fn step_params(&self, dt: f32, t: f32) -> StepParams {
        let mut p = StepParams {
            dt,
            t,
            gravity: self.scene.gravity.to_array(),
            always_rebuild: (!self.options.free_zone || !self.options.mixed_sort) as u32,
            damping: self.scene.time.damping.factor(dt, t),
            pad: [0; 1],
            rot: [[0.0; 9]; MAX_COLLIDERS],
            pivot_t: [[0.0; 3]; MAX_COLLIDERS],
            dt_f64: dt as f64,
            gravity_f64: self.scene.gravity.as_dvec3().to_array(),
        };
        for (k, c) in self.scene.colliders.iter().enumerate() {
            let w = c.angular_velocity;
            let r = if w.length() > 0.0 {
                Mat3::from_axis_angle(w / w.length(), w.length() * t)
            } else {
                Mat3::IDENTITY
            };
            p.rot[k] = r.to_cols_array();
            p.pivot_t[k] = (c.pivot + c.velocity * t).to_array();
        }
        p
    }

    /// True when G2P and the next step's P2G run as one kernel (see [`CudaOptions::g2p2g`]).
    pub fn g2p2g(&self) -> bool {
        self.grid_next.is_some()
    }

    /// The context of the coming step: with G2P2G the two grids swap roles every step.
    pub(crate) fn step_ctx(&self) -> Ctx {
        let mut c = self.ctx;
        if self.parity == 1 {
            std::mem::swap(&mut c.grid, &mut c.grid_next);
        }
        c
    }

    /// After enqueuing a step: the next one reads the other grid (G2P2G).
    pub(crate) fn end_step(&mut self) {
        self.last_grid = self.parity;
        if self.g2p2g() {
            self.parity ^= 1;
        }
    }

    /// Enqueue one step: replay of the graph captured for this grid parity and dt, else a
    /// capture (parameters live in device memory, so a graph is valid for any t).
    fn step_enqueued(&mut self, dt: f32) -> Result<(), SimError> {
        if !self.options.graph {
            return self.enqueue_step();
        }
        if let Some((g, gdt)) = &self.graph[self.parity]
            && *gdt == dt
        {
            return g.launch().map_err(err("graph launch"));
        }
        use cudarc::driver::sys::{CUgraphInstantiate_flags, CUstreamCaptureMode};
        self.graph[self.parity] = None;
        self.stream
            .begin_capture(CUstreamCaptureMode::CU_STREAM_CAPTURE_MODE_THREAD_LOCAL)
            .map_err(err("begin capture"))?;
        let r = self.enqueue_step();
        let g = self
            .stream
            .end_capture(CUgraphInstantiate_flags(0))
            .map_err(err("end capture"))?;
        r?;
        let g = g.ok_or_else(|| SimError::Backend("CUDA: empty graph".into()))?;
        g.launch().map_err(err("graph launch"))?;
        self.graph[self.parity] = Some((g, dt));
        Ok(())
    }

    /// The grid the last step wrote (velocities after the grid update).
    fn shown_grid(&self) -> &CudaSlice<u8> {
        match (self.last_grid, &self.grid_next) {
            (1, Some(g)) => g,
            _ => &self.grid,
        }
    }

    /// Enqueue the kernels of one step (parameters already uploaded).
    pub(crate) fn enqueue_step(&self) -> Result<(), SimError> {
        let (k, s, c) = (&self.kernels, &self.stream, &self.step_ctx());
        crate::rebuild::enqueue(k, s, c).map_err(err("rebuild"))?;
        self.p2g.enqueue(k, s, c).map_err(err("p2g"))?;
        crate::grid_update::enqueue(k, s, c).map_err(err("grid update"))?;
        if c.transfer != Transfer::Mls.code() && c.update == 1 {
            // MUSL: new particle velocities, their momenta re-mapped, then the final G2P.
            crate::g2p::enqueue_velocity(k, s, c).map_err(err("g2p (MUSL velocity)"))?;
            crate::p2g::enqueue_musl(k, s, c).map_err(err("p2g (MUSL re-map)"))?;
            crate::grid_update::enqueue_musl(k, s, c).map_err(err("grid update (MUSL)"))?;
        }
        crate::g2p::enqueue(k, s, c, self.all_fluid).map_err(err("g2p"))?;
        Ok(())
    }

    /// Upload the step parameters (async on the compute stream). No kernel reads `t` itself
    /// (colliders are posed on the host, damping is a factor), so a step whose parameters equal
    /// the last upload's but for `t` needs no copy: scenes without moving colliders or damping
    /// upload once, not twice per step.
    pub(crate) fn upload_params(&mut self, dt: f32, t: f32) -> Result<(), SimError> {
        let p = [self.step_params(dt, t)];
        let key = as_bytes(&[StepParams { t: 0.0, ..p[0] }]).to_vec();
        if self.last_params.as_ref() == Some(&key) {
            return Ok(());
        }
        self.stream
            .memcpy_htod(as_bytes(&p), &mut self.step_buf)
            .map_err(err("upload step parameters"))?;
        write_symbol(&self.module, &self.stream, "c_step", as_bytes(&p))?;
        self.last_params = Some(key);
        // G2P2G: the last fused scatter used the old dt in the stress term; redo this step's P2G.
        if self.g2p2g() && self.last_dt.is_some_and(|d| d != dt) {
            self.set_ctl_word(CTL_P2G_PENDING, 1)?;
        }
        self.last_dt = Some(dt);
        Ok(())
    }

    /// Extra device memory of the P2G strategy: (buffer, bytes); empty for the scatter.
    pub fn p2g_memory(&self) -> Vec<(&'static str, usize)> {
        self.p2g.memory()
    }

    /// Bytes of the grid (nodes of every allocated pblock), for comparison with
    /// [`CudaBackend::p2g_memory`].
    pub fn grid_bytes(&self) -> usize {
        self.ctx.pblock_cap as usize * 64 * 4 * self.real_bytes
    }

    /// Sizes of the reverse map (`p2g=reverse_map` only).
    pub fn reverse_map_size(&self) -> Option<ReverseMapSize> {
        match &self.p2g {
            P2gPlan::ReverseMap(r) => Some(r.size),
            _ => None,
        }
    }

    /// Every grid node of the pblocks in use with its four values (mass, momentum or velocity), by
    /// grid coordinate (synchronises). Pblock ids differ between runs, coordinates do not: this
    /// compares the grids of two backends node by node.
    pub fn grid_nodes(&mut self) -> Result<Vec<(IVec3, [f64; 4])>, SimError> {
        let (_, p, _) = self.block_counts()?;
        let grid = self
            .stream
            .clone_dtoh(self.shown_grid())
            .map_err(err("read grid"))?;
        let coords = self
            .stream
            .clone_dtoh(&self.block_coords)
            .map_err(err("read block coordinates"))?;
        let word = |b: &[u8], i: usize| {
            i32::from_le_bytes([b[4 * i], b[4 * i + 1], b[4 * i + 2], b[4 * i + 3]])
        };
        let mut out = Vec::with_capacity(p as usize * 64);
        for id in 0..(p as usize).min(self.ctx.pblock_cap as usize) {
            let bc = IVec3::new(
                word(&coords, 3 * id),
                word(&coords, 3 * id + 1),
                word(&coords, 3 * id + 2),
            );
            for cell in 0..64usize {
                let node = bc * 4
                    + IVec3::new(
                        (cell >> 4) as i32,
                        ((cell >> 2) & 3) as i32,
                        (cell & 3) as i32,
                    );
                let mut v = [0f64; 4];
                for (q, x) in v.iter_mut().enumerate() {
                    let i = 4 * (id * 64 + cell) + q;
                    *x = if self.real_bytes == 8 {
                        f64::from_le_bytes(grid[8 * i..8 * i + 8].try_into().unwrap_or([0; 8]))
                    } else {
                        f32::from_le_bytes(grid[4 * i..4 * i + 4].try_into().unwrap_or([0; 4]))
                            as f64
                    };
                }
                out.push((node, v));
            }
        }
        Ok(out)
    }

    pub(crate) fn ctl_words(&mut self) -> Result<Vec<u32>, SimError> {
        self.stream
            .clone_dtoh(&self.ctl)
            .map_err(err("read control words"))
    }

    /// Positions and velocities of every particle in original order, in the backend's
    /// precision widened to f64 (synchronises; for precision tests).
    pub fn read_x_v_f64(&mut self) -> Result<Vec<[[f64; 3]; 2]>, SimError> {
        let host = self
            .stream
            .clone_dtoh(&self.state)
            .map_err(err("read particles"))?;
        crate::state::unpack_x_v_f64(&host, self.n, self.ctx.cap as usize, self.options.f64)
            .map_err(SimError::Backend)
    }

    /// The particle state arrays as stored (SoA, stride = capacity; synchronises). Single
    /// precision only (the multi-GPU runs that use it refuse f64).
    pub fn read_state(&mut self) -> Result<Vec<f32>, SimError> {
        if self.options.f64 {
            return Err(SimError::Backend(
                "CUDA: read_state is single precision only".into(),
            ));
        }
        let bytes = self
            .stream
            .clone_dtoh(&self.state)
            .map_err(err("read particles"))?;
        Ok(bytes
            .chunks_exact(4)
            .map(|w| f32::from_le_bytes([w[0], w[1], w[2], w[3]]))
            .collect())
    }

    /// Write one control word (asynchronously, on the compute stream).
    pub(crate) fn set_ctl_word(&mut self, word: usize, value: u32) -> Result<(), SimError> {
        let mut view = self.ctl.slice_mut(word..word + 1);
        self.stream
            .memcpy_htod(&[value], &mut view)
            .map_err(err("write control word"))
    }

    /// Number of particles on this GPU.
    pub fn len(&self) -> usize {
        self.n
    }

    /// True when it holds no particle (never: construction refuses that).
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Number of rebuilds of the mapping so far (synchronises).
    pub fn rebuild_count(&mut self) -> Result<u32, SimError> {
        Ok(self.ctl_words()?[CTL_REBUILDS])
    }

    /// Current (gblock, pblock, warp) counts (synchronises).
    pub fn block_counts(&mut self) -> Result<(u32, u32, u32), SimError> {
        let c = self.ctl_words()?;
        Ok((c[CTL_GBLOCKS], c[CTL_PBLOCKS], c[CTL_WARPS]))
    }

    /// Sum of node masses and momenta/velocities on the grid, as f64 (synchronises). After a step
    /// the grid holds velocities; see the tests for how P2G alone is checked.
    pub fn grid_sums(&mut self) -> Result<[f64; 4], SimError> {
        let (_, p, _) = self.block_counts()?;
        let bytes = self
            .stream
            .clone_dtoh(self.shown_grid())
            .map_err(err("read grid"))?;
        let mut s = [0f64; 4];
        let nodes = p as usize * 64;
        for i in 0..nodes * 4 {
            let v = if self.real_bytes == 8 {
                f64::from_le_bytes(bytes[8 * i..8 * i + 8].try_into().unwrap_or([0; 8]))
            } else {
                f32::from_le_bytes(bytes[4 * i..4 * i + 4].try_into().unwrap_or([0; 4])) as f64
            };
            s[i % 4] += v;
        }
        Ok(s)
    }

    /// Enqueue only rebuild + P2G with the given dt (for tests of P2G conservation).
    pub fn run_p2g_only(&mut self, dt: f32) -> Result<(), SimError> {
        self.upload_params(dt, 0.0)?;
        self.last_grid = self.parity;
        let (k, s, c) = (&self.kernels, &self.stream, &self.step_ctx());
        crate::rebuild::enqueue(k, s, c).map_err(err("rebuild"))?;
        self.p2g.enqueue(k, s, c).map_err(err("p2g"))
    }

    pub(crate) fn error_check(&self, c: &[u32]) -> Result<(), SimError> {
        let e = c[CTL_ERROR];
        if e != 0 {
            let mut what = Vec::new();
            if e & 1 != 0 {
                what.push(format!(
                    "block hash table full ({} slots)",
                    self.ctx.hash_cap
                ));
            }
            if e & 2 != 0 {
                what.push(format!("more than {} gblocks", self.ctx.gblock_cap));
            }
            if e & 4 != 0 {
                what.push(format!("more than {} pblocks", self.ctx.pblock_cap));
            }
            if e & 8 != 0 {
                what.push(format!("more than {} warps", self.ctx.warp_cap));
            }
            if e & 16 != 0 {
                let detail = match self.reverse_map_size() {
                    Some(s) => format!(
                        "p2g=reverse_map: a node received more than {} entries in one of its {} maps, \
                         or the material reached more than {} pblocks (raise rmap_slots= or rmap_pblocks=)",
                        s.slots, s.replicas, s.pblocks
                    ),
                    None => "P2G contribution map overflow".to_string(),
                };
                what.push(detail);
            }
            if e & 32 != 0 {
                what.push(format!(
                    "more than {} blocks shared between GPUs (raise it with the shared= option)",
                    c[CTL_SHARED_CAP]
                ));
            }
            if e & 64 != 0 {
                what.push(
                    "the inter-GPU spin barrier timed out: another GPU never arrived (its host \
                     thread stopped; see the other errors)"
                        .to_string(),
                );
            }
            let hint = if e & 15 != 0 {
                " (the material spread over more blocks than allocated; raise the capacity with \
                 the gblocks=/pblocks= options)"
            } else {
                ""
            };
            let head = if e & !64 != 0 {
                "CUDA backend out of capacity"
            } else {
                "CUDA multi-GPU run stopped"
            };
            return Err(SimError::Backend(format!(
                "{head}: {}{hint}",
                what.join(", ")
            )));
        }
        Ok(())
    }
}

impl Backend for CudaBackend {
    fn name(&self) -> String {
        if self.options.f64 {
            format!("cuda ({}, f64)", self.device_name)
        } else {
            format!("cuda ({})", self.device_name)
        }
    }

    fn num_particles(&self) -> usize {
        self.n
    }

    fn step(&mut self, dt: f32, t: f32) -> Result<(), SimError> {
        self.upload_params(dt, t)?;
        let r = self.step_enqueued(dt);
        self.end_step();
        r
    }

    fn max_speed(&mut self) -> Result<f32, SimError> {
        let c = self.ctl_words()?;
        self.error_check(&c)?;
        Ok(f32::from_bits(c[CTL_MAX_SPEED]))
    }

    fn check(&mut self) -> Result<Option<BadParticle>, SimError> {
        let c = self.ctl_words()?;
        self.error_check(&c)?;
        if c[CTL_BAD_INDEX] == u32::MAX {
            return Ok(None);
        }
        let reset = [u32::MAX, 0];
        let mut view = self.ctl.slice_mut(CTL_BAD_INDEX..CTL_BAD_INDEX + 2);
        self.stream
            .memcpy_htod(&reset, &mut view)
            .map_err(err("reset bad particle"))?;
        let reason = if c[CTL_BAD_REASON] == 1 {
            BadReason::NonFinite
        } else {
            BadReason::TooFast
        };
        Ok(Some(BadParticle {
            index: c[CTL_BAD_INDEX] as usize,
            reason,
        }))
    }

    fn read_particles(&mut self, out: &mut Particles) -> Result<(), SimError> {
        let host = self
            .stream
            .clone_dtoh(&self.state)
            .map_err(err("read particles"))?;
        crate::state::unpack(&host, self.n, self.ctx.cap as usize, self.options.f64, out)
            .map_err(SimError::Backend)
    }
}

/// Size every column of `out` for `n` particles (zeros); see [`crate::state::resize_particles`].
pub use crate::state::resize_particles;

/// Put the `n` particles of a single-precision state array (SoA with stride `cap`, as stored on
/// one GPU) at their original index in `out` (already sized for every particle of the run).
pub fn scatter_state(
    host: &[f32],
    n: usize,
    cap: usize,
    out: &mut Particles,
) -> Result<(), SimError> {
    crate::state::scatter_f32(host, n, cap, out).map_err(SimError::Backend)
}
