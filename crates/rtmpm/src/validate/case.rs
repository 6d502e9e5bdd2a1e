//! What a validation case gets and gives: the command line ([`ValidateArgs`]), the context
//! that loads and runs its scenes ([`Ctx`]), the rows of the table ([`Row`]) and the transfer of
//! the `*_gimp` cases ([`GIMP`]).

use crate::backend::{BackendKind, make_backend};
use anyhow::{Context, Result};
use clap::Args;
use rtmpm_driver::Simulation;
use rtmpm_physics::Particles;
use rtmpm_render::plot::Plot;
use rtmpm_scene::Scene;
use std::path::PathBuf;

#[derive(Args)]
pub struct ValidateArgs {
    /// Backend.
    #[arg(long, value_enum, default_value_t = BackendKind::Auto)]
    pub backend: BackendKind,
    /// Run only these cases, comma separated (free_fall, hydrostatic_column,
    /// hydrostatic_column_gimp, vibrating_bar, vibrating_bar_gimp, dam_break, colliding_disks,
    /// granular_column, slump, cohesive_column, archimedes, sinking, rigid_momentum,
    /// emitter_mass; the rigid-body ones need the cargo feature `rigid`). Only when named: the
    /// experimental CK-MPM cases hydrostatic_column_ck, vibrating_bar_ck, dam_break_ck,
    /// granular_column_ck (CPU backend only).
    #[arg(long, value_delimiter = ',')]
    pub case: Vec<String>,
    /// Coarse resolutions that finish in a few minutes on 2 CPU cores (what CI runs).
    #[arg(long)]
    pub quick: bool,
    /// Also run the convergence studies (three resolutions, observed order).
    #[arg(long)]
    pub convergence: bool,
    /// Folder of the validation scenes.
    #[arg(long, default_value = "validation")]
    pub scenes: PathBuf,
    /// Where the plots go.
    #[arg(long, default_value = "out/validation")]
    pub out: PathBuf,
    /// CPU worker threads (default: one per core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Floating-point precision of the whole step: f32 or f64 (default: the scene's
    /// `[solver] precision`, else f32).
    #[arg(long, value_name = "f32|f64")]
    pub precision: Option<rtmpm_scene::Precision>,
    /// The CUDA backend's particle state: f32 or compact (default: the scene's
    /// `[solver] particle_state`, else f32; the CPU backend ignores it).
    #[arg(long, value_name = "f32|compact")]
    pub particle_state: Option<rtmpm_scene::ParticleState>,
}

/// One line of the table.
pub struct Row {
    pub case: String,
    pub quantity: String,
    pub reference: f64,
    pub simulated: f64,
    /// Error in the unit the tolerance is stated in.
    pub error: f64,
    pub tolerance: f64,
    /// "%" for relative errors, else the unit of an absolute error.
    pub unit: &'static str,
}

impl Row {
    pub fn pass(&self) -> bool {
        self.error.is_finite() && self.error <= self.tolerance
    }
}

/// What a case needs from the command line, and the plots it produces.
pub struct Ctx<'a> {
    pub args: &'a ValidateArgs,
    plots: std::cell::RefCell<Vec<(String, Plot)>>,
}

impl<'a> Ctx<'a> {
    /// The context of a validation run with the command line `args`, no plots yet.
    pub fn new(args: &'a ValidateArgs) -> Ctx<'a> {
        Ctx {
            args,
            plots: Default::default(),
        }
    }

    /// The plots kept so far, in the order kept.
    pub fn plots(&self) -> std::cell::Ref<'_, Vec<(String, Plot)>> {
        self.plots.borrow()
    }
}

impl Ctx<'_> {
    /// Keep a plot, written as `<out>/<name>.png` after the table.
    pub fn plot(&self, name: &str, plot: Plot) {
        self.plots.borrow_mut().push((name.to_string(), plot));
    }

    /// Load a validation scene.
    pub fn scene(&self, file: &str) -> Result<Scene> {
        let path = self.args.scenes.join(file);
        Scene::from_file(&path).with_context(|| format!("validation scene {}", path.display()))
    }

    /// The text of a validation scene.
    pub fn scene_text(&self, file: &str) -> Result<String> {
        let path = self.args.scenes.join(file);
        std::fs::read_to_string(&path)
            .with_context(|| format!("validation scene {}", path.display()))
    }

    /// A simulation at t = 0 of the scene `text` (named `origin` in messages), its particles
    /// sampled, on the backend and in the precision of the command line.
    pub fn simulation(&self, text: &str, origin: &str) -> Result<Simulation> {
        let mut scene = Scene::from_toml_in(text, origin, &self.args.scenes)
            .with_context(|| format!("validation scene {origin}"))?;
        if let Some(p) = self.args.precision {
            scene.precision = p;
        }
        if let Some(s) = self.args.particle_state {
            scene.particle_state = s;
        }
        let particles = scene.sample_particles()?;
        let backend = make_backend(
            self.args.backend,
            &scene,
            particles,
            self.args.threads,
            &rtmpm_cuda::CudaOptions::default(),
        )?;
        Ok(Simulation::new(scene, backend))
    }

    /// Run `scene` from `particles`, calling `each_frame(time, particles)` after every frame
    /// (and once at t = 0). Returns the simulation for a final read.
    pub fn run(
        &self,
        mut scene: Scene,
        particles: Particles,
        mut each_frame: impl FnMut(f64, &Particles),
    ) -> Result<Simulation> {
        if let Some(p) = self.args.precision {
            scene.precision = p;
        }
        if let Some(s) = self.args.particle_state {
            scene.particle_state = s;
        }
        each_frame(0.0, &particles);
        let backend = make_backend(
            self.args.backend,
            &scene,
            particles,
            self.args.threads,
            &rtmpm_cuda::CudaOptions::default(),
        )?;
        let mut sim = Simulation::new(scene, backend);
        let mut host = Particles::default();
        for _ in 0..sim.scene.time.frames() {
            sim.advance_frame()?;
            sim.backend.read_particles(&mut host)?;
            each_frame(sim.time, &host);
        }
        Ok(sim)
    }
}

/// The transfer of the `*_ck` cases: CK-MPM (Liu, Wang & Li, "CK-MPM: A Compact-Kernel Material
/// Point Method"), MLS-MPM/APIC on two staggered grids; experimental, CPU backend only.
pub const CK: rtmpm_physics::transfer::SolverSettings = rtmpm_physics::transfer::SolverSettings {
    transfer: rtmpm_physics::transfer::Transfer::CkMpm,
    update: rtmpm_physics::transfer::Update::Usl,
    flip: 0.0,
};

/// The transfer of the `*_gimp` cases: uGIMP with MUSL and a pure FLIP velocity update, the
/// energy-conserving classic scheme (Bardenhagen & Kober 2004; Sulsky et al. 1995).
pub const GIMP: rtmpm_physics::transfer::SolverSettings = rtmpm_physics::transfer::SolverSettings {
    transfer: rtmpm_physics::transfer::Transfer::Gimp,
    update: rtmpm_physics::transfer::Update::Musl,
    flip: 1.0,
};
