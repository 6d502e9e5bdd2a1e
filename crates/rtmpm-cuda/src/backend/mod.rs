//! [`CudaBackend`]: the CUDA backend on one GPU, and the simulation's [`Backend`] on it.
//!
//! Built in [`build`] (checks, the plan against the GPU's free memory, the program, the state
//! and every buffer, the rigid bodies, the constants, the P2G strategy). A step uploads its
//! parameters when they change and enqueues [`crate::step::enqueue_until`], replayed from a
//! CUDA graph ([`crate::step::graph`]) while dt stays the same. What the host reads back is in
//! [`readback`], the particles emitters add in [`emit`], per-stage timing in [`bench`]; the
//! state for other libraries in [`crate::export`].

use crate::contract::{CTL_P2G_PENDING, ColliderPoses, Ctx, StateLayout};
use crate::encode::{self, Tables};
use crate::error::err;
use crate::kernels::{Kernels, write_symbol};
use crate::options::CudaOptions;
use crate::setup::{Initial, SetupPhases, buffers};
use crate::step::graph::StepGraphs;
use crate::step::p2g::P2gPlan;
use crate::step::rigid::{Bodies, loads_of, poses_of, set_poses_of, states_of};
use crate::step::{Hooks, NoHooks, Stage, StepPlan};
use cudarc::driver::{CudaModule, CudaSlice, CudaStream, PinnedHostSlice};
use rtmpm_physics::Particles;
use rtmpm_scene::Scene;
use rtmpm_scene::sampling::SampledBody;
use rtmpm_sim::{Backend, BadParticle, SimError};
use std::sync::Arc;

pub mod bench;
mod build;
mod check;
mod check_copies;
pub mod emit;
pub mod readback;

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
    pub(crate) module: Arc<CudaModule>,
    pub(crate) buffers: buffers::Buffers,
    /// Every material is a fluid: G2P2G runs its fluid variant (`g2p2g_fluid`).
    pub(crate) all_fluid: bool,
    /// Where each field of a particle is in the state arrays.
    pub(crate) layout: StateLayout,
    /// G2P2G: which grid the coming step reads (0: `grid`, 1: `grid_next`).
    parity: usize,
    /// Which of a batch's body tables `ctx` points at for the coming step (0 elsewhere; the
    /// batch's bodies take theirs in turn, `crate::batch::bodies`): a key of the step's graph.
    pub(crate) body_table: usize,
    /// The grid the last step (or P2G) wrote, read back by [`CudaBackend::grid_nodes`].
    pub(crate) last_grid: usize,
    /// G2P2G: dt of the last upload (a new dt asks for a P2G: the fused scatter used the old one).
    last_dt: Option<f32>,
    /// The step parameters and poses last uploaded, with `t` zeroed (see `upload_params`).
    last_params: Option<(Vec<u8>, ColliderPoses)>,
    pub(crate) scene: Scene,
    pub(crate) n: usize,
    /// Memory reused by the reads of [`crate::export`].
    pub(crate) staging: Staging,
    graphs: StepGraphs,
    device_name: String,
    /// The rigid bodies coupled to the grid (`[[rigid_body]]`), if any.
    pub(crate) bodies: Option<Bodies>,
    /// A GPU of several with rigid bodies: the device side of their coupling (the bodies move
    /// in the multi-GPU backend's world, which drives it, `crate::multi::rank`).
    pub(crate) body_link: Option<crate::step::rigid::BodyLink>,
    /// Where the time of building this backend went.
    setup: SetupPhases,
    /// The render stage's buffers (a live view), allocated at the first picture.
    pub(crate) render: Option<Box<RenderBuffers>>,
    /// The user's tool (its world shape), see `view/steer.rs`.
    pub(crate) tool: Option<rtmpm_geometry::Shape>,
    /// The host's waits for the device, by reason ([`crate::waits`]; shared with a batch's
    /// parts).
    pub(crate) waits: Arc<crate::waits::HostWaits>,
    /// The health check's words copied behind steps whose check was left for later
    /// ([`CudaBackend::queue_check`], `backend/check.rs`).
    pub(crate) check_copies: check_copies::CheckCopies,
    /// The page-locked memory the step parameters and collider poses go up through when they
    /// change (moving colliders: every step).
    params_staging: crate::staging::StagingRing,
}

/// Page-locked buffers of the step parameters' uploads at most (four uploads a change).
pub(crate) const PARAMS_BUFFERS: usize = 64;

/// Memory reused by [`CudaBackend::read_fields`] and [`CudaBackend::read_vec3_ordered`]:
/// pinned host memory, and the device array that the ordered export gathers into.
#[derive(Default)]
pub(crate) struct Staging {
    pub(crate) pinned: Option<PinnedHostSlice<u8>>,
    pub(crate) ordered: Option<CudaSlice<f32>>,
    pub(crate) bad: Option<CudaSlice<u32>>,
}

/// The device buffers of the render stage (`view/render.rs`), allocated at the first picture and
/// again when the image size changes.
pub(crate) struct RenderBuffers {
    pub(crate) width: u32,
    pub(crate) height: u32,
    /// A 64-bit depth key per pixel.
    pub(crate) keys: CudaSlice<u64>,
    /// RGB bytes (room for RGBA words).
    pub(crate) image: CudaSlice<u8>,
    /// The light's depth map.
    pub(crate) shadow: CudaSlice<u32>,
    /// The automatic range's words.
    pub(crate) scratch: CudaSlice<u32>,
    /// The picture's objects (colliders, bodies, tool).
    pub(crate) objects: CudaSlice<u8>,
    /// The palette (3 floats a material).
    pub(crate) palette: CudaSlice<f32>,
    /// f32 per particle slot (allocated the first time a picture is coloured by a field).
    pub(crate) field: Option<CudaSlice<f32>>,
    /// The image, for the host.
    pub(crate) pinned: PinnedHostSlice<u8>,
    /// The range found (f32 bits), for the host.
    pub(crate) range: PinnedHostSlice<u32>,
    /// Recorded after a picture's copies ([`CudaBackend::begin_picture`]).
    pub(crate) done: cudarc::driver::CudaEvent,
    /// The picture begun and not yet collected.
    pub(crate) pending: Option<PendingPicture>,
    /// The scene's mesh offsets: each collider's, each rigid body's.
    pub(crate) collider_mesh: Vec<u32>,
    pub(crate) body_mesh: Vec<u32>,
}

/// What [`CudaBackend::finish_picture`] needs of a picture begun: its size and colouring.
pub(crate) struct PendingPicture {
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) color_by: rtmpm_scene::ColorBy,
    pub(crate) range: Option<(f32, f32)>,
    pub(crate) auto_range: bool,
    pub(crate) label: Option<String>,
}

impl RenderBuffers {
    /// Device bytes of the render stage.
    pub(crate) fn bytes(&self) -> usize {
        self.keys.num_bytes()
            + self.image.num_bytes()
            + self.shadow.num_bytes()
            + self.scratch.num_bytes()
            + self.objects.num_bytes()
            + self.palette.num_bytes()
            + self.field.as_ref().map_or(0, |f| f.num_bytes())
    }
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
    /// ([`rtmpm_scene::sampling::sample_bodies`]) to device 0, packed straight from their
    /// positions: the same state as [`CudaBackend::new`] with `scene.sample_particles()`,
    /// without the host holding those particles (129 instead of 254 bytes a particle at the
    /// host's peak).
    pub fn from_bodies(
        scene: &Scene,
        bodies: &[SampledBody],
        options: CudaOptions,
    ) -> Result<CudaBackend, SimError> {
        Self::build(scene, Initial::Bodies(bodies), &Part::default(), options)
    }

    /// Where the time of building this backend went (probe, host layout, kernels, packing,
    /// allocation and upload, device fill).
    pub fn setup_phases(&self) -> SetupPhases {
        self.setup
    }

    /// Where each field of a particle is in the state arrays.
    pub fn state_layout(&self) -> StateLayout {
        self.layout
    }

    /// True when the step's kernels after its first are launched with programmatic dependent
    /// launch ([`CudaOptions::pdl`] asked for on a GPU of compute capability 9.0 or newer).
    pub fn pdl(&self) -> bool {
        self.kernels.pdl
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
            std::mem::swap(&mut c.grid_aux, &mut c.grid_aux_next);
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
            let key = (self.parity, self.body_table);
            let r = graphs.run(&self.stream, key, dt, || self.enqueue(hooks, Stage::G2p));
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
        if crate::waits::old_waits() {
            // Pageable copies (counted: the driver may wait for the stream to reach them).
            self.waits.wait(crate::waits::WaitReason::Pageable, || ());
            let s = &self.stream;
            s.memcpy_htod(&step, &mut self.buffers.step.slice_mut(..step.len()))
                .map_err(err("upload step parameters"))?;
            s.memcpy_htod(bytemuck::bytes_of(&key.1), &mut self.buffers.poses)
                .map_err(err("upload collider poses"))?;
            write_symbol(&self.module, s, "c_step", &step)?;
            write_symbol(&self.module, s, "c_poses", bytemuck::bytes_of(&key.1))?;
        } else {
            self.upload_params_staged(&step, bytemuck::bytes_of(&key.1))?;
        }
        self.last_params = Some(key);
        // G2P2G: the last fused scatter used the old dt in the stress term; redo this step's P2G.
        if self.g2p2g() && self.last_dt.is_some_and(|d| d != dt) {
            self.set_ctl_word(CTL_P2G_PENDING, 1)?;
        }
        self.last_dt = Some(dt);
        Ok(())
    }

    /// True when a step of `dt` will redo every world's P2G because its dt is not the last
    /// step's (G2P2G: the last fused scatter used the old dt; [`CudaBackend::upload_params`]).
    pub(crate) fn p2g_due_for(&self, dt: f32) -> bool {
        self.g2p2g() && self.last_dt.is_some_and(|d| d != dt)
    }

    /// The step parameters `step` and collider poses `poses` to their buffers and constant
    /// symbols through page-locked memory (`params_staging`: no wait for the steps queued ahead).
    fn upload_params_staged(&mut self, step: &[u8], poses: &[u8]) -> Result<(), SimError> {
        let (s, w) = (&self.stream, &*self.waits);
        let ring = &mut self.params_staging;
        ring.copy_to_device(s, step, &mut self.buffers.step, w)?;
        ring.copy_to_device(s, poses, &mut self.buffers.poses, w)?;
        for (name, bytes) in [("c_step", step), ("c_poses", poses)] {
            let mut sym = self
                .module
                .get_global(name, s)
                .map_err(|e| SimError::Backend(format!("CUDA: constant symbol {name}: {e:?}")))?;
            let len = bytes.len().min(sym.len());
            ring.copy_to_device(s, &bytes[..len], &mut sym, w)?;
        }
        Ok(())
    }

    /// Enqueue only rebuild + P2G with the given dt (for tests of P2G conservation).
    pub fn run_p2g_only(&mut self, dt: f32) -> Result<(), SimError> {
        self.upload_params(dt, 0.0)?;
        self.last_grid = self.parity;
        let last = Stage::P2g(self.p2g.phases().len() - 1);
        self.enqueue(&mut NoHooks, last)
    }

    /// The host's waits for the device so far, by reason ([`crate::waits`]).
    pub fn host_waits(&self) -> crate::waits::WaitCounts {
        self.waits.snapshot()
    }

    /// The rigid bodies' states now (none without `[[rigid_body]]`).
    pub fn rigid_body_states(&self) -> &[rtmpm_rigid::BodyState] {
        self.bodies.as_ref().map_or(&[], |b| b.states())
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

/// Pictures of a live view collected while the next steps run (a picture queued with an event,
/// the next steps queued behind it, the host waiting for that event only): on by default,
/// `RTMPM_VIEW_OVERLAP=0` draws and publishes each picture before the next step. Measured on an
/// H200 (bench/RESULTS.md, "Live view"): the streamed snow 1.33M steps 2.8 % slower than
/// without the view with the overlap, 23.7 % without. The CPU backend draws on the host and
/// never overlaps.
pub fn view_overlap() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| std::env::var("RTMPM_VIEW_OVERLAP").map_or(true, |v| v.trim() != "0"))
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
        if self.body_link.is_some() {
            return Err(SimError::Backend(
                "this GPU holds one part of a multi-GPU run with rigid bodies, which move in \
                 the multi-GPU backend: step that backend (MultiGpuBackend)"
                    .into(),
            ));
        }
        self.upload_params(dt, t)?;
        self.run_step(dt, &mut NoHooks, true)
    }

    fn max_speed(&mut self) -> Result<f32, SimError> {
        let c = self.ctl_words()?;
        self.error_check(&c)?;
        Ok(f32::from_bits(c[crate::contract::CTL_MAX_SPEED]))
    }

    /// The first bad particle since the last check (the control words read back: a wait for the
    /// steps queued; or the copy [`CudaBackend::queue_check`] queued after them, waited for
    /// alone), its words reset for the next.
    fn check(&mut self) -> Result<Option<BadParticle>, SimError> {
        self.check_now()
    }

    fn add_particles(&mut self, particles: &Particles) -> Result<(), SimError> {
        self.append_particles(particles)
    }

    /// The `n` words of every state word copied into the pooled pinned memory (one copy per
    /// word, at the bus's page-locked rate; the `cap - n` free slots are not read), then
    /// unpacked to original order by every core ([`crate::state::unpack_rows`]).
    fn read_particles(&mut self, out: &mut Particles) -> Result<(), SimError> {
        let (n, layout, f64) = (self.n, self.layout, self.options.f64);
        let words: Vec<usize> = (0..layout.words()).collect();
        let rows = self.read_fields(&words)?;
        crate::state::unpack_rows(&rows, n, layout, f64, out).map_err(SimError::Backend)
    }

    fn memory_bytes(&self) -> Option<(u64, u64)> {
        Some((0, self.device_bytes() as u64))
    }

    fn rigid_bodies(&self) -> Vec<rtmpm_rigid::BodyState> {
        states_of(self.bodies.as_ref())
    }

    fn rigid_poses(&self) -> Vec<rtmpm_rigid::BodyPose> {
        poses_of(self.bodies.as_ref())
    }

    /// Every body's load over the last step the bodies took (kinematic and fixed bodies too;
    /// with `rigid_overlap`, the last step's after [`Backend::flush_rigid`]:
    /// [`crate::step::rigid::LastLoads`]).
    fn rigid_loads(&self) -> Option<Vec<rtmpm_rigid::BodyLoad>> {
        loads_of(self.bodies.as_ref())
    }

    fn flush_rigid(&mut self) -> Result<(), SimError> {
        match self.bodies.as_mut() {
            Some(b) => b.flush(),
            None => Ok(()),
        }
    }

    fn set_rigid_poses(&mut self, poses: &[rtmpm_rigid::BodyPose]) -> Result<(), SimError> {
        set_poses_of(self.bodies.as_mut(), poses)
    }

    /// The bodies take the impulses of the frame's last step (with `rigid_overlap` they are
    /// a step behind): at a frame's end they are where the CPU backend's would be.
    fn end_of_frame(&mut self) -> Result<(), SimError> {
        self.flush_rigid()
    }

    fn export_frame(&mut self, sink: &mut dyn rtmpm_sim::ChunkSink) -> Result<(), SimError> {
        self.export_chunks(sink)
    }

    fn setup_details(&self) -> Option<String> {
        Some(self.setup.to_string())
    }

    /// The picture drawn on this GPU from its own arrays (`view/render.rs`): always drawn here.
    fn render_view(
        &mut self,
        req: &rtmpm_render::ViewRequest,
        out: &mut rtmpm_render::Image,
    ) -> Result<bool, SimError> {
        req.check()
            .map_err(|e| SimError::Backend(format!("live view: {e}")))?;
        self.render_picture(&req.options(&self.scene), req.colliders, out)?;
        Ok(true)
    }

    /// The picture queued after the steps so far ([`CudaBackend::begin_picture`]), unless
    /// `RTMPM_VIEW_OVERLAP=0` ([`view_overlap`]); then not begun (`Ok(false)`), and a live view
    /// draws each picture with [`Backend::render_view`], waiting for it before the next steps.
    fn begin_view(&mut self, req: &rtmpm_render::ViewRequest) -> Result<bool, SimError> {
        if !view_overlap() {
            return Ok(false);
        }
        req.check()
            .map_err(|e| SimError::Backend(format!("live view: {e}")))?;
        self.begin_picture(&req.options(&self.scene), req.colliders, None)?;
        Ok(true)
    }

    fn finish_view(&mut self, out: &mut rtmpm_render::Image) -> Result<(), SimError> {
        self.finish_picture(out).map(|_| ())
    }

    fn set_gravity(&mut self, gravity: rtmpm_physics::math::Vec3) -> Result<(), SimError> {
        self.set_gravity_vector(gravity)
    }

    fn set_tool(&mut self, tool: Option<rtmpm_geometry::Tool>) -> Result<(), SimError> {
        if let Some(t) = &tool {
            t.check().map_err(SimError::Backend)?;
        }
        self.set_tool_shape(tool.map(|t| (t.sdf(), t.velocity)))
    }

    fn chunk_memory(
        &self,
        words: usize,
    ) -> Result<Box<dyn rtmpm_io::chunks::HostBuffer>, SimError> {
        Ok(Box::new(self.chunk_host_memory(words)?))
    }
}
