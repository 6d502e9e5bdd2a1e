//! The budget of a run, estimated before anything is sampled or allocated: particles, steps,
//! frames, output bytes, host and GPU memory. `rtmpm check` prints it, `rtmpm run` refuses a
//! run that cannot fit (with the numbers and the fix) and warns when steps or frames are absurd.

use crate::sampling;
use crate::scene::Scene;
use crate::settings::{ParticleState, Precision, StepMode};
use rtmpm_io::limits::human_bytes;

/// Host bytes per particle of a CPU run in f32: the particle state (112 B) twice (the backend
/// sorts into a spare copy), ids and stencil bases twice, the layout's order and the host copy
/// that frames are written from.
pub const HOST_BYTES_PER_PARTICLE_F32: u64 = 112 * 2 + 8 + 24 + 16 + 112;
/// The same in f64 (the backend's state is twice as wide).
pub const HOST_BYTES_PER_PARTICLE_F64: u64 = 224 * 2 + 8 + 24 + 16 + 112;
/// Host bytes per particle of a CUDA run whose state is packed straight from the sampled
/// positions (`rtmpm-cuda` `state::pack_bodies`), in f32: the packed state (29 words, 116 B), the
/// positions (12 B), the stencil bases (12 B) and the layout's order (4 B), rounded up. Measured:
/// 129 bytes a particle at the peak for 8.4M particles (bench/RESULTS.md).
pub const HOST_BYTES_PER_PARTICLE_CUDA_F32: u64 = 160;
/// The same in f64 (the packed state is twice as wide).
pub const HOST_BYTES_PER_PARTICLE_CUDA_F64: u64 = 280;
/// Host bytes per particle of a CUDA run whose state the device fills from the uploaded
/// positions (`rtmpm-cuda` `fill`, the default): the positions (12 B, f32 in either precision)
/// and a margin for the walk's chunks, rounded up. Measured: 12.7 bytes a particle at the peak
/// of the host's share for 26.3M particles (`setup_profile ... device`).
pub const HOST_BYTES_PER_PARTICLE_CUDA_FILL: u64 = 16;
/// Device bytes per particle of a CUDA run in f32 with the 29-word state, twice that in f64: the
/// CUDA backend's plan (`rtmpm-cuda` `Capacity::bytes`, docs/memory.md) rounded up: state 116,
/// sort scratch 16 (the default 4 fields), sort ranks 4, warp list 0.4. The grid is counted per
/// node of the domain. Other state layouts: [`gpu_bytes_per_particle`].
pub const GPU_BYTES_PER_PARTICLE: u64 = 140;

/// Words per particle of the CUDA backend's state for `scene` (`rtmpm-cuda`'s
/// `StateLayout::choose` with the default options; a unit test there checks the two agree): 29,
/// or 20 when every material is a fluid (F in one word, no plastic word); with
/// `particle_state = "compact"` (C in 5 words) 25 and 16.
pub fn gpu_state_words(scene: &Scene) -> u64 {
    let all_fluid = scene
        .materials
        .iter()
        .all(|m| matches!(m.model, rtmpm_physics::material::Model::Fluid(_)));
    let compact = scene.particle_state == ParticleState::Compact;
    match (all_fluid, compact) {
        (true, false) => 20,
        (false, false) => 29,
        (true, true) => 16,
        (false, true) => 25,
    }
}

/// Device bytes per particle of a CUDA run of `scene`: the state's words and 6 more (sort
/// scratch 4, ranks 1, warp list, rounded up), 4 bytes each in f32, 8 in f64 (29 words:
/// [`GPU_BYTES_PER_PARTICLE`]).
pub fn gpu_bytes_per_particle(scene: &Scene) -> u64 {
    let real = match scene.precision {
        Precision::F32 => 4,
        Precision::F64 => 8,
    };
    real * (gpu_state_words(scene) + 6)
}
/// More steps than this is refused: even at a microsecond a step it would take hours.
pub const MAX_STEPS: u64 = 10_000_000_000;
/// More frames than this is refused (that many files in one folder).
pub const MAX_FRAMES: u64 = 10_000_000;
/// Steps above which a warning is printed.
pub const WARN_STEPS: u64 = 10_000_000;
/// Frames above which a warning is printed.
pub const WARN_FRAMES: u64 = 100_000;

/// What a run of a scene will need, estimated from the scene alone.
#[derive(Clone, Debug, PartialEq)]
pub struct Budget {
    /// Estimated particles of each body (see [`sampling::estimate_body`]).
    pub body_particles: Vec<u64>,
    /// Their sum, plus every particle the emitters add by the end of the run.
    pub particles: u64,
    /// Frames to simulate.
    pub frames: u64,
    /// Steps: exact for a fixed dt; for a CFL step, the duration over the step that the sound
    /// speed and the initial speeds allow (particles that speed up need more).
    pub steps: u64,
    /// The time step used for `steps` (s).
    pub dt: f64,
    /// What sets that step, e.g. "the sound speed 3.2e3 m/s of material `steel`".
    pub dt_reason: String,
    /// How to take fewer steps, given what sets the step.
    pub dt_fix: String,
    /// The CFL step's floor `time.min_dt` (s): a run whose step falls below it stops there.
    pub min_dt: Option<f64>,
    /// Particles each emitter adds by the end of the run.
    pub emitter_particles: Vec<u64>,
    /// Particles of the checkpoint a resumed run starts from (0 for a fresh run).
    pub resumed_particles: u64,
    /// Bytes of frame files written (every particle format asked, every frame including
    /// frame 0; surface meshes not counted).
    pub output_bytes: u64,
    /// Host memory of a CPU run (particles, sorting copies, the grid of the touched blocks).
    pub host_bytes: u64,
    /// Device memory of a CUDA run on one GPU (particles, and the grid of every block of the
    /// domain, which the backend allocates up front).
    pub gpu_bytes: u64,
    /// The part of `host_bytes` that grows with each particle (bytes per particle).
    pub host_bytes_per_particle: u64,
}

/// A count for a message: the number, or "more than 1.8e19" where an estimate saturated.
pub fn count(n: u64) -> String {
    if n == u64::MAX {
        format!("more than {:.1e}", u64::MAX as f64)
    } else {
        n.to_string()
    }
}

/// One problem with a budget: what, by how much, how to fix it.
#[derive(Clone, Debug, PartialEq)]
pub struct BudgetIssue {
    pub message: String,
    pub fix: String,
}

impl std::fmt::Display for BudgetIssue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}\n  fix: {}", self.message, self.fix)
    }
}

/// Bytes per particle of one frame, summed over the formats written (each format's
/// [`rtmpm_io::frame::FrameBytes`]). Surface meshes are not counted (their size depends on the
/// flow).
fn frame_bytes_per_particle(scene: &Scene) -> u64 {
    let o = &scene.output;
    o.formats.iter().map(|f| f.bytes.with(o.derived())).sum()
}

/// The CFL step of `scene` and what sets it: `max_dt`, or `cfl dx / (c + s)` with `c` the
/// largest sound speed of its materials and `s` the fastest of its speed sources (bodies,
/// emitters, colliders, rigid bodies, a fall across the domain: [`Scene::speed_sources`]), or
/// gravity's own bound ([`super::speeds::gravity_dt`]), whichever is smallest.
fn cfl_step(scene: &Scene, cfl: f32, max_dt: f32) -> (f64, String, String) {
    let (sound, material) = scene
        .materials
        .iter()
        .map(|m| (m.model.sound_speed(m.density) as f64, m.name.as_str()))
        .fold((0.0, ""), |a, b| if b.0 > a.0 { b } else { a });
    let source = scene.fastest_source();
    let speed = source.as_ref().map_or(0.0, |s| s.speed);
    let cfl_dt = cfl as f64 * scene.dx as f64 / (sound + speed);
    let gravity_dt = super::speeds::gravity_dt(scene.gravity, scene.dx, cfl) as f64;
    let shorter = "or a shorter time.duration";
    if gravity_dt < cfl_dt.min(max_dt as f64) {
        let g = super::speeds::norm(scene.gravity);
        return (
            gravity_dt,
            format!(
                "gravity {g:.3e} m/s^2: |g| dt^2 <= cfl dx, so that a step adds less than a \
                 cell to a fall"
            ),
            format!("lower `gravity` (|g| = {g:.3e} m/s^2; Earth's is 9.81) {shorter}"),
        );
    }
    if cfl_dt.is_nan() || cfl_dt >= max_dt as f64 {
        return (
            max_dt as f64,
            "time.max_dt".to_string(),
            format!("raise time.max_dt {shorter}"),
        );
    }
    match source {
        Some(s) if s.speed > sound => (
            cfl_dt,
            format!(
                "the CFL condition at the speed {:.3e} m/s of {} (`{}`)",
                s.speed, s.what, s.field
            ),
            format!(
                "lower `{}` ({} moves at {:.3e} m/s, {:.0} times the fastest sound speed) {shorter}",
                s.field,
                s.what,
                s.speed,
                s.speed / sound.max(1e-30)
            ),
        ),
        _ => (
            cfl_dt,
            format!(
                "the CFL condition at the sound speed {sound:.3e} m/s of material `{material}` \
                 (set by its stiffness and density)"
            ),
            format!(
                "use a softer or denser material `{material}` (a lower youngs_modulus or \
                 bulk_modulus, or a higher density), a larger dx {shorter}"
            ),
        ),
    }
}

impl Budget {
    /// Estimate the budget of `scene`; `frames` overrides the scene's duration x fps.
    pub fn estimate(scene: &Scene, frames: Option<u64>) -> Budget {
        let body_particles: Vec<u64> = (0..scene.bodies.len())
            .map(|i| sampling::estimate_body(scene, i))
            .collect();
        Self::estimate_from(scene, frames, body_particles, 0)
    }

    /// The budget of a run resumed from a checkpoint of `particles` particles (which replace
    /// the bodies'; the emitters' totals are added, an upper bound of what they still emit).
    pub fn estimate_resumed(scene: &Scene, frames: Option<u64>, particles: u64) -> Budget {
        Self::estimate_from(scene, frames, Vec::new(), particles)
    }

    fn estimate_from(
        scene: &Scene,
        frames: Option<u64>,
        body_particles: Vec<u64>,
        resumed_particles: u64,
    ) -> Budget {
        // The bodies' particles and every particle the emitters add by the end of the run.
        let emitter_particles: Vec<u64> = scene.emitters.iter().map(|e| e.total()).collect();
        let emitted = emitter_particles
            .iter()
            .fold(resumed_particles, |a, &e| a.saturating_add(e));
        let particles = body_particles
            .iter()
            .fold(emitted, |a, &b| a.saturating_add(b));
        let frames = frames.unwrap_or_else(|| scene.time.frames());
        let frame_time = 1.0 / scene.time.fps as f64;
        let (dt, dt_reason, dt_fix) = match scene.time.step {
            StepMode::Fixed { dt } => (
                dt as f64,
                "the fixed time.dt".to_string(),
                "use a larger time.dt or a shorter time.duration".to_string(),
            ),
            StepMode::Cfl { cfl, max_dt, .. } => cfl_step(scene, cfl, max_dt),
        };
        let per_frame = (frame_time / dt).ceil().max(1.0);
        let steps_f = per_frame * frames as f64;
        let steps = if steps_f < u64::MAX as f64 {
            steps_f as u64
        } else {
            u64::MAX
        };
        let frame_files = frames.saturating_add(1);
        let output_bytes = particles
            .saturating_mul(frame_bytes_per_particle(scene))
            .saturating_add(1024)
            .saturating_mul(frame_files);
        let per_host = match scene.precision {
            Precision::F32 => HOST_BYTES_PER_PARTICLE_F32,
            Precision::F64 => HOST_BYTES_PER_PARTICLE_F64,
        };
        let real = match scene.precision {
            Precision::F32 => 4u64,
            Precision::F64 => 8,
        };
        // Grid nodes: the CPU allocates the touched blocks (at most 27 nodes per particle), the
        // GPU every block of the domain; 4 values a node and a second array of 3 (CK-MPM, CPU
        // only: a second grid of 4 values a node).
        let [nx, ny, nz] = scene.n_cells();
        let domain_nodes = (nx as u64 + 9) * (ny as u64 + 9) * (nz as u64 + 9);
        let ck = scene.solver.transfer == rtmpm_physics::transfer::Transfer::CkMpm;
        let node_bytes = if ck { 8 } else { 7 } * real;
        let host_nodes = domain_nodes.min(particles.saturating_mul(27));
        let host_bytes = particles
            .saturating_mul(per_host)
            .saturating_add(host_nodes.saturating_mul(node_bytes));
        let gpu_bytes = particles
            .saturating_mul(gpu_bytes_per_particle(scene))
            .saturating_add(domain_nodes.saturating_mul(2 * 4 * real + 16));
        Budget {
            body_particles,
            particles,
            frames,
            steps,
            dt,
            dt_reason,
            dt_fix,
            min_dt: match scene.time.step {
                StepMode::Cfl { min_dt, .. } => Some(min_dt as f64),
                StepMode::Fixed { .. } => None,
            },
            emitter_particles,
            resumed_particles,
            output_bytes,
            host_bytes,
            gpu_bytes,
            host_bytes_per_particle: per_host,
        }
    }

    /// The budget of a CUDA run built from the sampled positions: the host holds
    /// [`HOST_BYTES_PER_PARTICLE_CUDA_FILL`] a particle when the device fills the state
    /// (`device_fill`), else [`HOST_BYTES_PER_PARTICLE_CUDA_F32`] (or `_F64`) for the state it
    /// packs, and no grid.
    pub fn for_cuda_host(mut self, precision: Precision, device_fill: bool) -> Budget {
        self.host_bytes_per_particle = match (device_fill, precision) {
            (true, _) => HOST_BYTES_PER_PARTICLE_CUDA_FILL,
            (false, Precision::F32) => HOST_BYTES_PER_PARTICLE_CUDA_F32,
            (false, Precision::F64) => HOST_BYTES_PER_PARTICLE_CUDA_F64,
        };
        self.host_bytes = self.particles.saturating_mul(self.host_bytes_per_particle);
        self
    }

    /// [`Budget::for_cuda_host`] with the device fill when the device also draws the bodies it
    /// can ([`crate::deferred::can_defer`]): the host holds none of their particles.
    pub fn with_drawn_bodies(mut self, scene: &Scene) -> Budget {
        let drawn: u64 = self
            .body_particles
            .iter()
            .enumerate()
            .filter(|(i, _)| crate::deferred::can_defer(scene, *i))
            .map(|(_, n)| *n)
            .sum();
        self.host_bytes = self
            .host_bytes
            .saturating_sub(drawn.saturating_mul(self.host_bytes_per_particle));
        self
    }

    /// What cannot fit: more host memory than `host_available`, more output than
    /// `disk_available` (both when known; `output` false for a run without frame files), or
    /// absurd step and frame counts.
    pub fn refusals(
        &self,
        host_available: Option<u64>,
        disk_available: Option<u64>,
        output: bool,
    ) -> Vec<BudgetIssue> {
        let mut out = Vec::new();
        if let Some(avail) = host_available
            && self.host_bytes > avail
        {
            let bodies = self
                .body_particles
                .iter()
                .enumerate()
                .map(|(i, &n)| (format!("body[{i}]"), n));
            let emitters = self
                .emitter_particles
                .iter()
                .enumerate()
                .map(|(i, &n)| (format!("emitter[{i}]"), n));
            let resumed = std::iter::once(("the checkpoint".to_string(), self.resumed_particles));
            let (largest, in_largest) = bodies
                .chain(emitters)
                .chain(resumed)
                .fold((String::new(), 0), |a, b| if b.1 > a.1 { b } else { a });
            // What fits: the memory left beside the grid, at this many bytes a particle.
            let grid = self
                .host_bytes
                .saturating_sub(self.particles.saturating_mul(self.host_bytes_per_particle));
            let fit = avail.saturating_sub(grid) / self.host_bytes_per_particle.max(1);
            out.push(BudgetIssue {
                message: format!(
                    "the run needs about {} of memory for {} particles, more than the {} \
                     available (the largest, {largest}, has {in_largest}); about {fit} particles \
                     fit",
                    human_bytes(self.host_bytes),
                    count(self.particles),
                    human_bytes(avail)
                ),
                fix: "use fewer particles: a larger dx, a lower particles_per_cell or count, \
                      smaller bodies, or lower emitter rates"
                    .into(),
            });
        }
        if output
            && let Some(avail) = disk_available
            && self.output_bytes > avail
        {
            out.push(BudgetIssue {
                message: format!(
                    "the frames would take about {} ({} frames of {} particles), more than the \
                     {} free on the output disk",
                    human_bytes(self.output_bytes),
                    count(self.frames.saturating_add(1)),
                    count(self.particles),
                    human_bytes(avail)
                ),
                fix: "write fewer frames (a lower time.fps or --frames N), only one format \
                      ([output] formats), --no-output, or another --out folder"
                    .into(),
            });
        }
        if self.frames > MAX_FRAMES {
            out.push(BudgetIssue {
                message: format!(
                    "{} frames is more than the {MAX_FRAMES} allowed",
                    self.frames
                ),
                fix: "lower time.fps or time.duration, or give --frames N".into(),
            });
        }
        if let Some(min_dt) = self.min_dt
            && self.dt < min_dt
        {
            out.push(BudgetIssue {
                message: format!(
                    "the step the scene needs, {:.2e} s ({}), is below time.min_dt = {min_dt:.2e} \
                     s: the run would stop at its first step",
                    self.dt, self.dt_reason
                ),
                fix: format!(
                    "{}; or, if the speed is intended, lower time.min_dt",
                    self.dt_fix
                ),
            });
        }
        if self.steps > MAX_STEPS {
            out.push(BudgetIssue {
                message: format!(
                    "about {:.2e} steps of dt = {:.2e} s ({}) is more than the {:.0e} allowed \
                     (it would not end)",
                    self.steps as f64, self.dt, self.dt_reason, MAX_STEPS as f64
                ),
                fix: self.dt_fix.clone(),
            });
        }
        out
    }

    /// Counts that are allowed but probably not meant.
    pub fn warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        if self.steps > WARN_STEPS && self.steps <= MAX_STEPS {
            out.push(format!(
                "about {:.2e} steps of dt = {:.2e} s ({}): {:.2e} particle-steps, hours or days \
                 of computing; check time.dt / time.max_dt, the materials' stiffness and \
                 time.duration",
                self.steps as f64,
                self.dt,
                self.dt_reason,
                self.steps as f64 * self.particles as f64
            ));
        }
        if self.frames > WARN_FRAMES && self.frames <= MAX_FRAMES {
            out.push(format!(
                "{} frames: check time.fps ({} files per format)",
                self.frames,
                self.frames.saturating_add(1)
            ));
        }
        out
    }

    /// A few lines for `rtmpm check`.
    pub fn describe(&self) -> String {
        format!(
            "  budget      {} particles (estimated), {} frames, about {} steps of {:.2e} s\n  \
             output      about {} of frame files\n  memory      about {} on the host (cpu), {} \
             on one GPU (cuda)",
            count(self.particles),
            count(self.frames),
            count(self.steps),
            self.dt,
            human_bytes(self.output_bytes),
            human_bytes(self.host_bytes),
            human_bytes(self.gpu_bytes)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(extra_time: &str, bodies: usize, radius: f32) -> Scene {
        let mut t = format!(
            "[domain]\nmin = [0, 0, 0]\nmax = [4, 4, 4]\ndx = 0.01\n[time]\nduration = 1\n\
             {extra_time}\n[[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000\n\
             bulk_modulus = 1e5\n"
        );
        for i in 0..bodies {
            let c = 0.5 + i as f32 * 0.6;
            t.push_str(&format!(
                "[[body]]\nmaterial = \"w\"\nshape = \"sphere\"\ncenter = [{c}, 2, 2]\n\
                 radius = {radius}\n"
            ));
        }
        Scene::from_toml(&t, "budget").unwrap()
    }

    #[test]
    fn estimates_match_the_sampling() {
        let s = scene("fps = 10\ndt = 1e-3", 1, 0.1);
        let b = Budget::estimate(&s, None);
        let exact = sampling::count_body(&s, 0).unwrap();
        assert!(
            (b.particles as f64 / exact as f64 - 1.0).abs() < 0.02,
            "{} vs {exact}",
            b.particles
        );
        assert_eq!(b.frames, 10);
        assert_eq!(b.steps, 1000);
        assert!(b.refusals(Some(1 << 40), Some(1 << 40), true).is_empty());
        assert!(b.warnings().is_empty());
        // Bytes: 11 frame files of 32 B per particle (PLY only).
        assert_eq!(b.output_bytes, (b.particles * 32 + 1024) * 11);
    }

    /// Five bodies are refused as a whole when the memory is not there (saying how many
    /// particles fit), and the estimate does not sample anything (it is instant).
    #[test]
    fn five_huge_bodies_are_refused_without_sampling() {
        let s = scene("fps = 10", 5, 0.29);
        let t = std::time::Instant::now();
        let b = Budget::estimate(&s, None);
        assert!(t.elapsed().as_secs_f64() < 0.5);
        assert!(b.particles > 5 * 800_000, "{}", b.particles);
        let r = b.refusals(Some(1 << 30), None, true);
        assert_eq!(r.len(), 1, "{r:?}");
        assert!(r[0].message.contains("memory") && r[0].fix.contains("dx"));
        // What fits: the memory less the grid, at the bytes of a particle (here the grid alone
        // is over 1 GiB: nothing fits).
        assert!(
            r[0].message.contains("about 0 particles fit"),
            "{}",
            r[0].message
        );
        let grid = b.host_bytes - b.particles * HOST_BYTES_PER_PARTICLE_F32;
        let avail = grid + 1_000_000 * HOST_BYTES_PER_PARTICLE_F32 + 17;
        let r = b.refusals(Some(avail), None, true);
        assert!(
            r[0].message.contains("about 1000000 particles fit"),
            "{}",
            r[0].message
        );
    }

    /// A CUDA run packed from the positions needs far less host memory than a CPU run: the
    /// scene a CPU run cannot fit in 1 GiB fits as a CUDA run.
    #[test]
    fn a_lean_cuda_run_counts_its_own_host_bytes() {
        let b = Budget::estimate(&scene("fps = 10", 2, 0.12), None);
        let avail = b.particles * 200;
        assert!(!b.refusals(Some(avail), None, false).is_empty());
        let c = b.clone().for_cuda_host(Precision::F32, false);
        assert_eq!(c.host_bytes, b.particles * HOST_BYTES_PER_PARTICLE_CUDA_F32);
        assert!(c.refusals(Some(avail), None, false).is_empty());
        let d = b.clone().for_cuda_host(Precision::F64, false);
        assert_eq!(d.host_bytes_per_particle, HOST_BYTES_PER_PARTICLE_CUDA_F64);
        // Filled on the device: the positions only, in either precision; a host of 20 bytes a
        // particle fits it, not the packing.
        let avail = b.particles * 20;
        for p in [Precision::F32, Precision::F64] {
            let e = b.clone().for_cuda_host(p, true);
            assert_eq!(
                e.host_bytes,
                b.particles * HOST_BYTES_PER_PARTICLE_CUDA_FILL
            );
            assert!(e.refusals(Some(avail), None, false).is_empty());
            assert!(
                !b.clone()
                    .for_cuda_host(p, false)
                    .refusals(Some(avail), None, false)
                    .is_empty()
            );
        }
    }

    /// Bodies the device draws cost the host nothing a particle (spinning ones too); a points
    /// file's particles are read on the host and keep their bytes.
    #[test]
    fn bodies_drawn_on_the_device_cost_the_host_nothing() {
        let mut s = scene("fps = 10", 2, 0.12);
        s.bodies[1].angular_velocity = rtmpm_physics::math::Vec3::Y;
        let b = Budget::estimate(&s, None).for_cuda_host(Precision::F32, true);
        assert!(b.host_bytes > 0);
        assert_eq!(b.clone().with_drawn_bodies(&s).host_bytes, 0, "both drawn");
        // A points body (a binary PLY of 3 points) beside a sphere.
        let dir = std::env::temp_dir().join(format!("rtmpm-budget-drawn-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n\
property float y\nproperty float z\nend_header\n"
            .to_vec();
        for k in 0..9 {
            ply.extend((1.0f32 + 0.1 * k as f32).to_le_bytes());
        }
        std::fs::write(dir.join("p.ply"), ply).unwrap();
        let text = "[domain]\nmin = [0, 0, 0]\nmax = [4, 4, 4]\ndx = 0.01\n[time]\nduration = 1\n\
             fps = 10\n[[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000\n\
             bulk_modulus = 1e5\n[[body]]\nmaterial = \"w\"\nshape = \"sphere\"\n\
             center = [0.5, 2, 2]\nradius = 0.12\n[[body]]\nmaterial = \"w\"\n\
             shape = \"particles\"\nfile = \"p.ply\"\n";
        let s = Scene::from_toml_in(text, "budget", &dir).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        let b = Budget::estimate(&s, None).for_cuda_host(Precision::F32, true);
        assert_eq!(b.body_particles[1], 3);
        assert_eq!(
            b.with_drawn_bodies(&s).host_bytes,
            3 * HOST_BYTES_PER_PARTICLE_CUDA_FILL
        );
    }

    #[test]
    fn absurd_steps_and_frames() {
        let b = Budget::estimate(&scene("fps = 1e11\ndt = 1e-12", 1, 0.1), None);
        let r = b.refusals(None, None, true);
        assert_eq!(r.len(), 2, "{r:?}");
        assert!(r[0].message.contains("frames") && r[1].message.contains("steps"));
        let b = Budget::estimate(&scene("fps = 10\ndt = 1e-8", 1, 0.1), None);
        assert!(b.refusals(None, None, true).is_empty());
        assert!(b.warnings()[0].contains("steps"), "{:?}", b.warnings());
        let r = b.refusals(None, Some(1000), true);
        assert!(r[0].message.contains("free on the output disk"), "{r:?}");
        assert!(b.refusals(None, Some(1000), false).is_empty());
    }
}
