//! The driver of a run: [`Simulation`] steps a backend through the frames of a scene. It chooses
//! the time steps (fixed, or CFL-adaptive with a cap), lands every frame exactly on its time,
//! hands the backend the emitters' particles before the step they appear in, and reports
//! blow-ups with the particle, its material and advice.

use rtmpm_physics::math::Vec3;
use rtmpm_scene::{Scene, StepMode, speeds};
use rtmpm_sim::{Backend, BadReason, Blowup, MAX_CELLS_PER_STEP, Particles, SimError};

/// Drives a backend through frames of a scene. The backend is a `Box<dyn Backend>` by default;
/// a caller that needs the concrete type (or `Send`) names it, e.g. `Simulation<MyBackend>`.
pub struct Simulation<B: Backend + ?Sized = dyn Backend> {
    pub scene: Scene,
    pub backend: Box<B>,
    /// Simulated time (s).
    pub time: f64,
    /// Steps taken so far.
    pub step: u64,
    /// Frames completed so far.
    pub frame: u64,
    /// Time step of the last step.
    pub last_dt: f32,
    max_sound_speed: f32,
    /// Simulated time of the last health check that passed (the blow-up a check finds
    /// happened after it).
    checked_time: f64,
    /// Particles each emitter has emitted so far; set at the first step from the time then
    /// (a resumed run starts with those of its checkpoint).
    emitted: Option<Vec<u64>>,
}

impl Simulation {
    /// A simulation at time 0 (or at the given state when resuming).
    pub fn new(scene: Scene, backend: Box<dyn Backend>) -> Simulation {
        Simulation::with_backend(scene, backend)
    }
}

/// Which checks an advance makes ([`Simulation::advance_with`] and its variants).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Checks {
    /// Every frame end's and the last step's.
    All,
    /// A frame end's where the call goes on past it, not the last step's.
    NotLast,
    /// None.
    None,
}

impl<B: Backend + ?Sized> Simulation<B> {
    /// A simulation of a backend of type `B` (see [`Simulation::new`] for the usual
    /// `Box<dyn Backend>`).
    pub fn with_backend(scene: Scene, backend: Box<B>) -> Simulation<B> {
        let max_sound_speed = scene
            .materials
            .iter()
            .map(|m| m.model.sound_speed(m.density))
            .fold(0.0f32, f32::max);
        Simulation {
            scene,
            backend,
            time: 0.0,
            step: 0,
            frame: 0,
            last_dt: 0.0,
            max_sound_speed,
            checked_time: 0.0,
            emitted: None,
        }
    }

    /// Change gravity from the next step on: the backend's and the scene's
    /// ([`Backend::set_gravity`]); a non-finite vector is refused.
    pub fn set_gravity(&mut self, gravity: Vec3) -> Result<(), SimError> {
        if !gravity.is_finite() {
            return Err(SimError::Backend(format!(
                "gravity must be finite, got {gravity}"
            )));
        }
        self.backend.set_gravity(gravity)?;
        self.scene.gravity = gravity;
        Ok(())
    }

    /// Duration of one frame (s).
    pub fn frame_duration(&self) -> f64 {
        1.0 / self.scene.time.fps as f64
    }

    /// Time step for the next step, before clipping to the frame end.
    pub fn next_dt(&mut self) -> Result<f32, SimError> {
        Ok(match self.scene.time.step {
            StepMode::Fixed { dt } => dt,
            StepMode::Cfl {
                cfl,
                max_dt,
                min_dt,
            } => {
                // The fastest particle or boundary (colliders, rigid bodies, emitters: the
                // material they meet takes their speed within the step), and gravity's bound.
                let particles = self.backend.max_speed()?;
                let now = (self.time, self.time);
                let boundary = self.fastest_boundary(now).map_or(0.0, |b| b.speed as f32);
                let (dx, sound) = (self.scene.dx, self.max_sound_speed);
                let gravity_dt = speeds::gravity_dt(self.scene.gravity, dx, cfl);
                let step_for = |boundary: f32| {
                    let speed = particles.max(boundary) + sound;
                    let dt = if speed > 0.0 {
                        (cfl * dx / speed).min(max_dt)
                    } else {
                        max_dt
                    };
                    dt.min(gravity_dt)
                };
                let dt = step_for(boundary);
                // NaN speeds are the health check's (a blow-up); a finite collapse is a stall.
                if dt < min_dt {
                    return Err(self.stall(dt, min_dt));
                }
                // A faster keyframed segment starting within the step: the step ends there
                // (or follows it), so that the collider never moves unseen.
                speeds::keyframe_step(&self.scene, self.time, dt, step_for)
            }
        })
    }

    /// The error of a CFL step `dt` below `min_dt`, naming the fastest particle.
    fn stall(&mut self, dt: f32, min_dt: f32) -> SimError {
        let mut p = Particles::default();
        if let Err(e) = self.backend.read_particles(&mut p) {
            return e;
        }
        let (i, speed) =
            p.v.iter()
                .map(|v| v.length())
                .enumerate()
                .fold((0, f32::NEG_INFINITY), |a, b| if b.1 > a.1 { b } else { a });
        let material = p
            .material
            .get(i)
            .and_then(|&m| self.scene.materials.get(m as usize))
            .map(|m| m.name.clone())
            .unwrap_or_else(|| "?".into());
        SimError::Stall(Box::new(Blowup {
            step: self.step,
            time: self.time,
            particle: i,
            position: p.x.get(i).copied().unwrap_or(Vec3::NAN),
            velocity: p.v.get(i).copied().unwrap_or(Vec3::NAN),
            material,
            reason: format!(
                "the CFL step is {dt:.3e} s, below time.min_dt = {min_dt:.3e} s (fastest \
                 particle at {speed:.4e} m/s, sound speed {:.4e} m/s)",
                self.max_sound_speed
            ),
            dt,
            advice: self.stall_advice(dt, speed),
        }))
    }

    /// The fastest boundary or emitter over the times `window` ([`speeds::fastest_boundary`]).
    fn fastest_boundary(&self, window: (f64, f64)) -> Option<speeds::SpeedSource> {
        if self.scene.colliders.is_empty()
            && self.scene.rigid_bodies.is_empty()
            && self.scene.emitters.is_empty()
        {
            return None;
        }
        speeds::fastest_boundary(&self.scene, window, &self.backend.rigid_bodies())
    }

    /// What made the CFL step collapse to `dt` when it is not the fastest particle (at
    /// `particle_speed`): a boundary or emitter faster than it, or gravity's bound.
    fn stall_advice(&self, dt: f32, particle_speed: f32) -> Option<String> {
        let cfl = match self.scene.time.step {
            StepMode::Cfl { cfl, .. } => cfl,
            StepMode::Fixed { .. } => return None,
        };
        let g = speeds::norm(self.scene.gravity);
        if dt >= speeds::gravity_dt(self.scene.gravity, self.scene.dx, cfl) * 0.999 {
            return Some(format!(
                "gravity ({g:.4e} m/s^2) asks for steps of at most sqrt(cfl dx / |g|) = {dt:.3e} s \
                 (so that a step adds less than a cell to a fall): lower `gravity` (Earth's is \
                 9.81 m/s^2); or, if it is intended, lower `time.min_dt`"
            ));
        }
        let b = self.fastest_boundary((self.time, self.time))?;
        (b.speed as f32 > particle_speed).then(|| {
            format!(
                "{} moves at {:.4e} m/s, and the step follows it so that the material it meets \
                 moves less than a cell per step: lower `{}`; or, if the speed is intended, lower \
                 `time.min_dt`",
                b.what, b.speed, b.field
            )
        })
    }

    /// The cause of a blow-up at step size `dt` of the particle at `x`, when something the step
    /// does not follow moves faster than a cell per step (a fixed `time.dt`, or a step capped
    /// by `time.max_dt` above what the boundaries allow), or an emitter near it piles its
    /// particles up; `None` leaves the generic advice (the step or the stiffness).
    fn blame(&self, dt: f32, x: Vec3) -> Option<String> {
        let dx = self.scene.dx;
        let fix = |field: &str, speed: f64| {
            format!(
                "lower `{field}`, or the time step to at most {:.3e} s (a cell per step: \
                 `time.dt`, or `time.max_dt` with `time.cfl`)",
                dx as f64 / speed
            )
        };
        // Over the steps since the last check that passed (within this frame; at least the
        // last step): a keyframed segment or an emitter may have ended in them.
        let since = self.checked_time.max(self.time - self.frame_duration());
        let since = since.min(self.time - dt as f64);
        if let Some(b) = self.fastest_boundary((since, self.time))
            && b.speed * dt as f64 > dx as f64
        {
            return Some(format!(
                "{} moves at {:.4e} m/s, {:.1} cells in a step of {dt:.3e} s: the material it \
                 meets is flung faster than the step follows; {}",
                b.what,
                b.speed,
                b.speed * dt as f64 / dx as f64,
                fix(&b.field, b.speed)
            ));
        }
        // Gravity: the speed of a fall since the start (at most across the domain).
        let fall =
            (speeds::norm(self.scene.gravity) * self.time).min(speeds::fall_speed(&self.scene));
        if fall * dt as f64 > MAX_CELLS_PER_STEP as f64 * dx as f64 {
            return Some(format!(
                "gravity ({:.4e} m/s^2) makes a fall of {:.4e} m/s by now, {:.1} cells in a step \
                 of {dt:.3e} s; {}",
                speeds::norm(self.scene.gravity),
                fall,
                fall * dt as f64 / dx as f64,
                fix("gravity", fall)
            ));
        }
        let near = |e: &rtmpm_scene::emitter::Emitter| {
            let (lo, hi) = e.shape.bounds();
            x.cmpge(lo - 2.0 * dx).all() && x.cmple(hi + 2.0 * dx).all()
        };
        let (i, e) = self
            .scene
            .emitters
            .iter()
            .enumerate()
            .find(|(_, e)| e.piles_up() && near(e))?;
        Some(format!(
            "emitter[{i}] `{}` emits {:.4e} particles per second, but at its velocity only about \
             {:.4e} per second leave it: they pile up in it, are compressed and burst out; lower \
             `emitter[{i}].rate` (or volume_rate to its flux, cross-section x speed), or raise its \
             velocity",
            e.name,
            e.rate,
            e.outflow()
        ))
    }

    /// One step of size `dt`; the emitters' particles due by its end appear first.
    pub fn step_once(&mut self, dt: f32) -> Result<(), SimError> {
        self.emit(self.time + dt as f64)?;
        self.backend.step(dt, self.time as f32)?;
        self.time += dt as f64;
        self.step += 1;
        self.last_dt = dt;
        if self.backend.cheap_check() {
            self.check()?;
        }
        Ok(())
    }

    /// Advance to the end of the next frame; returns the number of steps taken.
    ///
    /// With a fixed dt that divides the frame duration, exactly that many equal steps are taken;
    /// otherwise the last step is shortened to land on the frame time.
    pub fn advance_frame(&mut self) -> Result<u64, SimError> {
        let start = self.step;
        self.advance(u64::MAX)?;
        Ok(self.step - start)
    }

    /// Advance towards the end of the current frame, taking at most `max_steps` steps. Returns
    /// true when the frame was completed (then [`Simulation::frame`] has moved on).
    pub fn advance(&mut self, max_steps: u64) -> Result<bool, SimError> {
        self.advance_with(max_steps, &mut |_| {})
    }

    /// [`Simulation::advance`], calling `queued` once with the backend when the steps are
    /// queued, before the host first waits for the device: before the check that ends the call
    /// (fixed steps), or before the second step's size is read (CFL steps read the fastest
    /// particle). A caller does its own host work there while the device steps (a live view
    /// finishes its last picture). Not called when a step fails.
    pub fn advance_with(
        &mut self,
        max_steps: u64,
        queued: &mut dyn FnMut(&mut B),
    ) -> Result<bool, SimError> {
        self.advance_checked(max_steps, queued, Checks::All)
    }

    /// [`Simulation::advance`] without the health check of its last step when it takes all
    /// `max_steps` steps (at a frame's end too, whose frame then counts and whose backend's
    /// `end_of_frame` runs before that check): the steps stay queued on a backend that runs
    /// them asynchronously (the GPU), and the caller must [`Simulation::check`] before anything
    /// else steps, reads or changes the backend: that check finds what the skipped one would
    /// have found (no step was taken since), reported at the same step and time. The checks of
    /// earlier steps (a frame ending before the last step) are made as in `advance`.
    pub fn advance_unchecked(&mut self, max_steps: u64) -> Result<bool, SimError> {
        self.advance_checked(max_steps, &mut |_| {}, Checks::NotLast)
    }

    /// [`Simulation::advance_unchecked`] without the check of a frame's end either (the call
    /// ends there, as `advance` does): the caller checks every step it took later, and each frame
    /// end the call ended at (a backend that queues what a check reads, `Worlds::queue_check`,
    /// behind each frame's steps: the lockstep driver's deferred checks).
    pub fn advance_no_checks(&mut self, max_steps: u64) -> Result<bool, SimError> {
        self.advance_checked(max_steps, &mut |_| {}, Checks::None)
    }

    /// [`Simulation::advance_with`], the checks made or left to the caller as `checks` says.
    fn advance_checked(
        &mut self,
        max_steps: u64,
        queued: &mut dyn FnMut(&mut B),
        checks: Checks,
    ) -> Result<bool, SimError> {
        let check_last = checks == Checks::All;
        let check_frame = |taken: u64| match checks {
            Checks::All => true,
            Checks::NotLast => taken < max_steps,
            Checks::None => false,
        };
        let mut called = false;
        let mut once = |b: &mut B| {
            if !called {
                called = true;
                queued(b);
            }
        };
        let frame_start = self.frame as f64 * self.frame_duration();
        let frame_end = (self.frame + 1) as f64 * self.frame_duration();
        let mut taken = 0;
        if let StepMode::Fixed { dt } = self.scene.time.step {
            let per_frame = self.frame_duration() / dt as f64;
            if (per_frame - per_frame.round()).abs() < 1e-6 * per_frame.max(1.0) {
                // Whole number of equal steps per frame: count them, so time never drifts.
                let per_frame = per_frame.round() as u64;
                let done = ((self.time - frame_start) / dt as f64).round() as u64;
                while done + taken < per_frame {
                    if taken == max_steps {
                        once(&mut self.backend);
                        if check_last {
                            self.check()?;
                        }
                        return Ok(false);
                    }
                    self.step_once(dt)?;
                    taken += 1;
                    self.time = frame_start + (done + taken) as f64 * dt as f64;
                }
                self.time = frame_end;
                once(&mut self.backend);
                self.finish_frame(check_frame(taken))?;
                return Ok(true);
            }
        }
        let eps = 1e-9 * self.frame_duration();
        while self.time < frame_end - eps {
            if taken == max_steps {
                once(&mut self.backend);
                if check_last {
                    self.check()?;
                }
                return Ok(false);
            }
            if taken > 0 {
                once(&mut self.backend);
            }
            let dt = self.next_dt()?;
            let remaining = (frame_end - self.time) as f32;
            self.step_once(dt.min(remaining))?;
            taken += 1;
        }
        self.time = frame_end;
        once(&mut self.backend);
        self.finish_frame(check_frame(taken))?;
        Ok(true)
    }

    /// Hand the backend the particles the emitters emit by time `t_end`.
    fn emit(&mut self, t_end: f64) -> Result<(), SimError> {
        let emitters = &self.scene.emitters;
        if emitters.is_empty() {
            return Ok(());
        }
        let time = self.time;
        let emitted = self
            .emitted
            .get_or_insert_with(|| emitters.iter().map(|e| e.count_at(time)).collect());
        let p = rtmpm_scene::emitter::emit_between(emitters, &self.scene.materials, emitted, t_end);
        if p.is_empty() {
            return Ok(());
        }
        self.backend.add_particles(&p)
    }

    /// Particles emitted so far by each emitter of the scene (empty before the first step).
    pub fn emitted(&self) -> &[u64] {
        self.emitted.as_deref().unwrap_or(&[])
    }

    /// The frame counted, checked (unless `check` is false: the caller checks later,
    /// [`Simulation::advance_unchecked`]) and ended on the backend.
    fn finish_frame(&mut self, check: bool) -> Result<(), SimError> {
        self.frame += 1;
        if check {
            self.check()?;
        }
        self.backend.end_of_frame()
    }

    /// Check the backend for a bad particle and turn it into a [`SimError::Blowup`].
    pub fn check(&mut self) -> Result<(), SimError> {
        if let Some(bad) = self.backend.check()? {
            let mut p = Particles::default();
            self.backend.read_particles(&mut p)?;
            let i = bad.index.min(p.len().saturating_sub(1));
            let material = p
                .material
                .get(i)
                .and_then(|&m| self.scene.materials.get(m as usize))
                .map(|m| m.name.clone())
                .unwrap_or_else(|| "?".into());
            // What the health check saw, else the state as stored (a non-finite position is
            // stored clamped to the domain: said so rather than shown as a real place).
            let (position, velocity) = bad.seen.unwrap_or((
                p.x.get(i).copied().unwrap_or(Vec3::NAN),
                p.v.get(i).copied().unwrap_or(Vec3::NAN),
            ));
            let reason = match bad.reason {
                BadReason::NonFinite if bad.seen.is_none() && position.is_finite() => {
                    "position, velocity or deformation gradient is not finite (NaN or infinity; \
                     the position shown is where the step clamped it, at the domain's edge)"
                        .into()
                }
                BadReason::NonFinite => {
                    "position, velocity or deformation gradient is not finite (NaN or infinity)"
                        .into()
                }
                BadReason::TooFast => format!(
                    "speed exceeds {MAX_CELLS_PER_STEP} cells per step (|v| dt > {MAX_CELLS_PER_STEP} dx)"
                ),
            };
            return Err(SimError::Blowup(Box::new(Blowup {
                step: self.step,
                time: self.time,
                particle: bad.index,
                position,
                velocity,
                material,
                reason,
                dt: self.last_dt,
                advice: self.blame(self.last_dt, p.x.get(i).copied().unwrap_or(position)),
            })));
        }
        self.checked_time = self.time;
        Ok(())
    }
}
