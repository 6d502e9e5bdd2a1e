//! The lockstep batch driver (`rtmpm_driver::batch::lockstep`: every world held by one backend,
//! one time step for all, as the GPU runs a batch) on a backend of CPU worlds side by side: at a
//! fixed step every world gives, bit for bit, its separate run; a world that blows up is frozen
//! at its last frame, the frame is run again from there, and the others end as if it had never
//! been there; the output folders hold each world's frames and `batch.csv`. A backend that
//! keeps its own rewind point (as the GPU does on the device) is read only when its particles
//! are needed, and rewinds to that point bit for bit as the host's copy does.

use rtmpm_sim::Particles;
mod common;

use common::bits;
use common::cpu::CpuBackend;
use rtmpm_driver::Simulation;
use rtmpm_driver::batch::lockstep::LockstepRun;
use rtmpm_driver::batch::{BatchOptions, WorldStatus};
use rtmpm_scene::{BatchScene, Scene};
use rtmpm_sim::{Backend, BadParticle, SimError, Worlds};

/// A small slump: a column of Herschel-Bulkley mud on a sticky floor, at a fixed step.
const SLUMP: &str = r#"name = "slump"
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
struct SideBySide {
    scenes: Vec<Scene>,
    worlds: Vec<CpuBackend>,
    /// Keep the rewind point itself ([`Worlds::save_point`], as the GPU batch does on the
    /// device), in `point`; otherwise the driver keeps it on the host (the trait's default).
    keeps_point: bool,
    point: Vec<Particles>,
    /// Calls of [`Worlds::read_worlds`] (the driver reading every world to the host).
    reads: usize,
    /// Steps taken (counted over rewinds), and `(w, k)`: every particle of world `w` set to
    /// 10^5 m/s before step `k` (it blows up in that step), once.
    steps: usize,
    poison: Option<(usize, usize)>,
    /// World `w` set to 10^5 m/s before every step (it fails again once frozen and parked).
    relapse: Option<usize>,
}

impl SideBySide {
    fn new(scenes: &[Scene]) -> SideBySide {
        let p: Vec<Particles> = scenes
            .iter()
            .map(|s| s.sample_particles().expect("sample"))
            .collect();
        SideBySide::from_particles(scenes, &p)
    }

    /// The worlds `scenes` with their particles `p` (a resumed batch's).
    fn from_particles(scenes: &[Scene], p: &[Particles]) -> SideBySide {
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
            reads: 0,
            steps: 0,
            poison: None,
            relapse: None,
        }
    }

    /// Every world's particles (not counted in `reads`).
    fn read_all(&mut self) -> Result<Vec<Particles>, SimError> {
        self.worlds
            .iter_mut()
            .map(|b| {
                let mut p = Particles::default();
                b.read_particles(&mut p).map(|()| p)
            })
            .collect()
    }

    /// First particle (over all worlds) of each world, and the total.
    fn offsets(&self) -> Vec<usize> {
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
        self.worlds.iter_mut().try_for_each(|b| b.step(dt, t))
    }

    fn max_speed(&mut self) -> Result<f32, SimError> {
        let mut m = 0.0f32;
        for b in &mut self.worlds {
            m = m.max(b.max_speed()?);
        }
        Ok(m)
    }

    fn check(&mut self) -> Result<Option<BadParticle>, SimError> {
        let o = self.offsets();
        for (w, b) in self.worlds.iter_mut().enumerate() {
            if let Some(mut bad) = b.check()? {
                bad.index += o[w];
                return Ok(Some(bad));
            }
        }
        Ok(None)
    }

    fn read_particles(&mut self, out: &mut Particles) -> Result<(), SimError> {
        *out = Particles::default();
        for p in self.read_all()? {
            out.extend(&p);
        }
        Ok(())
    }

    fn cheap_check(&self) -> bool {
        true
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

    fn save_point(&mut self) -> Result<bool, SimError> {
        if self.keeps_point {
            self.point = self.read_all()?;
        }
        Ok(self.keeps_point)
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
fn alone(scene: &Scene, frames: u64) -> Particles {
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

fn lockstep(text: &str, options: &BatchOptions) -> (BatchScene, LockstepRun<SideBySide>) {
    let b = BatchScene::from_toml(text, "wedge.toml").unwrap_or_else(|e| panic!("{e}"));
    let backend = Box::new(SideBySide::new(&b.worlds));
    let mut r = LockstepRun::new(&b, text, b.worlds[0].clone(), backend, options).expect("batch");
    r.execute(|_, _| {}).expect("run");
    (b, r)
}

fn frames(n: u64) -> BatchOptions {
    BatchOptions {
        frames: Some(n),
        ..BatchOptions::default()
    }
}

#[test]
fn at_a_fixed_step_every_world_is_its_separate_run_bit_for_bit() {
    let (b, r) = lockstep(SLUMP, &frames(3));
    assert_eq!((r.sim.frame, r.running()), (3, 3));
    let mut seen = Vec::new();
    for (w, world) in r.worlds.iter().enumerate() {
        let separate = alone(&b.worlds[w], 3);
        assert!(separate.len() > 300);
        assert_eq!(bits(world.particles()), bits(&separate), "world {w}");
        seen.push(bits(&separate));
    }
    assert_ne!(seen[0], seen[1], "the sweep matters");
}

#[test]
fn a_world_that_blows_up_is_frozen_and_the_others_end_as_without_it() {
    // World 1's body starts far too fast and blows up in frame 1; worlds 0 and 2 must end as
    // their separate runs, although frame 1 was stepped, rewound and stepped again.
    let text = SLUMP.replace(
        "\"material[0].yield_stress\" = [20, 150, 600]",
        "\"body[0].velocity\" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]",
    );
    let (b, r) = lockstep(&text, &frames(3));
    match &r.worlds[1].status {
        WorldStatus::Frozen { frame, reason } => {
            assert_eq!(*frame, 0);
            assert!(reason.contains("blew up"), "{reason}");
        }
        other => panic!("world 1 should be frozen: {other:?}"),
    }
    let initial = b.worlds[1].sample_particles().expect("sample");
    assert_eq!(r.worlds[1].particles().x, initial.x, "kept at frame 0");
    for w in [0, 2] {
        assert_eq!(r.worlds[w].status, WorldStatus::Running);
        assert_eq!(
            bits(r.worlds[w].particles()),
            bits(&alone(&b.worlds[w], 3)),
            "world {w} differs from its separate run"
        );
    }
    assert_eq!(r.sim.frame, 3);
}

#[test]
fn the_output_folder_holds_each_world_and_a_frozen_world_stops_at_its_frame() {
    let dir = std::env::temp_dir().join(format!("rtmpm-lockstep-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let text = SLUMP.replace(
        "\"material[0].yield_stress\" = [20, 150, 600]",
        "\"body[0].velocity\" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]",
    );
    let options = BatchOptions {
        frames: Some(2),
        out_dir: Some(dir.clone()),
        overwrite: false,
    };
    let (_, r) = lockstep(&text, &options);
    assert_eq!(r.running(), 2);
    let csv = std::fs::read_to_string(dir.join("batch.csv")).expect("batch.csv");
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], "world,folder,label,status,frames,steps");
    assert!(
        rows[1].starts_with("0,world_000,") && rows[1].contains(",done,2,"),
        "{csv}"
    );
    assert!(
        rows[2].contains("frozen: simulation blew up") && rows[2].ends_with(",0,0"),
        "{csv}"
    );
    assert!(rows[3].contains(",done,2,"), "{csv}");
    let files = |w: &str| {
        let mut f: Vec<String> = std::fs::read_dir(dir.join(w))
            .expect("world folder")
            .filter_map(|e| e.ok()?.file_name().into_string().ok())
            .filter(|n| n.starts_with("frame_") && n.ends_with(".ply"))
            .collect();
        f.sort();
        f
    };
    assert_eq!(files("world_000").len(), 3, "{:?}", files("world_000"));
    assert_eq!(files("world_001"), ["frame_00000.ply"]);
    assert_eq!(files("world_002").len(), 3);
    std::fs::remove_dir_all(&dir).expect("clean up");
}

/// A lockstep run of `text` without files, its state read at the start (as Python's batch).
fn unwritten(text: &str) -> (BatchScene, LockstepRun<SideBySide>) {
    unwritten_keeping(text, false)
}

/// [`unwritten`], on a backend that keeps its rewind point itself when `keeps_point`.
fn unwritten_keeping(text: &str, keeps_point: bool) -> (BatchScene, LockstepRun<SideBySide>) {
    let b = BatchScene::from_toml(text, "wedge.toml").unwrap_or_else(|e| panic!("{e}"));
    let mut backend = Box::new(SideBySide::new(&b.worlds));
    backend.keeps_point = keeps_point;
    let options = BatchOptions::default();
    let mut r = LockstepRun::new(&b, text, b.worlds[0].clone(), backend, &options).expect("batch");
    r.write_first_frame().expect("read");
    (b, r)
}

/// World `scene` run alone for `steps` steps.
fn alone_steps(scene: &Scene, steps: u64) -> Particles {
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

#[test]
fn steps_cross_frame_ends_and_each_world_is_its_separate_run() {
    let (b, mut r) = unwritten(SLUMP);
    // 70 steps of 1 ms: a frame (50 steps) and 20 more, in two calls.
    assert!(r.advance_steps(33).expect("steps").is_empty());
    assert!(r.advance_steps(37).expect("steps").is_empty());
    assert_eq!((r.sim.step, r.sim.frame), (70, 1));
    for (w, world) in r.worlds.iter().enumerate() {
        assert_eq!((world.steps(), world.frame()), (70, 1));
        // 20 steps of the f32 dt (1e-3 + 4.7e-11) past the frame's end at 0.05 s.
        assert!((world.time() - 0.07).abs() < 1e-8, "{}", world.time());
        assert_eq!(
            bits(world.particles()),
            bits(&alone_steps(&b.worlds[w], 70)),
            "world {w}"
        );
    }
}

#[test]
fn a_world_that_blows_up_within_steps_is_frozen_and_the_others_go_on() {
    let text = SLUMP.replace(
        "\"material[0].yield_stress\" = [20, 150, 600]",
        "\"body[0].velocity\" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]",
    );
    let (b, mut r) = unwritten(&text);
    assert_eq!(r.advance_steps(10).expect("steps"), [1]);
    let WorldStatus::Frozen { reason, .. } = &r.worlds[1].status else {
        panic!("world 1 should be frozen");
    };
    // The particle is named by its index in world 1 (world 0, before it, holds as many: an
    // index over all worlds would be at least that count).
    let n = r.worlds[1].particles().len();
    let named: usize = reason
        .split("particle ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("no particle in {reason}"));
    assert_eq!(r.worlds[0].particles().len(), n);
    assert!(named < n, "{reason}");
    assert_eq!(r.worlds[1].steps(), 0, "kept at its last good state");
    for w in [0, 2] {
        assert_eq!(r.worlds[w].steps(), 10);
        let separate = alone_steps(&b.worlds[w], 10);
        assert_eq!(bits(r.worlds[w].particles()), bits(&separate), "world {w}");
    }
}

#[test]
fn a_reset_world_starts_its_clock_again_and_the_others_are_untouched() {
    let (b, mut r) = unwritten(SLUMP);
    for _ in 0..2 {
        assert!(r.advance_frame().expect("frame").is_empty());
    }
    let start = b.worlds[1].sample_particles().expect("sample");
    r.reset_worlds(vec![(1, start.clone())]).expect("reset");
    assert_eq!(bits(r.worlds[1].particles()), bits(&start));
    assert_eq!((r.worlds[1].frame(), r.worlds[1].steps()), (0, 0));
    for _ in 0..2 {
        assert!(r.advance_frame().expect("frame").is_empty());
    }
    let w1 = &r.worlds[1];
    assert_eq!((w1.frame(), w1.steps()), (2, 100));
    assert!((w1.time() - 0.1).abs() < 1e-9, "{}", w1.time());
    // Static walls: the reset world, stepped at later times, is its separate run of 2 frames.
    assert_eq!(bits(w1.particles()), bits(&alone(&b.worlds[1], 2)));
    for w in [0, 2] {
        assert_eq!(r.worlds[w].frame(), 4);
        assert_eq!(
            bits(r.worlds[w].particles()),
            bits(&alone(&b.worlds[w], 4)),
            "world {w} was touched by world 1's reset"
        );
    }
    // Resetting every world puts the shared clock back to 0.
    let starts = (0..3)
        .map(|w| (w, b.worlds[w].sample_particles().expect("sample")))
        .collect();
    r.reset_worlds(starts).expect("reset all");
    assert_eq!((r.sim.time, r.sim.step, r.sim.frame), (0.0, 0, 0));
    assert!(r.advance_frame().expect("frame").is_empty());
    for w in 0..3 {
        assert_eq!(bits(r.worlds[w].particles()), bits(&alone(&b.worlds[w], 1)));
    }
}

#[test]
fn resets_that_cannot_work_are_refused_before_any_world_changes() {
    // A collider moving with the shared clock: a partial reset is refused, naming it.
    let text = SLUMP.replace(
        "[batch]",
        "[[collider]]\nshape = \"box\"\nmin = [0.0, 0.0, 0.0]\nmax = [0.1, 0.5, 0.5]\n\
         velocity = [0.1, 0.0, 0.0]\n[batch]",
    );
    let (b, mut r) = unwritten(&text);
    assert!(r.advance_frame().expect("frame").is_empty());
    let before = bits(r.worlds[1].particles());
    let start = |w: usize| b.worlds[w].sample_particles().expect("sample");
    let e = r.reset_worlds(vec![(1, start(1))]).unwrap_err().to_string();
    assert!(
        e.contains("collider 0 moves") && e.contains("reset every world"),
        "{e}"
    );
    assert_eq!(bits(r.worlds[1].particles()), before);
    assert_eq!(r.worlds[1].frame(), 1);
    let e = r.reset_worlds(vec![(5, start(0))]).unwrap_err().to_string();
    assert!(e.contains("no world 5: the batch has 3"), "{e}");
    let mut short = start(0);
    short.x.truncate(10);
    let e = r.reset_worlds(vec![(0, short)]).unwrap_err().to_string();
    assert!(e.contains("world 0 has") && e.contains("10 given"), "{e}");
    // Every world at once: the clock goes back to 0, so the collider is where it started.
    r.reset_worlds((0..3).map(|w| (w, start(w))).collect())
        .expect("reset all");
    assert_eq!(r.sim.step, 0);
}

#[test]
fn a_backend_keeping_its_rewind_point_is_read_only_when_its_particles_are_needed() {
    let (b, mut r) = unwritten_keeping(SLUMP, true);
    assert_eq!(r.sim.backend.reads, 1, "the state at the start");
    // 70 calls of one step (a frame end crossed): nothing read back.
    for _ in 0..70 {
        assert!(r.advance_steps(1).expect("step").is_empty());
    }
    assert_eq!(r.sim.backend.reads, 1, "no call read the worlds");
    for world in &r.worlds {
        assert_eq!((world.steps(), world.frame()), (70, 1));
    }
    r.sync().expect("sync");
    assert_eq!(r.sim.backend.reads, 2);
    r.sync().expect("sync again");
    assert_eq!(r.sim.backend.reads, 2, "a second sync reads nothing");
    for (w, world) in r.worlds.iter().enumerate() {
        assert_eq!(
            bits(world.particles()),
            bits(&alone_steps(&b.worlds[w], 70)),
            "world {w}"
        );
    }
    // A checkpoint needs the particles: it reads them, once.
    assert!(r.advance_steps(3).expect("steps").is_empty());
    let dir = std::env::temp_dir().join(format!("rtmpm-lockstep-lazy-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    r.checkpoint(&dir, SLUMP, "slump.toml").expect("checkpoint");
    std::fs::remove_dir_all(&dir).expect("clean up");
    assert_eq!(r.sim.backend.reads, 3);
    assert_eq!(
        bits(r.worlds[0].particles()),
        bits(&alone_steps(&b.worlds[0], 73))
    );
}

/// One run of blow-ups and resets in calls of a few steps: world 2 made to blow up within the
/// second call (its particles sped up to 10^5 m/s before its 10th step, behind the driver's
/// back), a call, world 1 reset to a body at 10^5 m/s (it blows up in the next call, world 2
/// frozen before it), then world 2 reset to its start; the batch at the end, synced, and every
/// world as the backend held it after world 1's blow-up (the frozen ones parked and stepped).
fn resets_and_blow_ups(keeps_point: bool) -> (BatchScene, LockstepRun<SideBySide>, Vec<Particles>) {
    let (b, mut r) = unwritten_keeping(SLUMP, keeps_point);
    r.sim.backend.poison = Some((2, 9));
    assert!(r.advance_steps(7).expect("steps").is_empty());
    assert_eq!(r.advance_steps(5).expect("steps"), [2]);
    // Frozen at its last good state, the start of the call: its separate run of 7 steps.
    assert_eq!(
        bits(r.worlds[2].particles()),
        bits(&alone_steps(&b.worlds[2], 7)),
        "world 2 keeps its state of the call's start"
    );
    assert!(r.advance_steps(3).expect("steps").is_empty());
    let mut fast = b.worlds[1].sample_particles().expect("sample");
    fast.v
        .iter_mut()
        .for_each(|v| *v = glam::Vec3::new(1e5, 0.0, 0.0));
    r.reset_worlds(vec![(1, fast)]).expect("reset");
    assert_eq!(r.advance_steps(4).expect("steps"), [1]);
    let held = r.sim.backend.read_all().expect("read");
    let start = b.worlds[2].sample_particles().expect("sample");
    r.reset_worlds(vec![(2, start)]).expect("reset");
    assert!(r.advance_steps(6).expect("steps").is_empty());
    r.sync().expect("sync");
    (b, r, held)
}

#[test]
fn a_rewind_to_the_backends_own_point_equals_the_host_rewind_bit_for_bit() {
    let (b, host, host_held) = resets_and_blow_ups(false);
    let (_, kept, kept_held) = resets_and_blow_ups(true);
    // The backend held the same worlds after the second rewind, the frozen world 2 (parked
    // again from its last good state, as the host's rewind parks it) among them.
    for w in 0..3 {
        assert_eq!(
            bits(&kept_held[w]),
            bits(&host_held[w]),
            "world {w} as held"
        );
    }
    for w in 0..3 {
        let (a, k) = (&host.worlds[w], &kept.worlds[w]);
        assert_eq!(k.status, a.status, "world {w}");
        assert_eq!(bits(k.particles()), bits(a.particles()), "world {w}");
        assert_eq!((k.steps(), k.frame()), (a.steps(), a.frame()), "world {w}");
        assert_eq!(k.time().to_bits(), a.time().to_bits(), "world {w}");
    }
    assert!(matches!(kept.worlds[1].status, WorldStatus::Frozen { .. }));
    assert_eq!(kept.worlds[2].steps(), 6);
    assert_eq!(kept.worlds[1].steps(), 0, "frozen at its reset");
    // World 0 went through both rewinds: bit for bit its separate run of 25 steps (in f32
    // builds: a rewind puts the worlds back through the particles' f32 interface, so an f64
    // world rewound after its first steps goes on from its state rounded, in both modes alike);
    // world 2 is its separate run of 6 steps from its reset.
    if cfg!(not(feature = "f64")) {
        assert_eq!(
            bits(kept.worlds[0].particles()),
            bits(&alone_steps(&b.worlds[0], 25))
        );
    }
    assert_eq!(
        bits(kept.worlds[2].particles()),
        bits(&alone_steps(&b.worlds[2], 6))
    );
    // A frozen world keeps its last good state: world 1's fast start.
    let fast = kept.worlds[1].particles();
    assert!(
        fast.v.iter().all(|v| v.x == 1e5),
        "world 1 keeps its reset state"
    );
    // The host's copy read the worlds after every call; the backend's point only when needed
    // (the start, the first rewind, the second, the end's sync).
    assert!(
        kept.sim.backend.reads < host.sim.backend.reads,
        "{} reads against {}",
        kept.sim.backend.reads,
        host.sim.backend.reads
    );
    assert_eq!(kept.sim.backend.reads, 4);
}

/// A world that fails again once frozen and parked (here sped up to 10^5 m/s before every step,
/// behind the driver's back) ends the call with an error naming it, after one rewind, whether
/// the rewind point is the host's copy or the backend's own: the driver never rewinds twice for
/// one world (stepping the same blow-up again and again).
#[test]
fn a_frozen_world_that_fails_again_ends_the_call_with_an_error_not_a_loop() {
    for keeps_point in [false, true] {
        let (_, mut r) = unwritten_keeping(SLUMP, keeps_point);
        r.sim.backend.relapse = Some(1);
        let e = r
            .advance_steps(5)
            .expect_err("a parked world that fails again ends the call");
        let e = format!("{e:#}");
        assert!(
            e.contains("world 1 (its particle") && e.contains("failed again"),
            "keeps_point {keeps_point}: {e}"
        );
        assert!(e.contains("blew up"), "the failure itself is said: {e}");
        // The failed step, then the step again from the rewind point (world 1 frozen), which
        // fails in world 1 once more: two steps, one rewind.
        assert_eq!(r.sim.backend.steps, 2, "keeps_point {keeps_point}");
        assert!(matches!(
            r.worlds[1].status,
            WorldStatus::Frozen { frame: 0, .. }
        ));
        assert_eq!(r.running(), 2);
    }
}

/// Every file under `dir` (relative path, bytes), the run locks aside.
fn files_under(dir: &std::path::Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    let mut out = std::collections::BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("read folder").flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if !p.ends_with(".rtmpm-run") && !p.to_string_lossy().contains(".lock") {
                let rel = p.strip_prefix(dir).expect("under").display().to_string();
                out.insert(rel, std::fs::read(&p).expect("read file"));
            }
        }
    }
    out
}

#[test]
#[cfg_attr(
    feature = "f64",
    ignore = "a checkpoint holds the particles' f32 interface state: an f64 run resumes from it \
              rounded, not bit for bit"
)]
fn a_resumed_lockstep_batch_equals_the_uninterrupted_one_bit_for_bit() {
    // World 1 blows up in frame 1 and stays frozen through the checkpoint and the resume.
    let text = SLUMP.replace(
        "\"material[0].yield_stress\" = [20, 150, 600]",
        "\"body[0].velocity\" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]",
    );
    let b = BatchScene::from_toml(&text, "wedge.toml").unwrap_or_else(|e| panic!("{e}"));
    let top = std::env::temp_dir().join(format!("rtmpm-lockstep-ckpt-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&top);
    let options = |dir: &str, frames: u64| BatchOptions {
        frames: Some(frames),
        out_dir: Some(top.join(dir)),
        overwrite: false,
    };
    let every = Some((2, text.as_str(), "wedge.toml"));
    let fresh = |dir: &str, frames: u64| {
        let backend = Box::new(SideBySide::new(&b.worlds));
        let mut r = LockstepRun::new(
            &b,
            &text,
            b.worlds[0].clone(),
            backend,
            &options(dir, frames),
        )
        .expect("batch");
        r.execute_checkpointed(every, |_, _| {}).expect("run");
        r
    };
    let whole = fresh("whole", 4);
    assert_eq!((whole.sim.frame, whole.running()), (4, 2));
    drop(fresh("cut", 2));
    let ckpt = top.join("cut").join("checkpoint_00002");
    assert!(ckpt.join("batch.toml").is_file() && ckpt.join("world_002.ckpt").is_file());
    let resume = |dir: &std::path::Path, options: &BatchOptions| {
        let side = |p: &[Particles]| {
            Ok((
                b.worlds[0].clone(),
                Box::new(SideBySide::from_particles(&b.worlds, p)),
            ))
        };
        LockstepRun::resume(&b, &text, dir, side, options)
    };
    let mut again = resume(&ckpt, &options("cut", 4)).expect("resume");
    assert_eq!((again.sim.frame, again.sim.step), (2, 100));
    assert!(matches!(
        again.worlds[1].status,
        WorldStatus::Frozen { frame: 0, .. }
    ));
    again
        .execute_checkpointed(every, |_, _| {})
        .expect("run on");
    for w in 0..3 {
        assert_eq!(
            bits(again.worlds[w].particles()),
            bits(whole.worlds[w].particles()),
            "world {w}"
        );
    }
    let (a, c) = (
        files_under(&top.join("whole")),
        files_under(&top.join("cut")),
    );
    assert_eq!(a.keys().collect::<Vec<_>>(), c.keys().collect::<Vec<_>>());
    assert!(
        a.contains_key("checkpoint_00004/world_000.ckpt"),
        "{:?}",
        a.keys()
    );
    for (k, v) in &a {
        assert!(
            c[k] == *v,
            "{k} differs between the resumed and the uninterrupted run"
        );
    }
    // A checkpoint whose running worlds are at different times cannot share one clock.
    let mut split = resume(&ckpt, &BatchOptions::default()).expect("resume without files");
    split.write_first_frame().expect("read");
    let start = b.worlds[0].sample_particles().expect("sample");
    split.reset_worlds(vec![(0, start)]).expect("reset world 0");
    let odd = top.join("odd");
    split
        .checkpoint(&odd, &text, "wedge.toml")
        .expect("checkpoint");
    let e = resume(&odd, &BatchOptions::default())
        .err()
        .expect("refused")
        .to_string();
    assert!(
        e.contains("different times") && e.contains("--backend cpu"),
        "{e}"
    );
    std::fs::remove_dir_all(&top).expect("clean up");
}

/// The slump's worlds with a kinematic tool (a 6 cm box above the mud).
#[cfg(feature = "rigid")]
fn with_tool(text: &str) -> String {
    text.replace(
        "[batch]",
        "[[rigid_body]]\nname = \"tool\"\nshape = \"box\"\nmin = [0.22, 0.27, 0.22]\n\
         max = [0.28, 0.33, 0.22]\ntype = \"kinematic\"\ndensity = 1000.0\n\
         condition = \"sticky\"\n[batch]",
    )
    .replace("max = [0.28, 0.33, 0.22]", "max = [0.28, 0.33, 0.28]")
}

/// World `scene` run alone for `steps` steps with its tool set to `velocity` first; its
/// particles, tool pose and load.
#[cfg(feature = "rigid")]
fn alone_with_tool(
    scene: &Scene,
    velocity: glam::Vec3,
    steps: u64,
) -> (Particles, rtmpm_rigid::BodyPose, rtmpm_rigid::BodyLoad) {
    let p = scene.sample_particles().expect("sample");
    let b = CpuBackend::new(scene, p, None).expect("cpu");
    let mut sim = Simulation::new(scene.clone(), Box::new(b));
    let mut poses = sim.backend.rigid_poses();
    poses[0].velocity = velocity;
    sim.backend.set_rigid_poses(&poses).expect("pose");
    while sim.step < steps {
        sim.advance(steps - sim.step).expect("stable");
    }
    let mut p = Particles::default();
    sim.backend.read_particles(&mut p).expect("read");
    let pose = sim.backend.rigid_poses()[0];
    let load = sim.backend.rigid_loads().expect("loads")[0];
    (p, pose, load)
}

/// Each world's tool posed before a call is kept with the world through a rewind: world 1 blows
/// up in the call, every world is put back and the steps taken again, and worlds 0 and 2 still
/// end (particles, tool pose, load on the tool) bit for bit as their separate runs with their
/// tools set the same way; the frozen world's tool is parked at rest; a reset world's tool goes
/// back to its pose at time 0 while the others' stay.
#[cfg(feature = "rigid")]
#[test]
fn each_worlds_tool_goes_with_its_particles_through_a_rewind_and_a_reset() {
    let text = with_tool(&SLUMP.replace(
        "\"material[0].yield_stress\" = [20, 150, 600]",
        "\"body[0].velocity\" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]",
    ));
    let (b, mut r) = unwritten(&text);
    let start: Vec<_> = (0..3).map(|w| r.worlds[w].bodies()[0]).collect();
    let speeds = [-0.5f32, -1.0, -1.5];
    for (w, s) in speeds.iter().enumerate() {
        let mut p = r.sim.backend.world_rigid_poses(w);
        p[0].velocity = glam::Vec3::new(0.0, *s, 0.0);
        r.sim.backend.set_world_rigid_poses(w, &p).expect("pose");
    }
    assert_eq!(r.advance_steps(60).expect("steps"), [1]);
    let parked = r.sim.backend.world_rigid_poses(1)[0];
    assert_eq!(
        parked.velocity,
        glam::Vec3::ZERO,
        "the frozen world's tool is parked"
    );
    assert_eq!(parked.position, start[1].position);
    for w in [0, 2] {
        let v = glam::Vec3::new(0.0, speeds[w], 0.0);
        let (p, pose, load) = alone_with_tool(&b.worlds[w], v, 60);
        assert_eq!(bits(r.worlds[w].particles()), bits(&p), "world {w}");
        assert_eq!(
            r.sim.backend.world_rigid_poses(w)[0],
            pose,
            "world {w}'s tool"
        );
        assert_eq!(r.worlds[w].bodies()[0], pose, "world {w}'s kept tool");
        let mine = r
            .sim
            .backend
            .world_rigid_loads(w)
            .expect("loads")
            .expect("some")[0];
        assert_eq!(mine, load, "world {w}'s load");
        assert!(load.force[1] > 0.0, "the mud pushes the tool up: {load:?}");
    }
    // A frozen world's tool stays parked although a script poses every world's.
    for w in 0..3 {
        let mut p = r.sim.backend.world_rigid_poses(w);
        p[0].velocity = glam::Vec3::new(0.0, -1.0, 0.0);
        r.sim.backend.set_world_rigid_poses(w, &p).expect("pose");
    }
    assert!(r.advance_steps(5).expect("steps").is_empty());
    assert_eq!(
        r.sim.backend.world_rigid_poses(1)[0].position,
        start[1].position
    );
    // A checkpoint holds each world's tool: the resumed batch goes on bit for bit.
    let dir = std::env::temp_dir().join(format!("rtmpm-lockstep-tools-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    r.checkpoint(&dir, &text, "tools.toml").expect("checkpoint");
    let side = |p: &[Particles]| {
        Ok((
            b.worlds[0].clone(),
            Box::new(SideBySide::from_particles(&b.worlds, p)),
        ))
    };
    let mut again =
        LockstepRun::resume(&b, &text, &dir, side, &BatchOptions::default()).expect("resume");
    std::fs::remove_dir_all(&dir).expect("clean up");
    for w in 0..3 {
        let want = r.sim.backend.world_rigid_poses(w);
        assert_eq!(again.sim.backend.world_rigid_poses(w), want, "world {w}");
    }
    assert!(r.advance_steps(10).expect("steps").is_empty());
    assert!(again.advance_steps(10).expect("steps").is_empty());
    for w in [0, 2] {
        // As for a_resumed_lockstep_batch_equals_the_uninterrupted_one_bit_for_bit: a checkpoint
        // holds the particles' f32 interface state, so an f64 run resumes from it rounded; its
        // particles are compared bit for bit in f32 builds only (the tools' poses in both).
        if cfg!(not(feature = "f64")) {
            assert_eq!(
                bits(again.worlds[w].particles()),
                bits(r.worlds[w].particles())
            );
        }
        let want = r.sim.backend.world_rigid_poses(w);
        assert_eq!(again.sim.backend.world_rigid_poses(w), want, "world {w}");
    }
    // A reset puts world 2's tool back to its start; world 0's stays where it went.
    let moved = r.sim.backend.world_rigid_poses(0)[0];
    let p2 = b.worlds[2].sample_particles().expect("sample");
    r.reset_worlds(vec![(2, p2)]).expect("reset");
    assert_eq!(r.sim.backend.world_rigid_poses(2)[0], start[2]);
    assert_eq!(r.worlds[2].bodies()[0], start[2]);
    assert_eq!(r.sim.backend.world_rigid_poses(0)[0], moved);
}
