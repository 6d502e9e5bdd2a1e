//! What a validation case gets and gives: the options of a validation run ([`Options`]), the
//! context that loads and runs its scenes ([`Ctx`]), the rows of the table ([`Row`]) and the
//! transfers of the `*_gimp` and `*_ck` cases ([`GIMP`], [`CK`]).

use anyhow::{Context, Result, anyhow};
use rtmpm_backends::{BackendKind, BackendRequest};
use rtmpm_driver::Simulation;
use rtmpm_physics::Particles;
use rtmpm_render::plot::Plot;
use rtmpm_scene::Scene;
use std::path::PathBuf;

/// How to run the validation cases: the backend, the resolution and where the scenes are.
#[derive(Clone, Debug)]
pub struct Options {
    /// Backend (`Auto`: CUDA when a GPU is usable, else the CPU; the choice is printed).
    pub backend: BackendKind,
    /// Coarse resolutions that finish in a few minutes on 2 CPU cores (what CI runs).
    pub quick: bool,
    /// Also run the convergence studies (three resolutions, observed order).
    pub convergence: bool,
    /// Folder of the validation scenes (`validation/` of the repository).
    pub scenes: PathBuf,
    /// CPU worker threads (default: one per core).
    pub threads: Option<usize>,
    /// Floating-point precision of the whole step (default: the scene's `[solver] precision`).
    pub precision: Option<rtmpm_scene::Precision>,
    /// The CUDA backend's particle state (default: the scene's `[solver] particle_state`).
    pub particle_state: Option<rtmpm_scene::ParticleState>,
    /// CUDA backend switches (`--cuda-options`), e.g. `ck_p2g=warp`; the CPU backend ignores them.
    pub cuda: rtmpm_cuda::CudaOptions,
}

impl Default for Options {
    /// Every case at full resolution on the best backend, scenes in `validation/`.
    fn default() -> Options {
        Options {
            backend: BackendKind::Auto,
            quick: false,
            convergence: false,
            scenes: PathBuf::from("validation"),
            threads: None,
            precision: None,
            particle_state: None,
            cuda: rtmpm_cuda::CudaOptions::default(),
        }
    }
}

/// One line of the table: a measured quantity of a case against its reference.
#[derive(Clone, Debug)]
pub struct Row {
    /// The case's name (`free_fall`, ...).
    pub case: String,
    /// What was measured, with the resolution where it matters.
    pub quantity: String,
    /// The reference value (analytic solution or experiment).
    pub reference: f64,
    /// The simulated value.
    pub simulated: f64,
    /// Error in the unit the tolerance is stated in.
    pub error: f64,
    pub tolerance: f64,
    /// "%" for relative errors, else the unit of an absolute error.
    pub unit: &'static str,
}

impl Row {
    /// True when the error is finite and within the tolerance.
    pub fn pass(&self) -> bool {
        self.error.is_finite() && self.error <= self.tolerance
    }
}

/// What a case needs from the options, and the plots it produces.
pub struct Ctx<'a> {
    /// The options of the run.
    pub options: &'a Options,
    plots: std::cell::RefCell<Vec<(String, Plot)>>,
}

impl<'a> Ctx<'a> {
    /// The context of a validation run with `options`, no plots yet.
    pub fn new(options: &'a Options) -> Ctx<'a> {
        Ctx {
            options,
            plots: Default::default(),
        }
    }

    /// The plots kept, in the order kept, taken out of the context.
    pub fn take_plots(&self) -> Vec<(String, Plot)> {
        self.plots.take()
    }
}

impl Ctx<'_> {
    /// Keep a plot, written as `<out>/<name>.png` after the table.
    pub fn plot(&self, name: &str, plot: Plot) {
        self.plots.borrow_mut().push((name.to_string(), plot));
    }

    /// Load a validation scene.
    pub fn scene(&self, file: &str) -> Result<Scene> {
        let path = self.options.scenes.join(file);
        Scene::from_file(&path).with_context(|| format!("validation scene {}", path.display()))
    }

    /// The text of a validation scene.
    pub fn scene_text(&self, file: &str) -> Result<String> {
        let path = self.options.scenes.join(file);
        std::fs::read_to_string(&path)
            .with_context(|| format!("validation scene {}", path.display()))
    }

    /// A simulation at t = 0 of the scene `text` (named `origin` in messages), its particles
    /// sampled, on the backend and in the precision of the command line.
    pub fn simulation(&self, text: &str, origin: &str) -> Result<Simulation> {
        let mut scene = Scene::from_toml_in(text, origin, &self.options.scenes)
            .with_context(|| format!("validation scene {origin}"))?;
        self.override_solver(&mut scene);
        let particles = scene.sample_particles()?;
        let backend = self.backend(&scene, particles)?;
        Ok(Simulation::new(scene, backend))
    }

    /// The options' precision and particle state, where given, in place of the scene's.
    fn override_solver(&self, scene: &mut Scene) {
        if let Some(p) = self.options.precision {
            scene.precision = p;
        }
        if let Some(s) = self.options.particle_state {
            scene.particle_state = s;
        }
    }

    /// The backend of the options for `scene` (in its precision), with `particles`; says which
    /// one `Auto` picked and why.
    fn backend(&self, scene: &Scene, particles: Particles) -> Result<Box<dyn rtmpm_sim::Backend>> {
        let request = BackendRequest {
            kind: self.options.backend,
            threads: self.options.threads,
            gpus: 1,
            cuda: self.options.cuda.clone(),
        };
        let created =
            rtmpm_backends::create(&request, scene, particles).map_err(|e| anyhow!("{e}"))?;
        if self.options.backend == BackendKind::Auto {
            eprintln!("backend: {}", created.reason);
        }
        Ok(Box::new(created.backend))
    }

    /// Run `scene` from `particles`, calling `each_frame(time, particles)` after every frame
    /// (and once at t = 0). Returns the simulation for a final read.
    pub fn run(
        &self,
        mut scene: Scene,
        particles: Particles,
        mut each_frame: impl FnMut(f64, &Particles),
    ) -> Result<Simulation> {
        self.override_solver(&mut scene);
        each_frame(0.0, &particles);
        let backend = self.backend(&scene, particles)?;
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
/// Point Method"), MLS-MPM/APIC on two staggered grids; experimental; the CPU backend and the CUDA backend on one GPU.
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
