//! The session's state and loop: commands, stepping, drawing.

use super::options::{SceneInfo, SessionOptions, SimFactory, Summary};
use super::rates::Rates;
use crate::camera::OrbitCamera;
use crate::command::{Command, Pace, Throw};
use crate::draw::{draw, draw_hud, draw_message};
use crate::frame::{Frame, FrameSlot, Status};
use crate::record::Recorder;
use crate::steer::{ToolDrag, ball, pick_depth, ray_enters_box};
use glam::Vec3;
use rtmpm_driver::Simulation;
use rtmpm_geometry::{Tool, ToolShape};
use rtmpm_physics::Particles;
use rtmpm_render::{Camera, Image, MAX_VIEW_SIDE, ViewRequest};
use rtmpm_scene::ColorBy;
use rtmpm_scene::Scene;
use rtmpm_scene::sampling::per_axis;
use rtmpm_scene::settings::StepMode;
use rtmpm_sim::SimError;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

/// How long an idle (paused) session waits for a command before looking again.
const IDLE_WAIT: Duration = Duration::from_millis(200);
/// Smallest image side a front-end may ask for.
const MIN_SIDE: u32 = 16;
/// The tool moves at most this fraction of a cell per step.
const TOOL_CELLS_PER_STEP: f32 = 0.3;

/// A live simulation and everything about how it is shown.
pub(super) struct Live {
    sim: Simulation,
    factory: SimFactory,
    opts: SessionOptions,
    orbit: OrbitCamera,
    radius: f32,
    pace: Pace,
    paused: bool,
    tool: ToolDrag,
    /// The tool as the backend has it.
    sent_tool: Option<Tool>,
    /// The first step's dt: the tool's speed limit comes from it (a limit from the current dt
    /// would grow with the speeds the tool itself causes).
    first_dt: f32,
    /// Steps of the last completed frame (the pace ladder's measure).
    steps_per_frame: u64,
    frame_start_step: u64,
    error: Option<String>,
    message: Option<String>,
    /// The scene's end was reached and the session paused there once.
    ended: bool,
    particles: Particles,
    /// `particles` hold the current state.
    fresh: bool,
    /// Something shown changed since the last picture.
    dirty: bool,
    seq: u64,
    throws: u64,
    rates: Rates,
    recorder: Option<Recorder>,
    recording_error: Option<String>,
}

impl Live {
    pub(super) fn new(
        sim: Simulation,
        factory: SimFactory,
        mut opts: SessionOptions,
        recorder: Option<Recorder>,
    ) -> Live {
        opts.width = opts.width.clamp(MIN_SIDE, MAX_VIEW_SIDE);
        opts.height = opts.height.clamp(MIN_SIDE, MAX_VIEW_SIDE);
        let scene = &sim.scene;
        let (lo, hi) = scene.interior();
        let camera = opts.camera.unwrap_or_else(|| {
            Camera::framing(
                lo,
                hi,
                opts.width as f32 / opts.height as f32,
                Camera::DEFAULT_FOV,
            )
        });
        let radius = opts.radius.unwrap_or_else(|| default_radius(scene));
        let shape = opts.tool.unwrap_or(ToolShape::Sphere {
            radius: ((hi - lo).min_element() / 8.0).max(2.0 * scene.dx),
        });
        Live {
            orbit: OrbitCamera::from_camera(camera),
            radius,
            pace: opts.pace,
            paused: opts.paused,
            tool: ToolDrag::new(shape, (scene.domain_min, scene.domain_max)),
            sent_tool: None,
            first_dt: 0.0,
            steps_per_frame: 1,
            frame_start_step: 0,
            error: None,
            message: None,
            ended: false,
            particles: Particles::default(),
            fresh: false,
            dirty: true,
            seq: 0,
            throws: 0,
            rates: Rates::default(),
            recorder,
            recording_error: None,
            sim,
            factory,
            opts,
        }
    }

    pub(super) fn info(&self) -> SceneInfo {
        let s = &self.sim.scene;
        SceneInfo {
            name: s.name.clone(),
            materials: s.materials.iter().map(|m| m.name.clone()).collect(),
            backend: self.sim.backend.name(),
            fps: s.time.fps,
            duration: s.time.duration,
        }
    }

    /// The loop: until Quit, the frame limit or the front-ends have all gone.
    pub(super) fn run(mut self, rx: &Receiver<Command>, slot: &FrameSlot) -> Summary {
        'session: loop {
            let idle = self.paused || self.error.is_some();
            if idle && !self.dirty {
                match rx.recv_timeout(IDLE_WAIT) {
                    Ok(Command::Quit) | Err(RecvTimeoutError::Disconnected) => break 'session,
                    Ok(c) => self.apply(c),
                    Err(RecvTimeoutError::Timeout) => continue,
                }
            }
            while let Ok(c) = rx.try_recv() {
                if c == Command::Quit {
                    break 'session;
                }
                self.apply(c);
            }
            if !self.paused && self.error.is_none() {
                let r = self.advance();
                self.stepped(r);
            }
            if self.dirty {
                self.publish(slot);
            }
            if self
                .opts
                .max_frames
                .is_some_and(|n| self.sim.frame >= n || self.error.is_some())
            {
                break;
            }
        }
        self.summary()
    }

    fn summary(self) -> Summary {
        let recording = match (self.recorder, self.recording_error) {
            (_, Some(e)) => Some(Err(e)),
            (Some(r), None) => Some(r.finish()),
            (None, None) => None,
        };
        Summary {
            displayed: self.seq,
            frames: self.sim.frame,
            steps: self.sim.step,
            time: self.sim.time,
            recording,
            error: self.error,
        }
    }

    /// The outcome of stepping: an error stops the stepping and is shown.
    fn stepped(&mut self, r: Result<(), SimError>) {
        self.dirty = true;
        self.fresh = false;
        if let Err(e) = r {
            self.error = Some(e.to_string());
            return;
        }
        let end = self.sim.scene.time.duration as f64;
        if !self.ended && self.sim.time >= end - 1e-9 * end.max(1.0) {
            self.ended = true;
            self.paused = true;
            self.message = Some(format!(
                "end of the scene at t = {:.3} s: paused (resume to go on, or reset)",
                self.sim.time
            ));
        }
    }

    // ------------------------------------------------------------------ commands

    fn apply(&mut self, c: Command) {
        self.dirty = true;
        let spf = self.steps_per_frame;
        match c {
            Command::Pause => self.paused = true,
            Command::Resume => self.paused = false,
            Command::TogglePause => self.paused = !self.paused,
            Command::Step => {
                self.paused = true;
                if self.error.is_none() {
                    let r = self.steps(1).map(|_| ());
                    self.stepped(r);
                }
            }
            Command::Reset => self.reset(),
            Command::Slower => self.pace = self.pace.slower(spf),
            Command::Faster => self.pace = self.pace.faster(spf),
            Command::SetPace(p) => self.pace = p,
            Command::ColorBy(c) => self.opts.color_by = c,
            Command::CycleColor => {
                let all = ColorBy::ALL;
                let i = all
                    .iter()
                    .position(|&c| c == self.opts.color_by)
                    .unwrap_or(0);
                self.opts.color_by = all[(i + 1) % all.len()];
            }
            Command::Orbit { dx, dy } => self.orbit.orbit(dx, dy),
            Command::Pan { dx, dy } => self.orbit.pan(dx, dy, self.opts.height),
            Command::Zoom(f) => self.orbit.zoom(f),
            Command::CameraReset => self.orbit.reset(),
            Command::Resize { width, height } => {
                self.opts.width = width.clamp(MIN_SIDE, MAX_VIEW_SIDE);
                self.opts.height = height.clamp(MIN_SIDE, MAX_VIEW_SIDE);
            }
            Command::ToolStart { x, y } => self.grab(x, y),
            Command::ToolMove { x, y } => {
                let (eye, ray) = self.ray(x, y);
                self.tool.aim(eye, ray);
            }
            Command::ToolDepth(f) => self.tool.push(f),
            Command::ToolEnd => {
                if self.tool.held() {
                    self.message = Some("tool released".into());
                }
                self.tool.release();
            }
            Command::ToolShape(s) => self.set_tool_shape(s),
            Command::Throw(t) => self.throw(&t),
            Command::Gravity(g) => self.set_gravity(g),
            Command::Quit => {}
        }
    }

    fn reset(&mut self) {
        match (self.factory)() {
            Ok(sim) => {
                self.sim = sim;
                self.error = None;
                self.ended = false;
                self.tool.release();
                self.sent_tool = None;
                self.fresh = false;
                self.frame_start_step = 0;
                self.message = Some("reset to t = 0".into());
            }
            Err(e) => self.error = Some(format!("reset failed: {e}")),
        }
    }

    /// The eye and the pixel ray of `(x, y)` (clamped to the image).
    fn ray(&self, x: f32, y: f32) -> (Vec3, Vec3) {
        let (w, h) = (self.opts.width, self.opts.height);
        let x = if x.is_finite() {
            x.clamp(0.0, w as f32)
        } else {
            0.5 * w as f32
        };
        let y = if y.is_finite() {
            y.clamp(0.0, h as f32)
        } else {
            0.5 * h as f32
        };
        let cam = self.orbit.camera();
        (cam.position, cam.pixel_ray(w, h, x, y))
    }

    /// Grab the tool at pixel `(x, y)`: at the depth where the ray meets the material (the
    /// nearest particle within a cell of it), else of the camera's target.
    fn grab(&mut self, x: f32, y: f32) {
        let (eye, ray) = self.ray(x, y);
        let cam = self.orbit.camera();
        if !self.fresh && self.sim.backend.read_particles(&mut self.particles).is_ok() {
            self.fresh = true;
        }
        let reach = self.sim.scene.dx;
        let fwd = (cam.target - cam.position).normalize_or(Vec3::NEG_Z);
        let depth = pick_depth(&self.particles.x, &cam, ray, reach)
            .unwrap_or_else(|| (cam.target - cam.position).dot(fwd));
        self.tool.grab(eye, ray, depth);
        self.message = Some("tool grabbed: drag it through the material".into());
    }

    fn set_tool_shape(&mut self, s: ToolShape) {
        let t = Tool {
            shape: s,
            center: Vec3::ZERO,
            velocity: Vec3::ZERO,
        };
        match t.check() {
            Ok(()) => self.tool.shape = s,
            Err(e) => self.message = Some(e),
        }
    }

    fn set_gravity(&mut self, g: Vec3) {
        self.message = Some(match self.sim.set_gravity(g) {
            Ok(()) => format!("gravity ({:.3}, {:.3}, {:.3}) m/s^2", g.x, g.y, g.z),
            Err(e) => e.to_string(),
        });
    }

    /// Throw a ball through pixel `(t.x, t.y)`: it starts where the ray enters the domain's
    /// interior (less the ball) and flies along the ray.
    fn throw(&mut self, t: &Throw) {
        let scene = &self.sim.scene;
        let (lo, hi) = scene.interior();
        let side = (hi - lo).min_element();
        let radius = t.radius.unwrap_or((side / 10.0).max(2.0 * scene.dx));
        let speed = t.speed.unwrap_or(2.0 * side);
        let material = t.material.unwrap_or(0);
        let (eye, ray) = self.ray(t.x, t.y);
        let dir = ray.normalize_or(Vec3::NEG_Z);
        let margin = Vec3::splat(radius + scene.dx);
        let made = match ray_enters_box(eye, dir, lo + margin, hi - margin) {
            None => Err("aim at the domain to throw a ball".to_string()),
            Some(s) => {
                self.throws += 1;
                let seed = scene.seed ^ self.throws.wrapping_mul(0x9e37_79b9_7f4a_7c15);
                ball(scene, material, eye + dir * s, radius, dir * speed, seed)
            }
        };
        self.message = Some(match made {
            Err(e) => e,
            Ok(p) => match self.sim.backend.add_particles(&p) {
                Ok(()) => {
                    self.fresh = false;
                    format!(
                        "threw {} particles of `{}` at {speed:.2} m/s",
                        p.len(),
                        scene.materials[material].name
                    )
                }
                Err(e) => e.to_string(),
            },
        });
    }

    // ------------------------------------------------------------------ stepping

    /// The time step to plan with: the last one, else the scene's.
    fn dt_estimate(&self) -> f32 {
        if self.sim.last_dt > 0.0 {
            return self.sim.last_dt;
        }
        match self.sim.scene.time.step {
            StepMode::Fixed { dt } => dt,
            StepMode::Cfl { max_dt, .. } => max_dt,
        }
    }

    /// Fastest the tool may go (m/s): a fraction of a cell per step of the first step's size.
    fn tool_speed_limit(&self) -> f32 {
        let dt = if self.first_dt > 0.0 {
            self.first_dt
        } else {
            self.dt_estimate()
        };
        TOOL_CELLS_PER_STEP * self.sim.scene.dx / dt.max(1e-12)
    }

    /// Advance by the pace; the held tool is aimed over the time it covers.
    fn advance(&mut self) -> Result<(), SimError> {
        let fd = self.sim.frame_duration();
        let duration = match self.pace {
            Pace::Frames(k) => (self.sim.frame + k as u64) as f64 * fd - self.sim.time,
            Pace::Steps(n) => n as f64 * self.dt_estimate() as f64,
        };
        let limit = self.tool_speed_limit();
        self.tool.plan(duration, limit);
        match self.pace {
            Pace::Frames(k) => {
                for _ in 0..k {
                    while !self.chunk(u64::MAX)?.1 {}
                }
                Ok(())
            }
            Pace::Steps(n) => self.steps(n as u64).map(|_| ()),
        }
    }

    /// Take `n` steps (fewer only if the simulation stops taking any).
    fn steps(&mut self, n: u64) -> Result<u64, SimError> {
        let mut left = n;
        while left > 0 {
            let (taken, _) = self.chunk(left)?;
            if taken == 0 {
                break;
            }
            left -= taken.min(left);
        }
        Ok(n - left)
    }

    /// At most `max` steps, up to the end of the current frame; one step while the tool
    /// moves (it moves between steps). Returns the steps taken and whether a frame ended.
    fn chunk(&mut self, max: u64) -> Result<(u64, bool), SimError> {
        let moving = self.tool.moving();
        let tool = self.tool.tool();
        if tool != self.sent_tool {
            self.sim.backend.set_tool(tool)?;
            self.sent_tool = tool;
        }
        let (s0, t0) = (self.sim.step, self.sim.time);
        let done = self.sim.advance(if moving { 1 } else { max })?;
        let taken = self.sim.step - s0;
        if self.first_dt == 0.0 && self.sim.last_dt > 0.0 {
            self.first_dt = self.sim.last_dt;
        }
        self.tool.advance(self.sim.time - t0);
        self.rates
            .stepped(taken, self.sim.backend.num_particles() as u64);
        if done {
            self.steps_per_frame = (self.sim.step - self.frame_start_step).max(1);
            self.frame_start_step = self.sim.step;
        }
        Ok((taken, done))
    }

    // ------------------------------------------------------------------ drawing

    fn request(&self) -> ViewRequest {
        ViewRequest {
            camera: self.orbit.camera(),
            width: self.opts.width,
            height: self.opts.height,
            color_by: self.opts.color_by,
            range: self.opts.range,
            radius: self.radius,
            colliders: true,
            floor: true,
            shadows: self.opts.shadows,
            time: self.sim.time as f32,
        }
    }

    /// Draw, publish and record the current state.
    pub(super) fn publish(&mut self, slot: &FrameSlot) {
        let t0 = Instant::now();
        let req = self.request();
        let tool = self.tool.tool();
        let (mut image, com) = match draw(
            self.sim.backend.as_mut(),
            &self.sim.scene,
            &req,
            tool.as_ref(),
            &mut self.particles,
        ) {
            Ok(d) => {
                self.fresh = d.read_particles;
                let com = d.read_particles.then(|| self.particles.center_of_mass());
                (d.image, com)
            }
            Err(e) => {
                self.error
                    .get_or_insert(format!("cannot draw the view: {e}"));
                (Image::new(req.width, req.height, [30, 30, 36]), None)
            }
        };
        let render_ms = t0.elapsed().as_secs_f64() * 1e3;
        self.seq += 1;
        let (steps_per_s, particle_steps_per_s, fps) = self.rates.sample(Instant::now(), self.seq);
        let status = Status {
            seq: self.seq,
            time: self.sim.time,
            frame: self.sim.frame,
            step: self.sim.step,
            particles: self.sim.backend.num_particles() as u64,
            steps_per_s,
            particle_steps_per_s,
            fps,
            render_ms,
            paused: self.paused,
            pace: self.pace.to_string(),
            color_by: self.opts.color_by.name().to_string(),
            gravity: self.sim.scene.gravity.to_array(),
            center_of_mass: com.filter(|c| c.iter().all(|x| x.is_finite())),
            tool: tool.map(|t| t.center.to_array()),
            backend: self.sim.backend.name(),
            width: req.width,
            height: req.height,
            error: self.error.clone(),
            message: self.message.clone(),
        };
        if self.opts.hud {
            draw_hud(&mut image, &hud_line(&status));
        }
        if let Some(e) = &self.error {
            draw_message(&mut image, e);
        }
        let frame = Arc::new(Frame { image, status });
        slot.publish(frame.clone());
        if let Some(r) = &self.recorder
            && let Err(e) = r.add(frame)
        {
            self.recording_error = Some(e);
            self.recorder = None;
        }
        self.dirty = false;
    }
}

/// The heads-up line: time, frame, particles, rates (parts separated by two spaces).
pub(crate) fn hud_line(s: &Status) -> String {
    let mut parts = vec![
        format!("T {:.3} S", s.time),
        format!("FRAME {}", s.frame),
        format!("{} PARTICLES", s.particles),
        format!("{:.0} STEPS/S", s.steps_per_s),
        format!("{:.2E} PARTICLE-STEPS/S", s.particle_steps_per_s),
        format!("{:.1} FPS", s.fps),
        format!("PACE {}", s.pace.to_uppercase()),
    ];
    if s.paused {
        parts.push("PAUSED".into());
    }
    parts.join("  ")
}

/// Splat radius from the scene: 0.6 of the first body's particle spacing (8 per cell when
/// the scene has no body).
fn default_radius(scene: &Scene) -> f32 {
    let ppc = scene.bodies.first().map_or(8, |b| b.particles_per_cell);
    0.6 * scene.dx / per_axis(ppc) as f32
}
