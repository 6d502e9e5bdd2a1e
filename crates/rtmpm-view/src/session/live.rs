//! The session's state and loop: commands, stepping, drawing.

use super::options::{SceneInfo, SessionOptions, SimFactory, Summary};
use super::present::Present;
use crate::camera::OrbitCamera;
use crate::command::{Command, Pace, Throw};
use crate::draw::draw;
use crate::frame::{FrameSlot, Status};
use crate::record::Recorder;
use crate::steer::{ToolDrag, ball, pick_depth, ray_enters_box};
use glam::Vec3;
use rtmpm_driver::Simulation;
use rtmpm_driver::run::{Run, RunOptions};
use rtmpm_geometry::{Tool, ToolShape};
use rtmpm_physics::Particles;
use rtmpm_render::{Camera, Image, MAX_VIEW_SIDE, ViewRequest};
use rtmpm_scene::ColorBy;
use rtmpm_scene::Scene;
use rtmpm_scene::sampling::per_axis;
use rtmpm_scene::settings::StepMode;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

/// How long an idle (paused) session waits for a command before looking again.
const IDLE_WAIT: Duration = Duration::from_millis(200);
/// Smallest image side a front-end may ask for.
const MIN_SIDE: u32 = 16;
/// The tool moves at most this fraction of a cell per step.
const TOOL_CELLS_PER_STEP: f32 = 0.3;

/// A live simulation (driven through the run driver's [`Run`], as `rtmpm run` drives one) and
/// everything about how it is shown.
pub(super) struct Live {
    run: Run,
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
    throws: u64,
    /// The pictures: published, in flight, timed.
    present: Present,
    /// When the timing began (the end of the first simulated frame).
    timed_from: Option<Instant>,
}

impl Live {
    pub(super) fn new(
        sim: Simulation,
        factory: SimFactory,
        mut opts: SessionOptions,
        recorder: Option<Recorder>,
        slot: Arc<FrameSlot>,
    ) -> Result<Live, String> {
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
        Ok(Live {
            present: Present::new(slot, recorder, opts.hud),
            timed_from: None,
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
            throws: 0,
            run: run_of(sim)?,
            factory,
            opts,
        })
    }

    pub(super) fn info(&self) -> SceneInfo {
        let s = &self.run.sim.scene;
        SceneInfo {
            name: s.name.clone(),
            materials: s.materials.iter().map(|m| m.name.clone()).collect(),
            backend: self.run.sim.backend.name(),
            fps: s.time.fps,
            duration: s.time.duration,
        }
    }

    /// The loop: until Quit, the frame limit or the front-ends have all gone.
    pub(super) fn run(mut self, rx: &Receiver<Command>) -> Summary {
        'session: loop {
            // First: an error before the loop (the first picture could not be drawn) idles
            // below, waiting for commands that a recording without a front-end never sends.
            if self.limit_reached() {
                break;
            }
            let idle = self.paused || self.error.is_some();
            if idle && !self.dirty {
                // The last picture is shown while idle.
                self.collect();
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
                self.publish();
            }
        }
        self.collect();
        self.summary()
    }

    /// A session of `max_frames` frames (a recording without a front-end) has them, or has
    /// stopped on an error.
    fn limit_reached(&self) -> bool {
        self.opts
            .max_frames
            .is_some_and(|n| self.run.sim.frame >= n || self.error.is_some())
    }

    fn summary(mut self) -> Summary {
        let mut timing = self.present.timing.clone();
        timing.wall_s = self.timed_from.map_or(0.0, |t| t.elapsed().as_secs_f64());
        let sim = &self.run.sim;
        let (frames, steps, time) = (sim.frame, sim.step, sim.time);
        let error = self.error.take();
        Summary {
            displayed: self.present.seq,
            frames,
            steps,
            time,
            recording: self.present.finish_recording(),
            error,
            timing,
        }
    }

    /// The outcome of stepping: an error stops the stepping and is shown.
    fn stepped(&mut self, r: Result<(), String>) {
        self.dirty = true;
        self.fresh = false;
        if let Some(e) = self.present.failed.take() {
            self.error.get_or_insert(e);
        }
        if let Err(e) = r {
            self.error = Some(e);
            return;
        }
        // A session of `max_frames` frames ends there, past the scene's end too (as `rtmpm run
        // --frames N`): no pause that nothing would resume.
        let end = self.run.sim.scene.time.duration as f64;
        if !self.ended
            && self.opts.max_frames.is_none()
            && self.run.sim.time >= end - 1e-9 * end.max(1.0)
        {
            self.ended = true;
            self.paused = true;
            self.message = Some(format!(
                "end of the scene at t = {:.3} s: paused (resume to go on, or reset)",
                self.run.sim.time
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
        self.collect();
        match (self.factory)().and_then(run_of) {
            Ok(run) => {
                self.run = run;
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
        if !self.fresh
            && self
                .run
                .sim
                .backend
                .read_particles(&mut self.particles)
                .is_ok()
        {
            self.fresh = true;
        }
        let reach = self.run.sim.scene.dx;
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
        self.message = Some(match self.run.sim.set_gravity(g) {
            Ok(()) => format!("gravity ({:.3}, {:.3}, {:.3}) m/s^2", g.x, g.y, g.z),
            Err(e) => e.to_string(),
        });
    }

    /// Throw a ball through pixel `(t.x, t.y)`: it starts where the ray enters the domain's
    /// interior (less the ball) and flies along the ray.
    fn throw(&mut self, t: &Throw) {
        let scene = &self.run.sim.scene;
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
            Ok(p) => match self.run.sim.backend.add_particles(&p) {
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
        if self.run.sim.last_dt > 0.0 {
            return self.run.sim.last_dt;
        }
        match self.run.sim.scene.time.step {
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
        TOOL_CELLS_PER_STEP * self.run.sim.scene.dx / dt.max(1e-12)
    }

    /// Advance by the pace; the held tool is aimed over the time it covers.
    fn advance(&mut self) -> Result<(), String> {
        let fd = self.run.sim.frame_duration();
        let duration = match self.pace {
            Pace::Frames(k) => (self.run.sim.frame + k as u64) as f64 * fd - self.run.sim.time,
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
    fn steps(&mut self, n: u64) -> Result<u64, String> {
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
    /// moves (it moves between steps). A picture in flight is collected once the steps are
    /// queued. Returns the steps taken and whether a frame ended.
    fn chunk(&mut self, max: u64) -> Result<(u64, bool), String> {
        let moving = self.tool.moving();
        let tool = self.tool.tool();
        if tool != self.sent_tool {
            self.run
                .sim
                .backend
                .set_tool(tool)
                .map_err(|e| e.to_string())?;
            self.sent_tool = tool;
        }
        let (s0, t0) = (self.run.sim.step, self.run.sim.time);
        let clock = Instant::now();
        let r = self
            .run
            .advance(if moving { 1 } else { max }, &mut self.present);
        self.present.timing.step_s += clock.elapsed().as_secs_f64();
        // A picture still in flight (a step failed before the steps were all queued).
        self.collect();
        let done = r.map_err(|e| format!("{e:#}"))?;
        let taken = self.run.sim.step - s0;
        if self.first_dt == 0.0 && self.run.sim.last_dt > 0.0 {
            self.first_dt = self.run.sim.last_dt;
        }
        self.tool.advance(self.run.sim.time - t0);
        self.present
            .rates
            .stepped(taken, self.run.sim.backend.num_particles() as u64);
        self.present.timing.steps += taken;
        if done {
            self.steps_per_frame = (self.run.sim.step - self.frame_start_step).max(1);
            self.frame_start_step = self.run.sim.step;
            self.present.timing.frames += 1;
            if self.timed_from.is_none() {
                // Timed from here: the first frame built the backend's first mapping.
                self.timed_from = Some(Instant::now());
                self.present.timing = Default::default();
            }
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
            time: self.run.sim.time as f32,
        }
    }

    /// Collect the picture in flight, if any, and publish it.
    pub(super) fn collect(&mut self) {
        if self.present.pending() {
            self.present.finish(self.run.sim.backend.as_mut());
            if let Some(e) = self.present.failed.take() {
                self.error.get_or_insert(e);
            }
        }
    }

    /// Draw the current state and publish it: begun on the backend and collected once the
    /// next steps are queued (or before anything else is shown), or drawn and published now.
    pub(super) fn publish(&mut self) {
        self.collect();
        self.dirty = false;
        let req = self.request();
        if self.opts.overlap && self.error.is_none() && !self.paused {
            let t0 = Instant::now();
            match self.run.sim.backend.begin_view(&req) {
                Ok(true) => {
                    let status = self.status(&req, None);
                    let status = self.present.next_status(status);
                    let ms = t0.elapsed().as_secs_f64() * 1e3;
                    self.present.timing.begin_s += ms * 1e-3;
                    self.present.began(status, ms);
                    return;
                }
                Ok(false) => {}
                Err(e) => {
                    self.error
                        .get_or_insert(format!("cannot draw the view: {e}"));
                }
            }
        }
        self.publish_now(&req);
    }

    /// Draw `req` at once and publish it.
    fn publish_now(&mut self, req: &ViewRequest) {
        let t0 = Instant::now();
        let tool = self.tool.tool();
        let (image, com) = match draw(
            self.run.sim.backend.as_mut(),
            &self.run.sim.scene,
            req,
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
        self.present.timing.draw_s += render_ms * 1e-3;
        let mut status = self.status(req, com);
        status.render_ms = render_ms;
        let status = self.present.next_status(status);
        self.present.show(image, status);
    }

    /// The status of the current state as `req` shows it (numbered and rated by
    /// [`Present::next_status`]).
    fn status(&self, req: &ViewRequest, com: Option<[f64; 3]>) -> Status {
        let sim = &self.run.sim;
        Status {
            time: sim.time,
            frame: sim.frame,
            step: sim.step,
            particles: sim.backend.num_particles() as u64,
            paused: self.paused,
            pace: self.pace.to_string(),
            color_by: self.opts.color_by.name().to_string(),
            gravity: sim.scene.gravity.to_array(),
            center_of_mass: com.filter(|c| c.iter().all(|x| x.is_finite())),
            tool: self.tool.tool().map(|t| t.center.to_array()),
            backend: sim.backend.name(),
            width: req.width,
            height: req.height,
            error: self.error.clone(),
            message: self.message.clone(),
            ..Default::default()
        }
    }
}

/// Splat radius from the scene: 0.6 of the first body's particle spacing (8 per cell when
/// the scene has no body).
fn default_radius(scene: &Scene) -> f32 {
    let ppc = scene.bodies.first().map_or(8, |b| b.particles_per_cell);
    0.6 * scene.dx / per_axis(ppc) as f32
}

/// A simulation as the run driver drives it, writing nothing (a live view shows it instead).
fn run_of(sim: Simulation) -> Result<Run, String> {
    let particles = sim.backend.num_particles();
    let options = RunOptions {
        frames: None,
        steps: None,
        checkpoint_every: None,
        out_dir: std::path::PathBuf::new(),
        writer: false,
        write_frames: false,
        read_frames: false,
        stream: false,
        frame_chunk: rtmpm_driver::stream::DEFAULT_CHUNK,
        frames_in_flight: 1,
        collect: false,
        fixed_chunk: None,
    };
    let mut run = Run::new(sim, particles, String::new(), "rtmpm view", None, options)
        .map_err(|e| format!("{e:#}"))?;
    run.begin(&mut NoHooks).map_err(|e| format!("{e:#}"))?;
    Ok(run)
}

/// Hooks that do nothing.
struct NoHooks;

impl rtmpm_driver::run::RunHooks for NoHooks {}
