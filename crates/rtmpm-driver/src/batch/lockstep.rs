//! The worlds of a batch held by one backend ([`Worlds`]: on the GPU every world in the same
//! kernels, `rtmpm_cuda::batch::CudaBatch`), stepped together by one [`Simulation`]: one time
//! step for every world (the CFL bound of the fastest particle of any world, the stiffest
//! material, the strongest gravity), each world's frames written to its own folder as
//! [`super::BatchRun`] writes them (`batch.csv`, `world_000/`, ...).
//!
//! A world that blows up (or stalls the time step) is frozen at its last frame: every world is
//! put back to its state at that frame, the frozen one parked (its particles where they were,
//! at rest, unstressed: it can neither bound the time step nor blow up again), and the frame
//! is run again. Its files stay those of its last frame; the others go on.

use super::{BatchOptions, WorldStatus, open_out, summary_row, world_output};
use crate::outdir::OutDir;
use crate::output::FrameOutput;
use crate::simulation::Simulation;
use anyhow::{Context, Result, bail};
use rtmpm_physics::Particles;
use rtmpm_physics::math::Mat3;
use rtmpm_scene::{BatchScene, Scene};
use rtmpm_sim::{SimError, Worlds};

/// One world of a lockstep batch: what sets it apart, where it stands, its files.
pub struct LockWorld {
    /// What sets it apart (`material[0].yield_stress = 150`).
    pub label: String,
    /// Running or frozen.
    pub status: WorldStatus,
    /// Its own scene (its files are written with it).
    scene: Scene,
    output: Option<FrameOutput>,
    /// Its particles at the last completed frame (of the frame it froze at, once frozen).
    kept: Particles,
    /// Steps to that frame.
    steps: u64,
}

impl LockWorld {
    /// The particles of the last completed frame (as written to its files).
    pub fn particles(&self) -> &Particles {
        &self.kept
    }
}

/// A batch whose worlds one backend steps together.
pub struct LockstepRun<B: Worlds + ?Sized> {
    /// The simulation of every world at once (its scene: the backend's, with every world's
    /// materials).
    pub sim: Simulation<B>,
    /// The worlds, in order.
    pub worlds: Vec<LockWorld>,
    /// The frames the run goes to.
    pub frames: u64,
    out: Option<OutDir>,
}

impl<B: Worlds + ?Sized> LockstepRun<B> {
    /// The worlds of `batch` held by `backend`, whose kernels run `scene` (world 0's with every
    /// world's materials and the strongest gravity: what bounds the shared time step); `text`
    /// is the scene file's text (it names the run in the output folders).
    pub fn new(
        batch: &BatchScene,
        text: &str,
        scene: Scene,
        backend: Box<B>,
        options: &BatchOptions,
    ) -> Result<LockstepRun<B>> {
        let count = batch.count();
        if backend.worlds() != count {
            bail!(
                "the backend holds {} worlds, the batch has {count}",
                backend.worlds()
            );
        }
        let out = open_out(batch, text, options, None)?;
        let mut worlds = Vec::with_capacity(count);
        for (w, s) in batch.worlds.iter().enumerate() {
            let label = batch.label(w);
            let output = match &out {
                Some(o) => Some(world_output(
                    &o.dir,
                    (w, count),
                    s,
                    (text, &label),
                    options,
                    None,
                )?),
                None => None,
            };
            worlds.push(LockWorld {
                label,
                status: WorldStatus::Running,
                scene: s.clone(),
                output,
                kept: Particles::default(),
                steps: 0,
            });
        }
        let run = LockstepRun {
            sim: Simulation::with_backend(scene, backend),
            worlds,
            frames: options.frames.unwrap_or_else(|| batch.base.time.frames()),
            out,
        };
        run.write_summary()?;
        Ok(run)
    }

    /// Worlds still running.
    pub fn running(&self) -> usize {
        self.worlds
            .iter()
            .filter(|w| w.status == WorldStatus::Running)
            .count()
    }

    /// Run every world to the last frame (frame 0 written first); `frame_done` is called after
    /// each frame with the worlds frozen in it.
    pub fn execute(&mut self, mut frame_done: impl FnMut(&Self, &[usize])) -> Result<()> {
        self.read_and_write_frame()?;
        while self.running() > 0 && self.sim.frame < self.frames {
            let frozen = self.advance_frame()?;
            frame_done(self, &frozen);
        }
        self.write_summary()
    }

    /// Advance every running world by one frame and write it; a world that blows up or stalls
    /// is frozen at its last frame (returned) and the frame run again without it; an error of
    /// the backend itself ends the run.
    pub fn advance_frame(&mut self) -> Result<Vec<usize>> {
        let (time, step, frame) = (self.sim.time, self.sim.step, self.sim.frame);
        let mut frozen = Vec::new();
        loop {
            let e = match self.sim.advance_frame() {
                Ok(_) => break,
                Err(e @ (SimError::Blowup(_) | SimError::Stall(_))) => e,
                Err(e) => return Err(e.into()),
            };
            let w = self.freeze(&e, frame)?;
            frozen.push(w);
            self.rewind(time, step, frame)?;
            if self.running() == 0 {
                break;
            }
        }
        if self.running() > 0 {
            self.read_and_write_frame()?;
        }
        if !frozen.is_empty() {
            self.write_summary()?;
        }
        Ok(frozen)
    }

    /// Freeze the world of the particle `e` names at `frame`, its last; an error that names no particle of a running
    /// world cannot be pinned on one and ends the run.
    fn freeze(&mut self, e: &SimError, frame: u64) -> Result<usize> {
        let particle = match e {
            SimError::Blowup(b) | SimError::Stall(b) => b.particle,
            _ => unreachable!("only blow-ups and stalls freeze a world"),
        };
        let world = self.sim.backend.world_of_particle(particle).map(|(w, _)| w);
        let Some(w) = world.filter(|&w| self.worlds[w].status == WorldStatus::Running) else {
            return Err(anyhow::anyhow!("{e}"))
                .context("a batch's step failed and no running world can be frozen for it");
        };
        self.worlds[w].status = WorldStatus::Frozen {
            frame,
            reason: e.to_string(),
        };
        Ok(w)
    }

    /// Every world back to its particles of the last frame (a frozen one parked), and the clock
    /// back to that frame.
    fn rewind(&mut self, time: f64, step: u64, frame: u64) -> Result<()> {
        for (w, world) in self.worlds.iter().enumerate() {
            let p = match world.status {
                WorldStatus::Running => world.kept.clone(),
                WorldStatus::Frozen { .. } => parked(&world.kept),
            };
            self.sim
                .backend
                .put_world(w, &p)
                .with_context(|| format!("putting world {w} back to frame {frame}"))?;
        }
        (self.sim.time, self.sim.step, self.sim.frame) = (time, step, frame);
        Ok(())
    }

    /// Read every world; keep and write the running ones' frame.
    fn read_and_write_frame(&mut self) -> Result<()> {
        let all = self.sim.backend.read_worlds()?;
        let (frame, time, steps) = (self.sim.frame, self.sim.time, self.sim.step);
        for (world, p) in self.worlds.iter_mut().zip(all) {
            if world.status != WorldStatus::Running {
                continue;
            }
            world.kept = p;
            world.steps = steps;
            if let Some(out) = world.output.as_mut() {
                out.write_frame(frame, time, &world.kept, &[], &world.scene)?;
            }
        }
        Ok(())
    }

    /// `batch.csv`, as [`super::BatchRun`] writes it.
    fn write_summary(&self) -> Result<()> {
        let Some(out) = &self.out else {
            return Ok(());
        };
        let count = self.worlds.len();
        let mut csv = String::from(super::SUMMARY_HEADER);
        for (w, world) in self.worlds.iter().enumerate() {
            csv.push_str(&summary_row(
                w,
                count,
                &world.label,
                &world.status,
                (self.sim.frame, self.frames),
                world.steps,
            ));
        }
        let path = out.dir.join("batch.csv");
        rtmpm_io::write_atomic(&path, csv.as_bytes())
            .with_context(|| format!("writing {}", path.display()))
    }
}

/// A frozen world's particles as it is left in the backend: where they were at its last frame,
/// at rest (`v = 0`, `C = 0`) and unstressed (`F = I`), so that it bounds no time step and
/// cannot blow up again; its files keep the state it froze at.
fn parked(kept: &Particles) -> Particles {
    let mut p = kept.clone();
    p.v.iter_mut().for_each(|v| *v = Default::default());
    p.c.iter_mut().for_each(|c| *c = Mat3::ZERO);
    p.f.iter_mut().for_each(|f| *f = Mat3::IDENTITY);
    p
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtmpm_physics::math::Vec3;

    #[test]
    fn a_parked_world_keeps_its_places_at_rest_and_unstressed() {
        let mut p = Particles::default();
        p.x.push(Vec3::new(0.1, 0.2, 0.3));
        p.v.push(Vec3::new(5.0, -1.0, 2.0));
        p.c.push(Mat3::from_diagonal(Vec3::splat(3.0)));
        p.f.push(Mat3::from_diagonal(Vec3::splat(1.5)));
        p.plastic.push(0.9);
        p.mass.push(1.0);
        p.vol0.push(1.0);
        p.material.push(0);
        let q = parked(&p);
        assert_eq!(q.x, p.x);
        assert_eq!(q.v[0], Vec3::ZERO);
        assert_eq!(q.c[0], Mat3::ZERO);
        assert_eq!(q.f[0], Mat3::IDENTITY);
        assert_eq!((q.mass.clone(), q.material.clone()), (p.mass, p.material));
    }
}
