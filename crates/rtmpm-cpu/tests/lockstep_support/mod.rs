//! CPU worlds side by side under the lockstep batch driver, shared by the `lockstep_*.rs` tests:
//! [`SideBySide`] (the [`Worlds`] interface the GPU batch has, on one CPU backend a world, with a
//! rewind point of its own when asked and blow-ups made behind the driver's back), the slump
//! batch they run ([`SLUMP`]), its worlds run alone, and lockstep runs of it with and without
//! files.
#![allow(dead_code)] // each test binary uses its part

use crate::common::cpu::CpuBackend;
use rtmpm_driver::Simulation;
use rtmpm_driver::batch::BatchOptions;
use rtmpm_driver::batch::lockstep::LockstepRun;
use rtmpm_scene::{BatchScene, Scene};
use rtmpm_sim::{Backend, BadParticle, Particles, SimError, Worlds};
use std::collections::VecDeque;

/// A small slump: a column of Herschel-Bulkley mud on a sticky floor, at a fixed step.
pub const SLUMP: &str = r#"name = "slump"
[domain]
min = [0.0, 0.0, 0.0]
max = [0.5, 0.5, 0.5]
dx = 0.03125
[time]
duration = 0.15
fps = 20
dt = 1e-3
[walls]
thickness = 3
faces.y_min = { condition = "sticky" }
[[material]]
name = "mud"
type = "herschel_bulkley"
density = 1600.0
bulk_modulus = 1e5
shear_modulus = 1e4
yield_stress = 250.0
consistency = 10.0
[[body]]
material = "mud"
shape = "box"
min = [0.2, 0.1, 0.2]
max = [0.3, 0.25, 0.3]
particles_per_cell = 8
[batch]
count = 3
[batch.sweep]
"material[0].yield_stress" = [20, 150, 600]
"#;

/// CPU worlds side by side, stepped together: the [`Worlds`] interface the GPU batch has.
pub struct SideBySide {
    /// Each world's scene.
    pub scenes: Vec<Scene>,
    /// Each world's backend.
    pub worlds: Vec<CpuBackend>,
    /// Keep the rewind point itself ([`Worlds::save_point`], as the GPU batch does on the
    /// device), in `point`; otherwise the driver keeps it on the host (the trait's default).
    pub keeps_point: bool,
    pub point: Vec<Particles>,
    /// With `keeps_point`, a second slot for the next call's point ([`Worlds::save_next_point`],
    /// as the GPU batch keeps one on the device), in `next_point`; the saves into it counted in
    /// `next_saves`, the points made current from it in `next_uses`.
    pub two_points: bool,
    pub next_point: Vec<Particles>,
    pub next_saves: usize,
    pub next_uses: usize,
    /// Calls of [`Worlds::drop_queued_steps`] (a pipelined call's steps dropped after the last
    /// call's check failed).
    pub drops: usize,
    /// Calls of [`Worlds::read_worlds`] (the driver reading every world to the host).
    pub reads: usize,
    /// Steps taken (counted over rewinds), and `(w, k)`: every particle of world `w` set to
    /// 10^5 m/s before step `k` (it blows up in that step), once.
    pub steps: usize,
    pub poison: Option<(usize, usize)>,
    /// World `w` set to 10^5 m/s before every step (it fails again once frozen and parked).
    pub relapse: Option<usize>,
    /// The health check is not cheap (as the GPU's: the driver checks at the end of a call
    /// and of a frame, not after every step), so a blow-up is found there; the first bad
    /// particle since the last check is kept as the step finds it (`latched`), as the GPU's
    /// control words keep it (a world put since does not hide it).
    pub checks_late: bool,
    pub latched: Option<BadParticle>,
    /// With `checks_late`: what a check reads (`latched`) is queued behind the steps when the
    /// driver asks (`Worlds::queue_check`), as the GPU batch copies its control words, and the
    /// checks read the copies oldest first (a bad particle found drops the later ones and
    /// clears the latch, as the GPU's check resets its words).
    pub queues: bool,
    pub queued: VecDeque<Option<BadParticle>>,
}

impl SideBySide {
    /// The worlds `scenes`, each with the particles its scene samples.
    pub fn new(scenes: &[Scene]) -> SideBySide {
        let p: Vec<Particles> = scenes
            .iter()
            .map(|s| s.sample_particles().expect("sample"))
            .collect();
        SideBySide::from_particles(scenes, &p)
    }

    /// The worlds `scenes` with their particles `p` (a resumed batch's).
    pub fn from_particles(scenes: &[Scene], p: &[Particles]) -> SideBySide {
        let worlds = scenes
            .iter()
            .zip(p)
            .map(|(s, p)| CpuBackend::new(s, p.clone(), None).expect("cpu"))
            .collect();
        SideBySide {
            scenes: scenes.to_vec(),
            worlds,
            keeps_point: false,
            point: Vec::new(),
            two_points: false,
            next_point: Vec::new(),
            next_saves: 0,
            next_uses: 0,
            drops: 0,
            reads: 0,
            steps: 0,
            poison: None,
            relapse: None,
            checks_late: false,
            latched: None,
            queues: false,
            queued: VecDeque::new(),
        }
    }

    /// Every world's particles (not counted in `reads`).
    pub fn read_all(&mut self) -> Result<Vec<Particles>, SimError> {
        self.worlds
            .iter_mut()
            .map(|b| {
                let mut p = Particles::default();
                b.read_particles(&mut p).map(|()| p)
            })
            .collect()
    }

    /// The first bad particle (over all worlds) each world's own check reports.
    fn check_worlds(&mut self) -> Result<Option<BadParticle>, SimError> {
        let o = self.offsets();
        for (w, b) in self.worlds.iter_mut().enumerate() {
            if let Some(mut bad) = b.check()? {
                bad.index += o[w];
                return Ok(Some(bad));
            }
        }
        Ok(None)
    }

    /// First particle (over all worlds) of each world, and the total.
    pub fn offsets(&self) -> Vec<usize> {
        let mut o = vec![0];
        for b in &self.worlds {
            o.push(o[o.len() - 1] + b.num_particles());
        }
        o
    }
}

impl Backend for SideBySide {
    fn name(&self) -> String {
        format!("{} CPU worlds side by side", self.worlds.len())
    }

    fn num_particles(&self) -> usize {
        self.worlds.iter().map(|b| b.num_particles()).sum()
    }

    fn step(&mut self, dt: f32, t: f32) -> Result<(), SimError> {
        let poisoned = match self.poison {
            Some((w, k)) if k == self.steps => {
                self.poison = None;
                Some(w)
            }
            _ => self.relapse,
        };
        if let Some(w) = poisoned {
            let mut p = Particles::default();
            self.worlds[w].read_particles(&mut p)?;
            p.v.iter_mut()
                .for_each(|v| *v = glam::Vec3::new(1e5, 0.0, 0.0));
            self.put_world(w, &p)?;
        }
        self.steps += 1;
        self.worlds.iter_mut().try_for_each(|b| b.step(dt, t))?;
        if self.checks_late && self.latched.is_none() {
            self.latched = self.check_worlds()?;
        }
        Ok(())
    }

    fn max_speed(&mut self) -> Result<f32, SimError> {
        let mut m = 0.0f32;
        for b in &mut self.worlds {
            m = m.max(b.max_speed()?);
        }
        Ok(m)
    }

    fn check(&mut self) -> Result<Option<BadParticle>, SimError> {
        if self.checks_late
            && let Some(copy) = self.queued.pop_front()
        {
            if copy.is_some() {
                self.queued.clear();
                self.latched = None;
            }
            return Ok(copy);
        }
        if self.checks_late {
            return Ok(self.latched.take());
        }
        self.check_worlds()
    }

    fn read_particles(&mut self, out: &mut Particles) -> Result<(), SimError> {
        *out = Particles::default();
        for p in self.read_all()? {
            out.extend(&p);
        }
        Ok(())
    }

    fn cheap_check(&self) -> bool {
        !self.checks_late
    }
}

impl Worlds for SideBySide {
    fn worlds(&self) -> usize {
        self.worlds.len()
    }

    fn read_worlds(&mut self) -> Result<Vec<Particles>, SimError> {
        self.reads += 1;
        self.read_all()
    }

    fn queues_checks(&self) -> bool {
        self.checks_late && self.queues
    }

    fn queue_check(&mut self) -> Result<bool, SimError> {
        if self.queues_checks() {
            self.queued.push_back(self.latched);
        }
        Ok(self.queues_checks())
    }

    fn save_point(&mut self) -> Result<bool, SimError> {
        if self.keeps_point {
            self.point = self.read_all()?;
        }
        Ok(self.keeps_point)
    }

    fn save_next_point(&mut self) -> Result<bool, SimError> {
        if !(self.keeps_point && self.two_points) {
            return Ok(false);
        }
        self.next_point = self.read_all()?;
        self.next_saves += 1;
        Ok(true)
    }

    fn use_next_point(&mut self) -> Result<(), SimError> {
        if self.next_point.is_empty() {
            return Err(SimError::Backend("no next point was kept".into()));
        }
        std::mem::swap(&mut self.point, &mut self.next_point);
        self.next_point.clear();
        self.next_uses += 1;
        Ok(())
    }

    fn drop_queued_steps(&mut self) -> Result<(), SimError> {
        self.drops += 1;
        Ok(())
    }

    fn restore_point(&mut self) -> Result<(), SimError> {
        let point = std::mem::take(&mut self.point);
        for (w, p) in point.iter().enumerate() {
            self.put_world(w, p)?;
        }
        self.point = point;
        Ok(())
    }

    fn put_world(&mut self, w: usize, particles: &Particles) -> Result<(), SimError> {
        self.worlds[w] = CpuBackend::new(&self.scenes[w], particles.clone(), None)?;
        Ok(())
    }

    fn world_of_particle(&self, index: usize) -> Option<(usize, usize)> {
        let o = self.offsets();
        let w = o.partition_point(|&f| f <= index).checked_sub(1)?;
        (w < self.worlds.len()).then(|| (w, index - o[w]))
    }

    fn world_rigid_poses(&self, w: usize) -> Vec<rtmpm_rigid::BodyPose> {
        self.worlds[w].rigid_poses()
    }

    fn set_world_rigid_poses(
        &mut self,
        w: usize,
        poses: &[rtmpm_rigid::BodyPose],
    ) -> Result<(), SimError> {
        self.worlds[w].set_rigid_poses(poses)
    }

    fn world_rigid_loads(&self, w: usize) -> Result<Option<Vec<rtmpm_rigid::BodyLoad>>, SimError> {
        Ok(self.worlds[w].rigid_loads())
    }
}

/// World `scene` run alone for `frames` frames.
pub fn alone(scene: &Scene, frames: u64) -> Particles {
    let p = scene.sample_particles().expect("sample");
    let b = CpuBackend::new(scene, p, None).expect("cpu");
    let mut sim = Simulation::new(scene.clone(), Box::new(b));
    for _ in 0..frames {
        sim.advance_frame().expect("stable");
    }
    let mut p = Particles::default();
    sim.backend.read_particles(&mut p).expect("read");
    p
}

/// A lockstep run of the batch `text` with `options`, executed to its end.
pub fn lockstep(text: &str, options: &BatchOptions) -> (BatchScene, LockstepRun<SideBySide>) {
    let b = BatchScene::from_toml(text, "wedge.toml").unwrap_or_else(|e| panic!("{e}"));
    let backend = Box::new(SideBySide::new(&b.worlds));
    let mut r = LockstepRun::new(&b, text, b.worlds[0].clone(), backend, options).expect("batch");
    r.execute(|_, _| {}).expect("run");
    (b, r)
}

/// Options of a run of `n` frames without files.
pub fn frames(n: u64) -> BatchOptions {
    BatchOptions {
        frames: Some(n),
        ..BatchOptions::default()
    }
}

/// A lockstep run of `text` without files, its state read at the start (as Python's batch).
pub fn unwritten(text: &str) -> (BatchScene, LockstepRun<SideBySide>) {
    unwritten_keeping(text, false)
}

/// [`unwritten`], on a backend that keeps its rewind point itself when `keeps_point`.
pub fn unwritten_keeping(text: &str, keeps_point: bool) -> (BatchScene, LockstepRun<SideBySide>) {
    let b = BatchScene::from_toml(text, "wedge.toml").unwrap_or_else(|e| panic!("{e}"));
    let mut backend = Box::new(SideBySide::new(&b.worlds));
    backend.keeps_point = keeps_point;
    let options = BatchOptions::default();
    let mut r = LockstepRun::new(&b, text, b.worlds[0].clone(), backend, &options).expect("batch");
    r.write_first_frame().expect("read");
    (b, r)
}

/// World `scene` run alone for `steps` steps.
pub fn alone_steps(scene: &Scene, steps: u64) -> Particles {
    let p = scene.sample_particles().expect("sample");
    let b = CpuBackend::new(scene, p, None).expect("cpu");
    let mut sim = Simulation::new(scene.clone(), Box::new(b));
    while sim.step < steps {
        sim.advance(steps - sim.step).expect("stable");
    }
    let mut p = Particles::default();
    sim.backend.read_particles(&mut p).expect("read");
    p
}
