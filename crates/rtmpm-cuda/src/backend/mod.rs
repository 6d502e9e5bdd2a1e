//! [`CudaBackend`]: one GPU. Building it is a list of steps (check, compile, capacities,
//! buffers, constants, P2G strategy); a step is [`crate::step::enqueue_step`], replayed from
//! a CUDA graph ([`crate::step::graph`]) while dt stays the same.

use crate::compile::{KernelOptions, compile};
use crate::contract::{CTL_P2G_PENDING, ColliderPoses, Ctx, StateLayout};
use crate::encode::{self, Tables};
use crate::error::err;
use crate::kernels::{Kernels, write_symbol};
use crate::setup::Initial;
use crate::setup::buffers;
use crate::setup::capacity::Capacity;
use crate::step::graph::StepGraphs;
use crate::step::p2g::P2gPlan;
use crate::step::{Hooks, NoHooks, Stage, StepPlan};
use crate::{CudaOptions, P2gMode};
use cudarc::driver::{CudaContext, CudaModule, CudaStream};
use rtmpm_core::scene::Precision;
use rtmpm_core::scene::sampling::SampledBody;
use rtmpm_core::sim::{Backend, BadParticle, BadReason, SimError};
use rtmpm_core::transfer::Transfer;
use rtmpm_core::{Particles, Scene};
use std::sync::Arc;

pub mod bench;
pub mod emit;
pub mod readback;
mod sim;

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

/// The CUDA backend (one GPU).
pub struct CudaBackend {
    pub(crate) stream: Arc<CudaStream>,
    pub(crate) kernels: Kernels,
    pub(crate) ctx: Ctx,
    pub(crate) options: CudaOptions,
    /// The P2G strategy and its buffers.
    pub(crate) p2g: P2gPlan,
    module: Arc<CudaModule>,
    pub(crate) buffers: buffers::Buffers,
    /// Every material is a fluid: G2P2G runs its fluid variant (`g2p2g_fluid`).
    pub(crate) all_fluid: bool,
    /// Where each field of a particle is in the state arrays.
    pub(crate) layout: StateLayout,
    /// G2P2G: which grid the coming step reads (0: `grid`, 1: `grid_next`).
    parity: usize,
    /// The grid the last step (or P2G) wrote, read back by [`CudaBackend::grid_nodes`].
    pub(crate) last_grid: usize,
    /// G2P2G: dt of the last upload (a new dt asks for a P2G: the fused scatter used the old one).
    last_dt: Option<f32>,
    /// The step parameters and poses last uploaded, with `t` zeroed (see `upload_params`).
    last_params: Option<(Vec<u8>, ColliderPoses)>,
    pub(crate) scene: Scene,
    pub(crate) n: usize,
    /// Pinned host memory of [`CudaBackend::read_fields`] (`export.rs`).
    pub(crate) staging: crate::export::Staging,
    graphs: StepGraphs,
    device_name: String,
    /// The rigid bodies coupled to the grid (`[[rigid_body]]`), if any.
    bodies: Option<crate::step::rigid::Bodies>,
    /// Where the time of building this backend went.
    setup: crate::setup::SetupPhases,
}

/// Checks before any GPU work: what the CUDA backend cannot run, as clear errors.
fn check(scene: &Scene, n: usize, part: &Part, o: &CudaOptions) -> Result<(), SimError> {
    if o.f64 && o.p2g == P2gMode::Shared {
        return Err(SimError::Backend(
            "CUDA backend: p2g=shared is single precision only (a 12^3 tile of f64 nodes \
             exceeds the 48 KiB of static shared memory); use p2g=warp with f64"
                .into(),
        ));
    }
    if !scene.rigid_bodies.is_empty() && part.ids.is_some() {
        return Err(SimError::Backend(
            "CUDA backend: the scene's [[rigid_body]] tables are coupled on one GPU only so \
             far; run it with --gpus 1 (or on the CPU backend)"
                .into(),
        ));
    }
    if n == 0 {
        return Err(SimError::Backend(format!(
            "CUDA backend (device {}): no particles",
            part.device
        )));
    }
    if part.ids.as_ref().is_some_and(|ids| ids.len() != n) {
        return Err(SimError::Backend(
            "CUDA backend: one id per particle".into(),
        ));
    }
    if matches!(o.p2g, P2gMode::ReverseMap | P2gMode::Sort)
        && scene.solver.transfer != Transfer::Mls
    {
        return Err(SimError::Backend(format!(
            "CUDA backend: p2g={} gathers MLS-MPM contributions only; the scene's [solver] \
             transfer is \"{}\": use p2g=warp (the default) or p2g=shared",
            o.p2g.name(),
            scene.solver.transfer.name()
        )));
    }
    Ok(())
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
        Self::build(scene, Initial::Particles(particles), part, options)
    }

    /// Upload the particles of sampled bodies
    /// ([`rtmpm_core::scene::sampling::sample_bodies`]) to device 0, packed straight from their
    /// positions: the same state as [`CudaBackend::new`] with `scene.sample_particles()`,
    /// without the host holding those particles (issue 19: 129 instead of 254 bytes a particle
    /// at the host's peak).
    pub fn from_bodies(
        scene: &Scene,
        bodies: &[SampledBody],
        options: CudaOptions,
    ) -> Result<CudaBackend, SimError> {
        Self::build(scene, Initial::Bodies(bodies), &Part::default(), options)
    }

    fn build(
        scene: &Scene,
        initial: Initial,
        part: &Part,
        options: CudaOptions,
    ) -> Result<CudaBackend, SimError> {
        let t0 = std::time::Instant::now();
        let mut setup = crate::setup::SetupPhases::default();
        let info = crate::probe_device(part.device).map_err(|e| {
            SimError::Backend(format!("CUDA device {} unavailable: {e}", part.device))
        })?;
        setup.probe = t0.elapsed().as_secs_f64();
        // The scene's precision, or the `f64` switch: the whole pipeline in f64.
        let options = CudaOptions {
            f64: options.f64 || scene.precision == Precision::F64,
            ..options
        };
        // Deferred bodies are drawn by the device fill; every other path walks them here.
        let walked;
        let initial = match initial {
            Initial::Bodies(b)
                if (!options.device_fill || options.p2g == P2gMode::ReverseMap)
                    && b.iter().any(|b| matches!(b, SampledBody::Deferred(_))) =>
            {
                walked = crate::setup::sample::walked(b);
                Initial::Bodies(&walked)
            }
            other => other,
        };
        let n = initial.len();
        check(scene, n, part, &options)?;
        let state_layout = crate::state::layout_for(scene, &options)
            .map_err(|e| SimError::Backend(format!("CUDA backend: {e}")))?;
        crate::backend::emit::check(scene, options.p2g)?;
        let tables = encode::tables(scene, options.f64)?;
        // The device fill (sampled bodies only): the table's checks before any GPU work.
        let device_fill = match initial {
            Initial::Bodies(b) if options.device_fill => {
                let fluid = crate::state::fluid_materials(scene);
                crate::setup::fill::table(b, &fluid, state_layout, options.f64)
                    .map_err(SimError::Backend)?;
                true
            }
            _ => false,
        };
        let t = std::time::Instant::now();

        // The program, compiled for this GPU (or from the cache), and its kernels.
        // Capacities from the initial mapping (crate::setup::initial_blocks).
        let (bases, blocks) = crate::setup::initial_blocks(scene, initial, &options);
        // Room for every particle the emitters will add (crate::backend::emit): nothing grows later.
        let n_max = n.saturating_add(crate::backend::emit::emitted_total(scene));
        let cap = Capacity::plan_blocks(scene, n_max, part.capacity, blocks, &options);
        setup.layout = t.elapsed().as_secs_f64();
        // G2P2G where it applies (see CudaOptions::g2p2g): not when every step rebuilds (the
        // fused scatter would always be redone).
        let g2p2g = options.g2p2g
            && scene.solver.transfer == Transfer::Mls
            && options.p2g == P2gMode::Warp
            && options.free_zone
            && options.mixed_sort;
        let real_bytes = if options.f64 { 8 } else { 4 };
        // The plan against the GPU's free memory, before anything is allocated or compiled.
        let t = std::time::Instant::now();
        let context = CudaContext::new(part.device).map_err(err("context"))?;
        let planned = buffers::sizes(
            scene,
            &cap,
            real_bytes,
            state_layout.words(),
            g2p2g,
            &options,
        );
        let (free, _) = context.mem_get_info().map_err(err("memory info"))?;
        let hint = match state_layout {
            StateLayout::Compact | StateLayout::CompactFluid => "",
            _ if options.f64 => ", f32 instead of f64",
            _ => ", the compact state ([solver] particle_state = \"compact\")",
        };
        let gpu = format!("GPU {} ({})", part.device, info.name);
        if let Some(why) =
            crate::setup::capacity::refusal(&planned, cap.particles, free, &gpu, hint)
        {
            return Err(SimError::Backend(why));
        }
        setup.probe += t.elapsed().as_secs_f64();
        let t = std::time::Instant::now();

        // Compiled for this GPU, the state's index width (64 bits past 2^32 words), and with
        // specialize=on the scene's models only (a smaller material switch).
        let ptx = compile(&KernelOptions {
            state64: crate::compile::state_needs_64_bits(state_layout.words(), cap.particles),
            layout: state_layout,
            arch: info.compute_capability,
            fast_math: options.fast_math,
            f64: options.f64,
            materials: if options.specialize {
                scene
                    .materials
                    .iter()
                    .fold(0u32, |m, mat| m | 1 << mat.model.code())
            } else {
                u32::MAX
            },
        })
        .map_err(SimError::Backend)?;
        // Single stream: no cross-stream event tracking (keeps launches capturable).
        // SAFETY: all our buffers are used on `stream` only.
        unsafe { context.disable_event_tracking() };
        let stream = context.new_stream().map_err(err("stream"))?;
        let module = context
            .load_module(cudarc::nvrtc::Ptx::from_src(ptx))
            .map_err(err("load module"))?;
        let mut kernels = Kernels::load(
            &module,
            info.sm_count,
            options.fused_rebuild,
            options.sort_scratch_fields,
            state_layout,
        )?;
        setup.kernels = t.elapsed().as_secs_f64();

        // The particle state (a fluid's F packed as J^(1/3) I) and every buffer.
        let fluid = crate::state::fluid_materials(scene);
        kernels.sort_mask =
            crate::step::rebuild::sorted_fields(state_layout, fluid.iter().all(|f| *f));
        // Packed with stride n; buffers::allocate places each field at its stride-cap offset.
        // With the device fill nothing is packed: the state is written on the device below.
        let t = std::time::Instant::now();
        let state = match initial {
            _ if device_fill => None,
            Initial::Particles(p) => Some(crate::state::pack(
                p,
                &fluid,
                state_layout,
                options.f64,
                n,
                part.ids.as_deref(),
            )),
            Initial::Bodies(b) => Some(crate::state::pack_bodies(
                b,
                &fluid,
                state_layout,
                options.f64,
            )),
        }
        .transpose()
        .map_err(SimError::Backend)?;
        setup.pack = t.elapsed().as_secs_f64();
        let needs = buffers::Needs {
            particles: n,
            real_bytes,
            state_words: state_layout.words(),
            grid_next: g2p2g,
            // NaN speeds are left to the health check of the first step.
            initial_speed: match initial {
                Initial::Particles(p) => p.v.iter().map(|v| v.length()).fold(0.0, f32::max),
                Initial::Bodies(b) => crate::state::max_speed(b),
            },
        };
        let t = std::time::Instant::now();
        let (mut buffers, mut ctx) = buffers::allocate(
            &stream,
            scene,
            state.as_deref(),
            &cap,
            needs,
            &tables,
            &options,
        )?;
        drop(state);
        stream.synchronize().map_err(err("upload"))?;
        setup.allocate = t.elapsed().as_secs_f64();
        if let (true, Initial::Bodies(b)) = (device_fill, initial) {
            let f = crate::setup::fill::fill(
                &stream,
                &kernels,
                &mut buffers.state,
                cap.particles,
                b,
                &fluid,
                state_layout,
                options.f64,
            )?;
            (setup.fill, setup.fill_gather, setup.fill_count) = (f.total, f.gather, f.count);
        }
        let bodies = crate::step::rigid::Bodies::new(
            scene,
            &stream,
            options.rigid_overlap,
            tables.body_mesh.clone(),
        )?;
        if let Some(b) = &bodies {
            (ctx.bodies, ctx.body_exchange, ctx.n_bodies) = b.ctx_fields(&stream);
        }

        // Read-only parameters in constant memory (kernels/common.cuh).
        write_symbol(&module, &stream, "c_scalars", &tables.scalars)?;
        write_symbol(&module, &stream, "c_materials", &tables.materials)?;
        write_symbol(
            &module,
            &stream,
            "c_colliders",
            bytemuck::cast_slice(&tables.colliders),
        )?;

        let p2g = P2gPlan::new(&options, &bases, blocks.1, &cap, &stream, &ctx, real_bytes)?;
        Ok(CudaBackend {
            stream,
            kernels,
            ctx,
            options,
            p2g,
            module,
            buffers,
            all_fluid: fluid.iter().all(|f| *f),
            layout: state_layout,
            parity: 0,
            last_grid: 0,
            last_dt: None,
            last_params: None,
            scene: scene.clone(),
            n,
            staging: Default::default(),
            graphs: StepGraphs::default(),
            device_name: info.name,
            bodies,
            setup: crate::setup::SetupPhases {
                total: t0.elapsed().as_secs_f64(),
                ..setup
            },
        })
    }

    /// Where the time of building this backend went (probe, host layout, kernels, packing,
    /// allocation and upload, device fill).
    pub fn setup_phases(&self) -> crate::setup::SetupPhases {
        self.setup
    }

    /// Where each field of a particle is in the state arrays.
    pub fn state_layout(&self) -> StateLayout {
        self.layout
    }

    /// True when G2P and the next step's P2G run as one kernel (see [`CudaOptions::g2p2g`]).
    pub fn g2p2g(&self) -> bool {
        self.buffers.grid_next.is_some()
    }

    /// The read-only tables of the run (for tests of the encoding).
    pub fn tables(&self) -> Result<Tables, SimError> {
        encode::tables(&self.scene, self.options.f64)
    }

    /// The context of the coming step: with G2P2G the two grids swap roles every step.
    pub(crate) fn step_ctx(&self) -> Ctx {
        let mut c = self.ctx;
        if self.parity == 1 {
            std::mem::swap(&mut c.grid, &mut c.grid_next);
        }
        c
    }

    /// What a step of this backend is made of.
    pub(crate) fn plan(&self) -> StepPlan<'_> {
        StepPlan {
            p2g: &self.p2g,
            all_fluid: self.all_fluid,
        }
    }

    /// Enqueue one step with `hooks` (parameters already uploaded), up to `last`.
    pub(crate) fn enqueue(&self, hooks: &mut dyn Hooks, last: Stage) -> Result<(), SimError> {
        crate::step::enqueue_until(
            &self.kernels,
            &self.stream,
            &self.step_ctx(),
            &self.plan(),
            hooks,
            last,
        )
    }

    /// After enqueuing a step: the next one reads the other grid (G2P2G).
    pub(crate) fn end_step(&mut self) {
        self.last_grid = self.parity;
        if self.g2p2g() {
            self.parity ^= 1;
        }
    }

    /// Enqueue one step with `hooks`, from the graph captured for this grid parity and dt when
    /// `graph` (the modes that time stages or wait on the host run without). With rigid bodies
    /// their states go up before the step and their impulses come back after it (a wait for the
    /// step, [`crate::step::rigid`]).
    pub(crate) fn run_step(
        &mut self,
        dt: f32,
        hooks: &mut dyn Hooks,
        graph: bool,
    ) -> Result<(), SimError> {
        if let Some(b) = self.bodies.as_mut() {
            b.upload(&self.module, &self.stream)?;
        }
        self.enqueue_graph_or_not(dt, hooks, graph)?;
        if let Some(b) = self.bodies.as_mut() {
            b.after_step(&self.stream, dt)?;
        }
        Ok(())
    }

    fn enqueue_graph_or_not(
        &mut self,
        dt: f32,
        hooks: &mut dyn Hooks,
        graph: bool,
    ) -> Result<(), SimError> {
        let r = if graph && self.options.graph {
            let mut graphs = std::mem::take(&mut self.graphs);
            let r = graphs.run(&self.stream, self.parity, dt, || {
                self.enqueue(hooks, Stage::G2p)
            });
            self.graphs = graphs;
            r
        } else {
            self.enqueue(hooks, Stage::G2p)
        };
        self.end_step();
        r
    }

    /// Drop the captured steps (before buffers they use change, or their hooks' resources go).
    pub(crate) fn clear_graphs(&mut self) {
        self.graphs.clear();
    }

    /// Upload the step parameters (async on the compute stream). No kernel reads `t` itself
    /// (colliders are posed on the host, damping is a factor), so a step whose parameters and
    /// collider poses equal the last upload's needs no copy: scenes without moving colliders or
    /// damping upload once, not every step.
    pub(crate) fn upload_params(&mut self, dt: f32, t: f32) -> Result<(), SimError> {
        let f64 = self.options.f64;
        let key = (
            encode::step_bytes(&self.scene, dt, t, f64, true),
            encode::poses(&self.scene, t),
        );
        if self.last_params.as_ref() == Some(&key) {
            return Ok(());
        }
        let step = encode::step_bytes(&self.scene, dt, t, f64, false);
        let s = &self.stream;
        s.memcpy_htod(&step, &mut self.buffers.step.slice_mut(..step.len()))
            .map_err(err("upload step parameters"))?;
        s.memcpy_htod(bytemuck::bytes_of(&key.1), &mut self.buffers.poses)
            .map_err(err("upload collider poses"))?;
        write_symbol(&self.module, s, "c_step", &step)?;
        write_symbol(&self.module, s, "c_poses", bytemuck::bytes_of(&key.1))?;
        self.last_params = Some(key);
        // G2P2G: the last fused scatter used the old dt in the stress term; redo this step's P2G.
        if self.g2p2g() && self.last_dt.is_some_and(|d| d != dt) {
            self.set_ctl_word(CTL_P2G_PENDING, 1)?;
        }
        self.last_dt = Some(dt);
        Ok(())
    }

    /// Enqueue only rebuild + P2G with the given dt (for tests of P2G conservation).
    pub fn run_p2g_only(&mut self, dt: f32) -> Result<(), SimError> {
        self.upload_params(dt, 0.0)?;
        self.last_grid = self.parity;
        let last = Stage::P2g(self.p2g.phases().len() - 1);
        self.enqueue(&mut NoHooks, last)
    }

    /// Number of particles on this GPU.
    pub fn len(&self) -> usize {
        self.n
    }

    /// True when it holds no particle (never: construction refuses that).
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }
}
