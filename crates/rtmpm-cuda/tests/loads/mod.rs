//! The load on a kinematic tool pushed into sand, shared by the GPU tests of rigid-body loads
//! (`tests/rigid.rs`: one GPU against the CPU backend; `tests/multi_gpu_rigid.rs`: several
//! GPUs against one): the scene, a run that averages the tool's load over its last steps, and
//! the tolerance of `tests/batch_rigid.rs` on such a mean (the force within 5 % of its size,
//! the torque within 5 % of its size plus 1e-4 N m).
#![allow(dead_code)] // each test binary uses its part

use rtmpm_rigid::BodyLoad;
use rtmpm_scene::Scene;
use rtmpm_sim::Backend;

/// The step (s).
pub const DT: f32 = 2e-4;
/// Steps of a run: 0.16 s, the tool 4 cm down (3 cm into the sand) and 1.6 cm sideways.
pub const STEPS: usize = 800;
/// The last steps whose loads are averaged.
pub const WINDOW: usize = 200;

/// The sand bed of `examples/python/batch_push.py` (0.38 x 0.09 x 0.18 m of Drucker-Prager
/// sand, friction angle 30 degrees, dx = 2 cm, 4 particles a cell, sticky walls) and its tool:
/// a kinematic 6 cm box whose centre is at `x` along x and 1 cm above the bed, moving down at
/// 0.25 m/s and along +x at 0.1 m/s (so that the sand pushes it up and holds it back, with a
/// torque about z), slip condition.
pub fn sand_and_tool(x: f32) -> Scene {
    let text = format!(
        r#"name = "tool_in_sand"
[domain]
min = [0.0, 0.0, 0.0]
max = [0.5, 0.36, 0.3]
dx = 0.02
[time]
duration = 0.2
fps = 50
dt = {DT}
[walls]
thickness = 3
condition = "sticky"
[[material]]
name = "sand"
type = "drucker_prager"
density = 1600.0
youngs_modulus = 5e5
poisson_ratio = 0.3
friction_angle = 30.0
[[body]]
material = "sand"
shape = "box"
min = [0.06, 0.06, 0.06]
max = [0.44, 0.15, 0.24]
particles_per_cell = 4
[[rigid_body]]
name = "tool"
shape = "box"
type = "kinematic"
condition = "slip"
density = 1000.0
min = [{}, 0.16, 0.12]
max = [{}, 0.22, 0.18]
velocity = [0.1, -0.25, 0.0]
"#,
        x - 0.03,
        x + 0.03
    );
    Scene::from_toml(&text, "tool_in_sand.toml").unwrap_or_else(|e| panic!("{e}"))
}

/// A mean of loads.
#[derive(Clone, Copy, Debug, Default)]
pub struct Mean {
    force: [f64; 3],
    torque: [f64; 3],
    n: usize,
}

impl Mean {
    /// Count `l` in.
    pub fn add(&mut self, l: &BodyLoad) {
        for a in 0..3 {
            self.force[a] += l.force[a];
            self.torque[a] += l.torque[a];
        }
        self.n += 1;
    }

    /// The mean force (N).
    pub fn force(&self) -> [f64; 3] {
        self.force.map(|f| f / self.n.max(1) as f64)
    }

    /// The mean torque (N m).
    pub fn torque(&self) -> [f64; 3] {
        self.torque.map(|t| t / self.n.max(1) as f64)
    }
}

fn norm(a: [f64; 3]) -> f64 {
    a.iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn diff(a: [f64; 3], b: [f64; 3]) -> f64 {
    norm([a[0] - b[0], a[1] - b[1], a[2] - b[2]])
}

/// Body 0's load after a step of `b`, read as Python's `Simulation.rigid_bodies` reads it
/// (after `flush_rigid`: with `rigid_overlap` the bodies take a step's sums a step late).
pub fn load(b: &mut dyn Backend) -> BodyLoad {
    b.flush_rigid().expect("flush the bodies");
    let loads = b
        .rigid_loads()
        .unwrap_or_else(|| panic!("`{}` reports no loads", b.name()));
    assert_eq!(loads.len(), 1, "one body");
    loads[0]
}

/// Run `b` for [`STEPS`] steps of [`DT`] and return the tool's mean load over the last
/// [`WINDOW`]; before the first step its load is zero.
pub fn push(b: &mut dyn Backend) -> Mean {
    assert_eq!(load(b), BodyLoad::default(), "no load before a step");
    let mut mean = Mean::default();
    for s in 0..STEPS {
        b.step(DT, s as f32 * DT).expect("step");
        if s >= STEPS - WINDOW {
            mean.add(&load(b));
        }
    }
    assert!(b.check().expect("check").is_none(), "{}: blow-up", b.name());
    mean
}

/// `got` against `want` (printed) within the tolerance of `tests/batch_rigid.rs`: a failure
/// when outside.
pub fn differ(label: &str, got: &Mean, want: &Mean) -> Option<String> {
    let (fg, fw) = (got.force(), want.force());
    let (tg, tw) = (got.torque(), want.torque());
    println!(
        "{label}: mean force {fg:.4?} N (reference {fw:.4?}), torque {tg:.5?} N m (reference \
         {tw:.5?})"
    );
    if diff(fg, fw) > 0.05 * norm(fw) {
        return Some(format!("{label}: force {fg:?} vs the reference's {fw:?}"));
    }
    if diff(tg, tw) > 0.05 * norm(tw) + 1e-4 {
        return Some(format!("{label}: torque {tg:?} vs the reference's {tw:?}"));
    }
    None
}

/// The reference load is the sand's on the tool: it pushes the tool up and holds back its
/// drag along +x.
pub fn assert_the_sand_pushes_back(want: &Mean) {
    let f = want.force();
    assert!(
        f[1] > 0.0 && f[0] < 0.0,
        "the sand should push the tool up and back: {f:?}"
    );
}
