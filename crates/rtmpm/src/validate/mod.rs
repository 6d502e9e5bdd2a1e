//! `rtmpm validate`: run the published validation cases (`validation/*.toml`), measure, compare
//! with the reference and print a table. Sources: `../shared/validation/REFERENCES.md`,
//! `docs/validation.md`.

mod bar;
mod column;
mod dam_break;
mod disks;
mod free_fall;
mod granular;
mod hydrostatic;
mod measure;
mod rigid;
mod slump;

use crate::backend::{BackendKind, make_backend};
use anyhow::{Context, Result, bail};
use clap::Args;
use rtmpm_driver::Simulation;
use rtmpm_physics::Particles;
use rtmpm_render::plot::Plot;
use rtmpm_scene::Scene;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub struct ValidateArgs {
    /// Backend.
    #[arg(long, value_enum, default_value_t = BackendKind::Auto)]
    pub backend: BackendKind,
    /// Run only these cases, comma separated (free_fall, hydrostatic_column,
    /// hydrostatic_column_gimp, vibrating_bar, vibrating_bar_gimp, dam_break, colliding_disks,
    /// granular_column, slump, cohesive_column, archimedes, sinking, rigid_momentum,
    /// emitter_mass; the rigid-body ones need the cargo feature `rigid`).
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
    fn pass(&self) -> bool {
        self.error.is_finite() && self.error <= self.tolerance
    }
}

/// What a case needs from the command line, and the plots it produces.
pub struct Ctx<'a> {
    pub args: &'a ValidateArgs,
    plots: std::cell::RefCell<Vec<(String, Plot)>>,
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

type Case = fn(&Ctx) -> Result<Vec<Row>>;

/// The transfer of the `*_gimp` cases: uGIMP with MUSL and a pure FLIP velocity update, the
/// energy-conserving classic scheme (Bardenhagen & Kober 2004; Sulsky et al. 1995).
pub const GIMP: rtmpm_physics::transfer::SolverSettings = rtmpm_physics::transfer::SolverSettings {
    transfer: rtmpm_physics::transfer::Transfer::Gimp,
    update: rtmpm_physics::transfer::Update::Musl,
    flip: 1.0,
};

const CASES: &[(&str, Case)] = &[
    ("free_fall", free_fall::run),
    ("hydrostatic_column", hydrostatic::run),
    ("hydrostatic_column_gimp", hydrostatic::run_gimp),
    ("vibrating_bar", bar::run),
    ("vibrating_bar_gimp", bar::run_gimp),
    ("dam_break", dam_break::run),
    ("colliding_disks", disks::run),
    ("granular_column", granular::run),
    ("slump", slump::run),
    ("cohesive_column", column::run),
    ("archimedes", rigid::archimedes),
    ("sinking", rigid::sinking),
    ("rigid_momentum", rigid::momentum),
    ("emitter_mass", rigid::emitter_mass),
];

/// The cases that need the cargo feature `rigid`.
const RIGID_CASES: &[&str] = &["archimedes", "sinking", "rigid_momentum"];

pub fn validate(args: ValidateArgs) -> Result<()> {
    if !args.scenes.is_dir() {
        bail!(
            "validation scenes not found in {} (run from the repository root or pass --scenes)",
            args.scenes.display()
        );
    }
    for name in &args.case {
        if !CASES.iter().any(|(n, _)| n == name) {
            let names: Vec<_> = CASES.iter().map(|(n, _)| *n).collect();
            bail!("unknown case `{name}`; cases: {}", names.join(", "));
        }
    }
    let selected: Vec<&(&str, Case)> = CASES
        .iter()
        .filter(|(n, _)| args.case.is_empty() || args.case.iter().any(|c| c == n))
        .collect();
    let ctx = Ctx {
        args: &args,
        plots: Default::default(),
    };
    let mut rows = Vec::new();
    // A case that cannot run (a backend that refuses its scene, a blow-up) is reported after
    // the table; the other cases still run.
    let mut broken: Vec<(String, anyhow::Error)> = Vec::new();
    for (name, case) in selected {
        if RIGID_CASES.contains(name) && !rigid::available() && args.case.is_empty() {
            eprintln!("validate: {name} skipped: it {}", rigid::NEEDS_FEATURE);
            continue;
        }
        let start = Instant::now();
        eprintln!("validate: {name} ...");
        match case(&ctx) {
            Ok(r) => {
                eprintln!(
                    "validate: {name} done in {:.1} s",
                    start.elapsed().as_secs_f64()
                );
                rows.extend(r);
            }
            Err(e) => {
                eprintln!("validate: {name} could not run: {e:#}");
                broken.push((name.to_string(), e));
            }
        }
    }
    print_table(&rows);
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    for (name, plot) in ctx.plots.borrow().iter() {
        let path = args.out.join(format!("{name}.png"));
        plot.render(900, 560)
            .write_png(&path)
            .with_context(|| format!("writing {}", path.display()))?;
        println!("plot: {}", path.display());
    }
    for (name, e) in &broken {
        println!("case {name} could not run: {e:#}");
    }
    let failed = rows.iter().filter(|r| !r.pass()).count();
    if failed > 0 || !broken.is_empty() {
        bail!(
            "{failed} of {} validation checks failed; {} cases could not run",
            rows.len(),
            broken.len()
        );
    }
    println!("{} passed, 0 failed", rows.len());
    Ok(())
}

fn print_table(rows: &[Row]) {
    println!(
        "{:<24} {:<44} {:>12} {:>12} {:>11} {:>11}  result",
        "case", "quantity", "reference", "simulated", "error", "tolerance"
    );
    for r in rows {
        let num = |v: f64| {
            if r.unit == "%" || v == 0.0 || (1e-2..1e5).contains(&v.abs()) {
                format!("{v:.4}")
            } else {
                format!("{v:.3e}")
            }
        };
        println!(
            "{:<24} {:<44} {:>12} {:>12} {:>11} {:>11}  {}",
            r.case,
            r.quantity,
            num(r.reference),
            num(r.simulated),
            format!("{}{}", num(r.error), r.unit),
            format!("{}{}", num(r.tolerance), r.unit),
            if r.pass() { "PASS" } else { "FAIL" }
        );
    }
}

/// Observed order of convergence from errors at resolutions refined by `ratio` each time.
pub fn observed_order(errors: &[f64], ratio: f64) -> Vec<f64> {
    errors
        .windows(2)
        .map(|w| (w[0] / w[1]).ln() / ratio.ln())
        .collect()
}

/// Relative error in percent.
pub fn rel_pct(simulated: f64, reference: f64) -> f64 {
    100.0 * (simulated - reference).abs() / reference.abs()
}
