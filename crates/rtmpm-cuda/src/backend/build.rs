//! Building a [`CudaBackend`], in the order it happens: the checks and the host's plan before
//! any GPU work ([`Plan`]: precision, state layout, tables, capacities), the plan against the
//! GPU's free memory, the program (compiled for this GPU, or from the cache), the particle state
//! and every buffer (packed on the host, or filled on the device), the rigid bodies, the
//! read-only parameters in constant memory and the P2G strategy. Each phase is timed into
//! [`SetupPhases`].

use super::{CudaBackend, Part};
use crate::backend::emit;
use crate::compile::image::{Image, compile_image};
use crate::compile::{KernelOptions, compile, state_needs_64_bits};
use crate::contract::{Ctx, StateLayout};
use crate::encode::{self, Tables};
use crate::error::err;
use crate::kernels::{Kernels, write_symbol};
use crate::options::{CkP2g, CudaOptions, KernelSet, P2gMode};
use crate::probe::DeviceInfo;
use crate::setup::buffers::{self, Buffers};
use crate::setup::capacity::{self, Capacity};
use crate::setup::{Initial, SetupPhases, fill, initial_blocks, sample};
use crate::state;
use crate::step::graph::StepGraphs;
use crate::step::p2g::P2gPlan;
use crate::step::rebuild::sorted_fields;
use crate::step::rigid::{Bodies, BodyLink};
use cudarc::driver::{CudaContext, CudaModule, CudaStream};
use rtmpm_physics::math::IVec3;
use rtmpm_physics::transfer::Transfer;
use rtmpm_scene::sampling::SampledBody;
use rtmpm_scene::{Precision, Scene};
use rtmpm_sim::SimError;
use std::sync::Arc;
use std::time::Instant;

impl CudaBackend {
    /// Build the backend of one GPU (`part`) for `scene`, starting from `initial`.
    pub(super) fn build(
        scene: &Scene,
        initial: Initial,
        part: &Part,
        options: CudaOptions,
    ) -> Result<CudaBackend, SimError> {
        Self::build_for(scene, initial, part, options, false)
    }

    /// [`CudaBackend::build`]; `batch`: the merged scene of a batch of worlds
    /// ([`crate::batch`]): the kernels compiled with `RTMPM_BATCH`, any number of materials.
    pub(crate) fn build_for(
        scene: &Scene,
        initial: Initial,
        part: &Part,
        options: CudaOptions,
        batch: bool,
    ) -> Result<CudaBackend, SimError> {
        let t0 = Instant::now();
        let mut setup = SetupPhases::default();
        let info = crate::probe::probe_device(part.device).map_err(|e| {
            SimError::Backend(format!("CUDA device {} unavailable: {e}", part.device))
        })?;
        setup.probe = t0.elapsed().as_secs_f64();
        // The scene's precision, or the `f64` switch: the whole pipeline in f64.
        let options = CudaOptions {
            f64: options.f64 || scene.precision == Precision::F64,
            ..options
        };
        // Deferred bodies are drawn by the device fill; every other path walks them here.
        let walked = walked_on_the_host(initial, &options);
        let initial = match &walked {
            Some(w) => Initial::Bodies(w),
            None => initial,
        };
        let plan = Plan::new(scene, initial, part, options, batch, &mut setup)?;

        // The plan against the GPU's free memory, before anything is allocated or compiled.
        let t = Instant::now();
        let context = CudaContext::new(part.device).map_err(err("context"))?;
        plan.refuse_past_free_memory(scene, &context, part, &info)?;
        setup.probe += t.elapsed().as_secs_f64();

        let t = Instant::now();
        let (stream, module, kernels) = plan.load_program(scene, &context, &info)?;
        setup.kernels = t.elapsed().as_secs_f64();

        let (buffers, mut ctx) =
            plan.state_and_buffers(scene, initial, part, &stream, &kernels, &mut setup)?;
        // One GPU moves its bodies itself; a GPU of several (`part.ids`) only couples them:
        // they move in the one rapier world of the multi-GPU backend (crate::multi::threaded).
        let (bodies, body_link) = if part.ids.is_none() {
            let b = Bodies::new(
                scene,
                &stream,
                plan.options.rigid_overlap,
                plan.tables.body_mesh.clone(),
            )?;
            (b, None)
        } else if scene.rigid_bodies.is_empty() {
            (None, None)
        } else {
            let n = scene.rigid_bodies.len();
            let link = BodyLink::new(&stream, n, plan.tables.body_mesh.clone())?;
            (None, Some(link))
        };
        if let Some(b) = &bodies {
            (ctx.bodies, ctx.body_exchange, ctx.n_bodies) = b.ctx_fields(&stream);
        }
        if let Some(l) = &body_link {
            (ctx.bodies, ctx.body_exchange, ctx.n_bodies) = l.ctx_fields(&stream);
        }
        write_constants(&module, &stream, &plan.tables)?;
        let p2g = P2gPlan::new(
            &plan.options,
            &plan.bases,
            plan.blocks.1,
            &plan.cap,
            &stream,
            &ctx,
            plan.real_bytes,
        )?;
        let all_fluid = plan.all_fluid();
        Ok(CudaBackend {
            stream,
            kernels,
            ctx,
            options: plan.options,
            p2g,
            module,
            buffers,
            all_fluid,
            layout: plan.layout,
            parity: 0,
            body_table: 0,
            last_grid: 0,
            last_dt: None,
            last_params: None,
            scene: scene.clone(),
            n: plan.n,
            staging: Default::default(),
            graphs: StepGraphs::default(),
            device_name: info.name,
            bodies,
            body_link,
            setup: SetupPhases {
                total: t0.elapsed().as_secs_f64(),
                ..setup
            },
            render: None,
            tool: None,
            waits: Default::default(),
            check_copies: Default::default(),
            params_staging: crate::staging::StagingRing::new(super::PARAMS_BUFFERS, 4),
        })
    }
}

/// More particles than the CUDA backend indexes: the health check's control word holds
/// `index << 1 | reason` below `u32::MAX` ([`crate::contract::bad_particle`]).
const MAX_CUDA_PARTICLES: usize = (1 << 31) - 1;

/// Checks before any GPU work: what the CUDA backend cannot run, as clear errors.
fn check(scene: &Scene, n: usize, part: &Part, o: &CudaOptions) -> Result<(), SimError> {
    if o.f64 && o.p2g == P2gMode::Shared {
        return Err(SimError::Backend(
            "CUDA backend: p2g=shared is single precision only (a 12^3 tile of f64 nodes \
             exceeds the 48 KiB of static shared memory); use p2g=warp with f64"
                .into(),
        ));
    }
    if n == 0 {
        return Err(SimError::Backend(format!(
            "CUDA backend (device {}): no particles",
            part.device
        )));
    }
    if n >= MAX_CUDA_PARTICLES {
        return Err(SimError::Backend(format!(
            "CUDA backend: {n} particles, more than the {} it indexes (the health check keeps \
             a particle's index in 31 bits); use a larger dx or fewer particles per cell",
            MAX_CUDA_PARTICLES - 1
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

/// What the CUDA backend's CK-MPM (`[solver] transfer = "ck-mpm"`, one GPU: the two grids'
/// kernels `p2g_ck`, the grid update, `g2p_ck`) does not run yet, as clear errors: rigid bodies
/// (the CPU backend refuses them too), several GPUs and a batch of worlds.
fn check_ck_mpm(scene: &Scene, part: &Part, batch: bool) -> Result<(), SimError> {
    if scene.solver.transfer != Transfer::CkMpm {
        return Ok(());
    }
    let what = if !scene.rigid_bodies.is_empty() {
        "does not couple [[rigid_body]] tables to its two grids yet; use transfer = \"mls\" (the \
         default) with rigid bodies"
    } else if part.ids.is_some() {
        "runs on one GPU only so far; use --gpus 1 (or transfer = \"mls\", the default, on \
         several GPUs)"
    } else if batch {
        "runs one world per GPU only so far; run the batch with --backend cpu (or transfer = \
         \"mls\", the default)"
    } else {
        return Ok(());
    };
    Err(SimError::Backend(format!(
        "CUDA backend: [solver] transfer = \"ck-mpm\" {what}"
    )))
}

/// The bodies of `initial` with every deferred body walked on the host, when the host needs
/// their positions (no device fill, or the reverse map's stencil bases); `None`: as they are.
fn walked_on_the_host(initial: Initial, options: &CudaOptions) -> Option<Vec<SampledBody>> {
    match initial {
        Initial::Bodies(b)
            if (!options.device_fill || options.p2g == P2gMode::ReverseMap)
                && b.iter().any(|b| matches!(b, SampledBody::Deferred(_))) =>
        {
            Some(sample::walked(b))
        }
        _ => None,
    }
}

/// What the host decides before any GPU work.
struct Plan {
    /// The options, in the scene's precision.
    options: CudaOptions,
    /// Particles at the start.
    n: usize,
    /// Where each field of a particle is in the state arrays.
    layout: StateLayout,
    /// The read-only tables (materials, colliders, meshes).
    tables: Tables,
    /// The state is filled on the device from the sampled bodies ([`crate::setup::fill`]).
    device_fill: bool,
    /// The initial particles' stencil bases (`p2g=reverse_map` only) and the initial
    /// mapping's (gblocks, pblocks): [`initial_blocks`].
    bases: Vec<IVec3>,
    blocks: (usize, usize),
    /// Every buffer's capacity.
    cap: Capacity,
    /// G2P and the next step's P2G run as one kernel (a second grid).
    g2p2g: bool,
    /// Bytes of a `real`: 4, or 8 in f64.
    real_bytes: usize,
    /// One entry per material: true for a fluid.
    fluid: Vec<bool>,
    /// The merged scene of a batch of worlds (`RTMPM_BATCH`).
    batch: bool,
}

impl Plan {
    /// The checks, the state layout, the tables, and the capacities from the initial mapping
    /// (timed as `setup.layout`).
    fn new(
        scene: &Scene,
        initial: Initial,
        part: &Part,
        options: CudaOptions,
        batch: bool,
        setup: &mut SetupPhases,
    ) -> Result<Plan, SimError> {
        let n = initial.len();
        check(scene, n, part, &options)?;
        check_ck_mpm(scene, part, batch)?;
        let layout = state::layout_for(scene, &options)
            .map_err(|e| SimError::Backend(format!("CUDA backend: {e}")))?;
        emit::check(scene, options.p2g)?;
        let tables = if batch {
            encode::batch_tables(scene, options.f64)?
        } else {
            encode::tables(scene, options.f64)?
        };
        let fluid = state::fluid_materials(scene);
        // The device fill (sampled bodies only): the table's checks before any GPU work.
        let device_fill = match initial {
            Initial::Bodies(b) if options.device_fill => {
                fill::table(b, &fluid, layout, options.f64).map_err(SimError::Backend)?;
                true
            }
            _ => false,
        };
        let t = Instant::now();
        // Capacities from the initial mapping.
        let (bases, blocks) = initial_blocks(scene, initial, &options);
        // Room for every particle the emitters will add (crate::backend::emit): nothing grows
        // later.
        let n_max = n.saturating_add(emit::emitted_total(scene));
        let cap = Capacity::plan_blocks(scene, n_max, part.capacity, blocks, &options);
        setup.layout = t.elapsed().as_secs_f64();
        // G2P2G where it applies (see CudaOptions::g2p2g; CK-MPM with ck_p2g=fused only): not
        // when every step rebuilds (the
        // fused scatter would always be redone).
        let g2p2g = options.g2p2g
            && (scene.solver.transfer == Transfer::Mls
                || (scene.solver.transfer == Transfer::CkMpm && options.ck_p2g == CkP2g::Fused))
            && options.p2g == P2gMode::Warp
            && options.free_zone
            && options.mixed_sort;
        let real_bytes = if options.f64 { 8 } else { 4 };
        Ok(Plan {
            options,
            n,
            layout,
            tables,
            device_fill,
            bases,
            blocks,
            cap,
            g2p2g,
            real_bytes,
            fluid,
            batch,
        })
    }

    /// Every material is a fluid.
    fn all_fluid(&self) -> bool {
        self.fluid.iter().all(|f| *f)
    }

    /// The planned buffers against the free memory of the GPU: a clear error, naming what
    /// fits and what would make it fit, when they exceed it.
    fn refuse_past_free_memory(
        &self,
        scene: &Scene,
        context: &Arc<CudaContext>,
        part: &Part,
        info: &DeviceInfo,
    ) -> Result<(), SimError> {
        let planned = buffers::sizes(
            scene,
            &self.cap,
            self.real_bytes,
            self.layout.words(),
            self.g2p2g,
            &self.options,
        );
        let (free, _) = context.mem_get_info().map_err(err("memory info"))?;
        let hint = match self.layout {
            StateLayout::Compact | StateLayout::CompactFluid => "",
            _ if self.options.f64 => ", f32 instead of f64",
            _ => ", the compact state ([solver] particle_state = \"compact\")",
        };
        let gpu = format!("GPU {} ({})", part.device, info.name);
        match capacity::refusal(&planned, self.cap.particles, free, &gpu, hint) {
            Some(why) => Err(SimError::Backend(why)),
            None => Ok(()),
        }
    }

    /// The program's compile options for a GPU of compute capability `arch`: the state's index
    /// width (64 bits past 2^32 words), with specialize=on the scene's models only (a smaller
    /// material switch), the fused kernels' code switches of this backend's kernel set
    /// (`fused_defaults=auto` gives the fluid set its own), and `pdl` ([`pdl_on`]).
    fn kernel_options(&self, scene: &Scene, arch: (i32, i32), pdl: bool) -> KernelOptions {
        let o = &self.options;
        let code = o
            .fused
            .resolve(KernelSet::of(self.all_fluid(), scene.solver.transfer));
        KernelOptions {
            state64: code.wide_state_index
                || state_needs_64_bits(self.layout.words(), self.cap.particles),
            layout: self.layout,
            arch,
            fast_math: o.fast_math,
            f64: o.f64,
            materials: if o.specialize {
                scene
                    .materials
                    .iter()
                    .fold(0u32, |m, mat| m | 1 << mat.model.code())
            } else {
                u32::MAX
            },
            batch: self.batch,
            ck_min_blocks: o.ck_min_blocks,
            stencil_pairs: o.stencil_pairs,
            uniform_loop: o.uniform_loop,
            row_unroll: code.row_unroll.define(),
            cuts: code.cuts,
            pdl,
        }
    }

    /// The program, compiled for this GPU (or read from the cache), its module loaded on the
    /// backend's one stream, and its kernels.
    fn load_program(
        &self,
        scene: &Scene,
        context: &Arc<CudaContext>,
        info: &DeviceInfo,
    ) -> Result<(Arc<CudaStream>, Arc<CudaModule>, Kernels), SimError> {
        let pdl = pdl_on(&self.options, info);
        let o = self.kernel_options(scene, info.compute_capability, pdl);
        let image = compile_image(&o).map_err(SimError::Backend)?;
        // Single stream: no cross-stream event tracking (keeps launches capturable).
        // SAFETY: all our buffers are used on `stream` only.
        unsafe { context.disable_event_tracking() };
        let stream = context.new_stream().map_err(err("stream"))?;
        let module = load_module(context, image, &o)?;
        let mut kernels = Kernels::load(&module, info.sm_count, &self.options, self.layout)?;
        kernels.sort_mask = sorted_fields(self.layout, self.all_fluid());
        kernels.pdl = pdl;
        Ok((stream, module, kernels))
    }

    /// The particle state (a fluid's F packed as J^(1/3) I) and every buffer: the state packed
    /// on the host and uploaded with the buffers, or, with the device fill, filled on the
    /// device once they are allocated (timed as `setup.pack`, `allocate` and `fill`).
    fn state_and_buffers(
        &self,
        scene: &Scene,
        initial: Initial,
        part: &Part,
        stream: &Arc<CudaStream>,
        kernels: &Kernels,
        setup: &mut SetupPhases,
    ) -> Result<(Buffers, Ctx), SimError> {
        let t = Instant::now();
        let state = self.pack(initial, part)?;
        setup.pack = t.elapsed().as_secs_f64();
        let needs = buffers::Needs {
            particles: self.n,
            real_bytes: self.real_bytes,
            state_words: self.layout.words(),
            grid_next: self.g2p2g,
            // NaN speeds are left to the health check of the first step.
            initial_speed: match initial {
                Initial::Particles(p) => p.v.iter().map(|v| v.length()).fold(0.0, f32::max),
                Initial::Bodies(b) => state::max_speed(b),
            },
        };
        let t = Instant::now();
        let (mut buffers, ctx) = buffers::allocate(
            stream,
            scene,
            state.as_deref(),
            &self.cap,
            needs,
            &self.tables,
            &self.options,
        )?;
        drop(state);
        stream.synchronize().map_err(err("upload"))?;
        setup.allocate = t.elapsed().as_secs_f64();
        if let (true, Initial::Bodies(b)) = (self.device_fill, initial) {
            let f = fill::fill(
                stream,
                kernels,
                &mut buffers.state,
                self.cap.particles,
                b,
                &self.fluid,
                self.layout,
                self.options.f64,
            )?;
            (setup.fill, setup.fill_gather, setup.fill_count) = (f.total, f.gather, f.count);
        }
        Ok((buffers, ctx))
    }

    /// The state image packed on the host with stride n ([`buffers::allocate`] places each
    /// field at its stride-cap offset); `None` with the device fill (nothing is packed: the
    /// state is written on the device).
    fn pack(&self, initial: Initial, part: &Part) -> Result<Option<Vec<u8>>, SimError> {
        let (fluid, layout, f64) = (&self.fluid, self.layout, self.options.f64);
        match initial {
            _ if self.device_fill => None,
            Initial::Particles(p) => Some(state::pack(
                p,
                fluid,
                layout,
                f64,
                self.n,
                part.ids.as_deref(),
            )),
            Initial::Bodies(b) => Some(state::pack_bodies(b, fluid, layout, f64)),
        }
        .transpose()
        .map_err(SimError::Backend)
    }
}

/// The read-only parameters in constant memory (`kernels/common.cuh`).
fn write_constants(
    module: &Arc<CudaModule>,
    stream: &Arc<CudaStream>,
    tables: &Tables,
) -> Result<(), SimError> {
    write_symbol(module, stream, "c_scalars", &tables.scalars)?;
    write_symbol(module, stream, "c_materials", &tables.materials)?;
    write_symbol(
        module,
        stream,
        "c_colliders",
        bytemuck::cast_slice(&tables.colliders),
    )
}

/// Whether the step launches with programmatic dependent launch: `pdl=on` on a GPU of compute
/// capability 9.0 or newer; on an older one the switch is ignored, with a warning.
fn pdl_on(o: &CudaOptions, info: &DeviceInfo) -> bool {
    if o.pdl && !crate::compile::pdl_supported(info.compute_capability) {
        let (major, minor) = info.compute_capability;
        eprintln!(
            "rtmpm: warning: --cuda-options pdl=on ignored: programmatic dependent launch needs \
             compute capability 9.0 or newer (Hopper), {} is {major}.{minor}",
            info.name
        );
    }
    o.pdl && crate::compile::pdl_supported(info.compute_capability)
}

/// `image` loaded into `context`: a cubin as it is; should the driver refuse a cubin (one not
/// made for this GPU after all), the PTX of `o` instead, which the driver compiles.
fn load_module(
    context: &Arc<CudaContext>,
    image: Image,
    o: &KernelOptions,
) -> Result<Arc<CudaModule>, SimError> {
    let kind = image.kind();
    match context.load_module(image.into_module_source()) {
        Ok(m) => Ok(m),
        Err(e) if kind == "cubin" => {
            eprintln!("warning: the driver refused the kernels' cubin ({e:?}); loading their PTX");
            let ptx = compile(o).map_err(SimError::Backend)?;
            context
                .load_module(cudarc::nvrtc::Ptx::from_src(ptx))
                .map_err(err("load module"))
        }
        Err(e) => Err(err("load module")(e)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::options::{FusedCode, KernelCuts, RowUnroll};

    fn free_fall() -> Scene {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../validation/free_fall.toml"
        );
        Scene::from_file(std::path::Path::new(path)).expect("scene")
    }

    fn one_gpu() -> Part {
        Part {
            device: 0,
            ids: None,
            capacity: 0,
        }
    }

    #[test]
    fn ck_mpm_runs_on_one_gpu_and_refuses_what_it_does_not_support() {
        let mut scene = free_fall();
        scene.solver.transfer = Transfer::CkMpm;
        let o = CudaOptions::default();
        assert!(check(&scene, 10, &one_gpu(), &o).is_ok());
        assert!(check_ck_mpm(&scene, &one_gpu(), false).is_ok());
        // Several GPUs, a batch of worlds: refused with the fix.
        let several = Part {
            ids: Some((0..10).collect()),
            ..one_gpu()
        };
        let msg = check_ck_mpm(&scene, &several, false)
            .expect_err("ck-mpm on several GPUs")
            .to_string();
        assert!(msg.contains("ck-mpm") && msg.contains("--gpus 1"), "{msg}");
        let msg = check_ck_mpm(&scene, &one_gpu(), true)
            .expect_err("ck-mpm batch")
            .to_string();
        assert!(
            msg.contains("ck-mpm") && msg.contains("--backend cpu"),
            "{msg}"
        );
        // The gathers of p2g= collect MLS-MPM contributions only.
        for p2g in [P2gMode::ReverseMap, P2gMode::Sort] {
            let o = CudaOptions {
                p2g,
                ..CudaOptions::default()
            };
            let msg = check(&scene, 10, &one_gpu(), &o)
                .expect_err("gather with ck-mpm")
                .to_string();
            assert!(msg.contains("ck-mpm") && msg.contains("p2g=warp"), "{msg}");
        }
        // The other transfers are not concerned.
        scene.solver.transfer = Transfer::Mls;
        assert!(check_ck_mpm(&scene, &several, true).is_ok());
    }

    /// The plan of `scene` (in validation/) with `options`, no GPU needed.
    fn plan_of(file: &str, options: &str) -> (Scene, Plan) {
        let path = format!("{}/../../validation/{file}", env!("CARGO_MANIFEST_DIR"));
        let scene = Scene::from_file(std::path::Path::new(&path)).expect("scene");
        let p = scene.sample_particles().expect("particles");
        let o: CudaOptions = options.parse().expect("options");
        let mut setup = SetupPhases::default();
        let plan = Plan::new(
            &scene,
            Initial::Particles(&p),
            &one_gpu(),
            o,
            false,
            &mut setup,
        )
        .expect("plan");
        (scene, plan)
    }

    /// `fused_defaults=auto` compiles the water scene's program (the fluid kernel set) with
    /// `row_unroll=planes` and the cuts but `lean_lanes`, and the jelly scene's and a CK-MPM
    /// water scene's (the general set) as `off` does; explicit switches reach every program.
    #[test]
    fn the_fused_switches_reach_the_program_of_the_scenes_kernel_set() {
        let tuned = |k: &KernelOptions| {
            (k.row_unroll, k.cuts, k.state64)
                == (
                    RowUnroll::Planes.define(),
                    FusedCode::FLUID_TUNED.cuts,
                    true,
                )
        };
        let arch = (9, 0);
        let (water, w) = plan_of("dam_break.toml", "fused_defaults=auto");
        assert!(w.all_fluid());
        assert!(tuned(&w.kernel_options(&water, arch, false)));
        let (water_off, w_off) = plan_of("dam_break.toml", "fused_defaults=off");
        let today = w_off.kernel_options(&water_off, arch, false);
        assert_eq!(
            (today.row_unroll, today.cuts, today.state64),
            (0, KernelCuts::default(), false)
        );
        let (jelly, j) = plan_of("free_fall.toml", "fused_defaults=auto");
        assert!(!j.all_fluid());
        let (jelly_off, j_off) = plan_of("free_fall.toml", "fused_defaults=off");
        assert_eq!(
            j.kernel_options(&jelly, arch, false),
            j_off.kernel_options(&jelly_off, arch, false)
        );
        let (mut ck, _) = plan_of("dam_break.toml", "fused_defaults=auto");
        ck.solver.transfer = Transfer::CkMpm;
        let c = Plan::new(
            &ck,
            Initial::Particles(&ck.sample_particles().expect("particles")),
            &one_gpu(),
            "fused_defaults=auto".parse().expect("options"),
            false,
            &mut SetupPhases::default(),
        )
        .expect("ck-mpm plan");
        assert!(!tuned(&c.kernel_options(&ck, arch, false)));
        // Last session's comparison line: the same program switches for the jelly as for the water.
        let ab = "row_unroll=planes,seg_clamp=on,zero_terms=skip,flat_checks=on,state_index=wide";
        let (jelly_ab, j_ab) = plan_of("free_fall.toml", ab);
        assert!(tuned(&j_ab.kernel_options(&jelly_ab, arch, false)));
    }

    #[cfg(feature = "rigid")]
    #[test]
    fn ck_mpm_refuses_rigid_bodies() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../validation/archimedes.toml"
        );
        let mut scene = Scene::from_file(std::path::Path::new(path)).expect("scene");
        assert!(!scene.rigid_bodies.is_empty());
        scene.solver.transfer = Transfer::CkMpm;
        let msg = check_ck_mpm(&scene, &one_gpu(), false)
            .expect_err("ck-mpm with rigid bodies")
            .to_string();
        assert!(
            msg.contains("ck-mpm") && msg.contains("rigid_body") && msg.contains("\"mls\""),
            "{msg}"
        );
    }
}
