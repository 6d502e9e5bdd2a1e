//! The lockstep batch driver (`rtmpm_driver::batch::lockstep`: every world held by one backend,
//! one time step for all, as the GPU runs a batch) on a backend of CPU worlds side by side: at a
//! fixed step every world gives, bit for bit, its separate run; a world that blows up is frozen
//! at its last frame, the frame is run again from there, and the others end as if it had never
//! been there; the output folders hold each world's frames and `batch.csv`.

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
}

impl SideBySide {
    fn new(scenes: &[Scene]) -> SideBySide {
        let worlds = scenes
            .iter()
            .map(|s| CpuBackend::new(s, s.sample_particles().expect("sample"), None).expect("cpu"))
            .collect();
        SideBySide {
            scenes: scenes.to_vec(),
            worlds,
        }
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
        for p in self.read_worlds()? {
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
        self.worlds
            .iter_mut()
            .map(|b| {
                let mut p = Particles::default();
                b.read_particles(&mut p).map(|()| p)
            })
            .collect()
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
