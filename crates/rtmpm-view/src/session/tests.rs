//! A live session on the CPU backend, driven by commands as a front-end drives it.

use super::*;
use crate::command::{Pace, Throw};
use crate::frame::{Frame, Status};
use glam::Vec3;
use rtmpm_cpu::CpuBackend;
use rtmpm_driver::Simulation;
use rtmpm_scene::Scene;
use std::time::{Duration, Instant};

const SCENE: &str = "[domain]\nmin = [0,0,0]\nmax = [1,1,1]\ndx = 0.05\n\
    [time]\nduration = 10.0\nfps = 50\ndt = 1e-3\n\
    [[material]]\nname = \"sand\"\ntype = \"drucker_prager\"\ndensity = 1600.0\n\
    youngs_modulus = 3.5e5\npoisson_ratio = 0.3\nfriction_angle = 35.0\n\
    [[material]]\nname = \"water\"\ntype = \"fluid\"\ndensity = 1000.0\nbulk_modulus = 1e4\n\
    [[body]]\nmaterial = \"sand\"\nshape = \"box\"\nmin = [0.3,0.15,0.3]\nmax = [0.7,0.4,0.7]\n";

fn factory(text: &'static str) -> SimFactory {
    Box::new(move || {
        let scene = Scene::from_toml(text, "<test>").map_err(|e| e.to_string())?;
        let p = scene.sample_particles().map_err(|e| e.to_string())?;
        let b = CpuBackend::new(&scene, p, Some(1)).map_err(|e| e.to_string())?;
        Ok(Simulation::new(scene, Box::new(b)))
    })
}

fn small(paused: bool) -> SessionOptions {
    SessionOptions {
        width: 160,
        height: 90,
        paused,
        shadows: false,
        ..Default::default()
    }
}

/// The first frame after `seen` that satisfies `pred`, within 30 s.
fn wait(s: &Session, seen: u64, pred: impl Fn(&Status) -> bool) -> Arc<Frame> {
    let slot = s.frames();
    let start = Instant::now();
    let mut seen = seen;
    while start.elapsed() < Duration::from_secs(30) {
        if let Ok(Some(f)) = slot.wait_newer(seen, Duration::from_millis(100)) {
            if pred(&f.status) {
                return f;
            }
            seen = f.status.seq;
        }
    }
    panic!(
        "no such frame within 30 s; the last: {:?}",
        slot.latest().map(|f| f.status.clone())
    );
}

fn latest(s: &Session) -> Status {
    s.frames().latest().expect("a frame").status.clone()
}

#[test]
fn pause_step_resume_and_reset_do_what_they_say() {
    let s = Session::start(factory(SCENE), small(true), None).expect("session");
    assert_eq!(s.info.materials, ["sand", "water"]);
    let first = latest(&s);
    assert_eq!((first.seq, first.step, first.time), (1, 0, 0.0));
    assert!(first.paused && first.particles > 1000);
    assert_eq!((first.width, first.height), (160, 90));
    let com0 = first
        .center_of_mass
        .expect("the CPU path reads the particles");
    // One step.
    s.send(Command::Step).unwrap();
    let f = wait(&s, first.seq, |st| st.step == 1);
    assert!(f.status.paused && (f.status.time - 1e-3).abs() < 1e-9);
    // Paused: the picture may be redrawn, the time stays.
    s.send(Command::Orbit { dx: 30.0, dy: 0.0 }).unwrap();
    let g = wait(&s, f.status.seq, |_| true);
    assert_eq!(g.status.step, 1);
    assert_ne!(g.image.rgb, f.image.rgb, "the camera turned");
    // Running: frames follow with time going on, a frame (20 steps) at a time.
    s.send(Command::Resume).unwrap();
    let r = wait(&s, g.status.seq, |st| st.frame >= 3);
    assert!(!r.status.paused && r.status.step >= 60);
    let com = r.status.center_of_mass.unwrap();
    assert!(com[1] < com0[1], "the sand settles: {com0:?} -> {com:?}");
    s.send(Command::Pause).unwrap();
    let p = wait(&s, r.status.seq, |st| st.paused);
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(latest(&s).step, p.status.step, "paused time stops");
    // Reset: back to t = 0, the state of the start.
    s.send(Command::Reset).unwrap();
    let z = wait(&s, p.status.seq, |st| st.step == 0);
    assert_eq!(z.status.time, 0.0);
    assert_eq!(z.status.center_of_mass, Some(com0));
    let sum = s.finish().unwrap();
    assert_eq!(sum.steps, 0);
    assert!(sum.displayed >= 5);
}

#[test]
fn pace_colour_gravity_and_throws_change_the_session() {
    let s = Session::start(factory(SCENE), small(true), None).expect("session");
    let seq = latest(&s).seq;
    let com0 = latest(&s).center_of_mass.unwrap();
    s.send(Command::Slower).unwrap();
    s.send(Command::ColorBy(rtmpm_scene::ColorBy::Speed))
        .unwrap();
    s.send(Command::Gravity(Vec3::new(0.0, 0.0, -4.0))).unwrap();
    let f = wait(&s, seq, |st| st.gravity == [0.0, 0.0, -4.0]);
    // The first frame has not been stepped: the ladder starts from one step a frame.
    assert_eq!(f.status.pace, "1 step");
    assert_eq!(f.status.color_by, "speed");
    // Gravity along -z: in 0.1 s the sand falls 0.5 4 0.1^2 = 0.02 m along -z.
    s.send(Command::SetPace(Pace::Frames(1))).unwrap();
    s.send(Command::Resume).unwrap();
    let r = wait(&s, f.status.seq, |st| st.frame >= 5);
    s.send(Command::Pause).unwrap();
    let v = r.status.center_of_mass.unwrap();
    let dz = com0[2] - v[2];
    assert!(dz > 0.01 && dz < 0.03, "{com0:?} -> {v:?}");
    let p = wait(&s, r.status.seq, |st| st.paused);
    let n = p.status.particles;
    s.send(Command::Throw(Throw {
        x: 80.0,
        y: 45.0,
        material: Some(1),
        radius: Some(0.08),
        speed: Some(2.0),
    }))
    .unwrap();
    let t = wait(&s, p.status.seq, |st| st.particles > n);
    assert!(
        t.status
            .message
            .as_deref()
            .is_some_and(|m| m.contains("water")),
        "{:?}",
        t.status.message
    );
    // A throw that cannot be made says why; nothing else changes.
    s.send(Command::Throw(Throw {
        x: 80.0,
        y: 45.0,
        material: Some(7),
        radius: None,
        speed: None,
    }))
    .unwrap();
    let e = wait(&s, t.status.seq, |st| {
        st.message
            .as_deref()
            .is_some_and(|m| m.contains("no material"))
    });
    assert_eq!(e.status.particles, t.status.particles);
}

/// The pixel of `p` in the first camera of a 160x90 session of [`SCENE`].
fn pixel(p: Vec3) -> (f32, f32) {
    let scene = Scene::from_toml(SCENE, "<test>").unwrap();
    let (lo, hi) = scene.interior();
    let cam = rtmpm_render::Camera::framing(lo, hi, 160.0 / 90.0, 40.0);
    let (x, y, _) = cam.project(160, 90, p);
    (x, y)
}

/// Grab a ball of 0.1 m where the ray through the block's front face, left of its middle,
/// meets the sand, drag it `dx` pixels to the right (into the block) or hold it still, and run 15 frames; returns the tool's centres at the grab and at the end,
/// and the sand's centre of mass at the end.
fn drag(dx: Option<f32>) -> (Vec3, Vec3, [f64; 3]) {
    let s = Session::start(factory(SCENE), small(true), None).expect("session");
    let f0 = latest(&s);
    s.send(Command::ToolShape(rtmpm_geometry::ToolShape::Sphere {
        radius: 0.1,
    }))
    .unwrap();
    let (x, y) = pixel(Vec3::new(0.38, 0.25, 0.7));
    s.send(Command::ToolStart { x, y }).unwrap();
    let g = wait(&s, f0.seq, |st| st.tool.is_some());
    let start = Vec3::from_array(g.status.tool.unwrap());
    if let Some(dx) = dx {
        s.send(Command::ToolMove { x: x + dx, y }).unwrap();
    }
    s.send(Command::Resume).unwrap();
    let m = wait(&s, g.status.seq, |st| st.frame >= 15);
    let end = Vec3::from_array(m.status.tool.unwrap());
    s.send(Command::ToolEnd).unwrap();
    wait(&s, m.status.seq, |st| st.tool.is_none());
    s.finish().unwrap();
    (start, end, m.status.center_of_mass.unwrap())
}

#[test]
fn the_tool_follows_the_drag_and_moves_the_material() {
    let (start, end, still) = drag(None);
    assert_eq!(start, end, "a tool held still stays");
    // Grabbed where the ray meets the sand: half in it.
    assert!(start.y < 0.4 && start.z > 0.6, "{start}");
    // Dragged to the right: screen-right is +x (and a little -z) for the default camera.
    let (start, end, dragged) = drag(Some(20.0));
    assert!(
        end.x > start.x + 0.1,
        "the tool went right: {start} -> {end}"
    );
    // The sand moves along the drag (measured: +0.018 m in x, -0.079 m in z, against the
    // tool held still).
    let d = (end - start).normalize().as_dvec3();
    let moved = glam::DVec3::from(dragged) - glam::DVec3::from(still);
    assert!(
        moved.dot(d) > 0.02 && moved.x > 0.005,
        "the drag pushed the sand along it: {dragged:?} vs {still:?} held still"
    );
}

/// Fixed steps far too long for the stiff jelly: it blows up in a few steps.
const BLOWS_UP: &str = "[domain]\nmin = [0,0,0]\nmax = [1,1,1]\ndx = 0.05\n\
    [time]\nduration = 1.0\nfps = 50\ndt = 2e-2\n\
    [[material]]\nname = \"jelly\"\ntype = \"fixed_corotated\"\ndensity = 10.0\n\
    youngs_modulus = 1e9\npoisson_ratio = 0.3\n\
    [[body]]\nmaterial = \"jelly\"\nshape = \"box\"\nmin = [0.3,0.3,0.3]\nmax = [0.7,0.6,0.7]\n\
    velocity = [0, -3, 0]\n";

#[test]
fn a_blow_up_is_shown_and_reset_recovers() {
    let s = Session::start(factory(BLOWS_UP), small(false), None).expect("session");
    let b = wait(&s, 0, |st| st.error.is_some());
    let msg = b.status.error.clone().unwrap();
    assert!(msg.contains("blew up"), "{msg}");
    // The message is in the picture: the message box's colour.
    let red = b
        .image
        .rgb
        .chunks(3)
        .filter(|p| p == &[110, 20, 24])
        .count();
    assert!(red > 500, "{red}");
    // Still alive: commands work, reset clears the error.
    s.send(Command::Pause).unwrap();
    s.send(Command::Reset).unwrap();
    let r = wait(&s, b.status.seq, |st| st.error.is_none() && st.step == 0);
    assert!(r.status.paused);
    s.finish().unwrap();
}

#[test]
fn a_factory_error_is_returned_by_start() {
    let f: SimFactory = Box::new(|| Err("no GPU here".to_string()));
    let e = Session::start(f, small(false), None).err().unwrap();
    assert_eq!(e, "no GPU here");
}

#[test]
fn a_session_with_a_frame_limit_records_every_frame_and_ends() {
    let dir = std::env::temp_dir().join(format!("rtmpm-view-session-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("run.gif");
    let rec = crate::record::Recorder::start(&path, 50.0, true).unwrap();
    let opts = SessionOptions {
        max_frames: Some(6),
        ..small(false)
    };
    let s = Session::start(factory(SCENE), opts, Some(rec)).expect("session");
    let start = Instant::now();
    while !s.ended() && start.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(20));
    }
    let sum = s.finish().unwrap();
    assert_eq!(sum.frames, 6);
    // The first picture (t = 0) and one per frame.
    assert_eq!(sum.displayed, 7);
    let line = sum.recording.unwrap().unwrap();
    assert!(line.contains("7 frames"), "{line}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A CPU backend that "draws on a device": a picture begun is a flat grey of the step count
/// then (collected later), and every call is logged.
struct Deferred {
    inner: CpuBackend,
    steps: u64,
    begun: Option<(u32, u32, u8)>,
    log: Arc<std::sync::Mutex<Vec<&'static str>>>,
}

impl rtmpm_sim::Backend for Deferred {
    fn name(&self) -> String {
        "deferred".into()
    }
    fn num_particles(&self) -> usize {
        self.inner.num_particles()
    }
    fn step(&mut self, dt: f32, t: f32) -> Result<(), rtmpm_sim::SimError> {
        self.log.lock().unwrap().push("step");
        self.steps += 1;
        self.inner.step(dt, t)
    }
    fn max_speed(&mut self) -> Result<f32, rtmpm_sim::SimError> {
        self.inner.max_speed()
    }
    fn check(&mut self) -> Result<Option<rtmpm_sim::BadParticle>, rtmpm_sim::SimError> {
        self.inner.check()
    }
    fn read_particles(
        &mut self,
        out: &mut rtmpm_physics::Particles,
    ) -> Result<(), rtmpm_sim::SimError> {
        self.inner.read_particles(out)
    }
    fn begin_view(&mut self, req: &rtmpm_render::ViewRequest) -> Result<bool, rtmpm_sim::SimError> {
        self.log.lock().unwrap().push("begin");
        self.begun = Some((req.width, req.height, self.steps as u8));
        Ok(true)
    }
    fn finish_view(&mut self, out: &mut rtmpm_render::Image) -> Result<(), rtmpm_sim::SimError> {
        self.log.lock().unwrap().push("finish");
        let (w, h, v) = self.begun.take().expect("a picture begun");
        *out = rtmpm_render::Image::new(w, h, [v; 3]);
        Ok(())
    }
}

fn deferred(log: Arc<std::sync::Mutex<Vec<&'static str>>>) -> SimFactory {
    Box::new(move || {
        let scene = Scene::from_toml(SCENE, "<test>").map_err(|e| e.to_string())?;
        let p = scene.sample_particles().map_err(|e| e.to_string())?;
        let inner = CpuBackend::new(&scene, p, Some(1)).map_err(|e| e.to_string())?;
        let b = Deferred {
            inner,
            steps: 0,
            begun: None,
            log: log.clone(),
        };
        Ok(Simulation::new(scene, Box::new(b)))
    })
}

/// Runs 6 frames; returns the calls and the pictures published (status, first pixel).
fn run_deferred(overlap: bool) -> (Vec<&'static str>, Vec<(Status, u8)>) {
    let log = Arc::new(std::sync::Mutex::new(Vec::new()));
    let opts = SessionOptions {
        max_frames: Some(6),
        hud: false,
        overlap,
        ..small(false)
    };
    let s = Session::start(deferred(log.clone()), opts, None).expect("session");
    let slot = s.frames();
    let mut shown = Vec::new();
    let mut seen = 0;
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(60) {
        match slot.wait_newer(seen, Duration::from_millis(100)) {
            Ok(Some(f)) => {
                seen = f.status.seq;
                shown.push((f.status.clone(), f.image.rgb[0]));
            }
            Ok(None) => {}
            Err(_) => break,
        }
    }
    let sum = s.finish().unwrap();
    assert_eq!(sum.frames, 6);
    assert_eq!(sum.displayed, 7, "the first picture and one a frame");
    assert_eq!(sum.timing.steps, 5 * 20, "timed after the first frame");
    let calls = log.lock().unwrap().clone();
    (calls, shown)
}

#[test]
fn a_picture_begun_is_collected_once_the_next_frames_steps_are_queued() {
    let (calls, shown) = run_deferred(true);
    // The first picture at once; then each frame's picture is begun after its 20 steps and
    // collected after the next frame's 20 steps were queued (the last at the end).
    let mut expect = vec!["begin", "finish"];
    for k in 0..6 {
        expect.extend(std::iter::repeat_n("step", 20));
        if k > 0 {
            expect.push("finish");
        }
        expect.push("begin");
    }
    expect.push("finish");
    assert_eq!(calls, expect);
    // Every picture shows the state it was begun at: its status's step count (the slot keeps
    // the latest only, so a reader may miss some).
    assert!(shown.len() >= 2, "{}", shown.len());
    for (st, px) in &shown {
        assert_eq!(*px as u64, st.step, "{st:?}");
        assert_eq!(st.step, 20 * st.frame);
    }
}

#[test]
fn without_overlap_each_picture_is_drawn_before_the_next_step() {
    let (calls, _) = run_deferred(false);
    assert!(calls.iter().all(|&c| c == "step"), "no picture begun");
    assert_eq!(calls.len(), 6 * 20);
}

#[test]
fn a_session_with_a_frame_limit_ends_when_its_first_picture_cannot_be_drawn() {
    // A camera the drawing refuses (its target so far that the distance overflows f32): the
    // first picture fails before the loop, and the session (a recording without a front-end:
    // nobody can send it a command) ends with the error instead of waiting idle for ever.
    let camera = rtmpm_render::Camera {
        position: Vec3::new(0.5, 0.5, 3.0),
        target: Vec3::splat(1e30),
        fov_deg: 40.0,
    };
    let opts = SessionOptions {
        max_frames: Some(3),
        camera: Some(camera),
        ..small(false)
    };
    let s = Session::start(factory(SCENE), opts, None).expect("session");
    let start = Instant::now();
    while !s.ended() && start.elapsed() < Duration::from_secs(30) {
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(
        s.ended(),
        "the session still waits 30 s after its picture failed"
    );
    let sum = s.finish().unwrap();
    let e = sum.error.expect("the drawing error");
    assert!(e.contains("cannot draw the view"), "{e}");
}

#[test]
fn a_session_with_a_frame_limit_past_the_scenes_end_runs_to_it() {
    // The scene lasts 2 frames; 4 asked for (as `rtmpm run --frames 4` runs them). A session
    // without a limit pauses at the scene's end; one with a limit must not: nothing would
    // resume it.
    const SHORT: &str = "[domain]\nmin = [0,0,0]\nmax = [1,1,1]\ndx = 0.05\n\
        [time]\nduration = 0.04\nfps = 50\ndt = 1e-3\n\
        [[material]]\nname = \"water\"\ntype = \"fluid\"\ndensity = 1000.0\nbulk_modulus = 1e4\n\
        [[body]]\nmaterial = \"water\"\nshape = \"box\"\nmin = [0.3,0.15,0.3]\nmax = [0.7,0.4,0.7]\n";
    let opts = SessionOptions {
        max_frames: Some(4),
        ..small(false)
    };
    let s = Session::start(factory(SHORT), opts, None).expect("session");
    let start = Instant::now();
    while !s.ended() && start.elapsed() < Duration::from_secs(30) {
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(s.ended(), "the session paused at the scene's end");
    let sum = s.finish().unwrap();
    assert_eq!(sum.frames, 4);
    assert!(sum.error.is_none(), "{:?}", sum.error);
}
