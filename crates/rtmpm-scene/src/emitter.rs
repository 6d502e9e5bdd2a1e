//! Emitters: particles that appear while the simulation runs (`[[emitter]]`).
//!
//! An emitter fills its shape at a constant rate between `start` and `stop`. The number of
//! particles it has emitted by time `t` is `N(t) = min(total, floor(rate (t - start)))` (zero
//! before `start`), so the emitted mass is `rate t m` within one particle mass `m` whatever the
//! time steps. Particle `j` of an emitter is placed by jittered sampling: the lattice of spacing
//! `dx / round(cbrt(particles_per_cell))` (the spacing of a body's sampling) is clipped to the
//! shape, its sub-cells are visited in a fixed shuffled order, one particle per sub-cell, each
//! moved uniformly within its sub-cell; every round of the sub-cells starts the order again
//! with new jitter. Positions depend only on the scene seed, the emitter's index and `j`: the
//! same on every backend and for any step sizes. `rtmpm_driver::Simulation`
//! emits before each step the particles due by its end and hands them to the backend
//! (`rtmpm_sim::Backend::add_particles`).

use rtmpm_geometry::Shape;
use rtmpm_physics::Particles;
use rtmpm_physics::material::Material;
use rtmpm_physics::math::Vec3;

/// Most particles one emitter may emit in a run.
pub const MAX_PARTICLES_PER_EMITTER: u64 = 50_000_000;
/// Most lattice sub-cells one emitter may list ([`Emitter::lattice`], 12 bytes each).
pub const MAX_EMITTER_SUB_CELLS: u64 = 1 << 24;

/// A validated emitter.
#[derive(Clone, Debug)]
pub struct Emitter {
    pub name: String,
    /// Material index.
    pub material: u32,
    /// Box, sphere or cylinder (inside the domain minus the walls).
    pub shape: Shape,
    /// Velocity of the emitted particles (m/s).
    pub velocity: Vec3,
    /// Particles per second.
    pub rate: f64,
    /// Emission starts at this time (s).
    pub start: f64,
    /// And stops at this time (s).
    pub stop: f64,
    /// Lattice spacing (m): each particle has volume `spacing^3`.
    pub spacing: f32,
    /// Mass of one particle (kg): density times volume.
    pub particle_mass: f32,
    /// Centres of the lattice sub-cells inside the shape, in the shuffled visiting order.
    pub cells: Vec<Vec3>,
    /// Seed of the jitter (scene seed and emitter index).
    pub seed: u64,
}

/// SplitMix64: a well-mixed 64-bit hash of `x` (Steele, Lea & Flood, "Fast splittable
/// pseudorandom number generators", OOPSLA 2014).
fn splitmix64(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

/// A uniform number in [0, 1) from 24 bits of `h`.
fn unit(h: u64) -> f32 {
    (h >> 40) as f32 / (1u64 << 24) as f32
}

impl Emitter {
    /// Sub-cells of the lattice of spacing `spacing` over the bounding box of `shape` (what
    /// [`Emitter::lattice`] visits), as an f64 that cannot overflow.
    pub fn lattice_size(shape: &Shape, spacing: f32) -> f64 {
        let (lo, hi) = shape.bounds();
        let n = ((hi - lo) / spacing - 1e-4).ceil().max(Vec3::ONE);
        n.x as f64 * n.y as f64 * n.z as f64
    }

    /// The sub-cell centres of the lattice of spacing `spacing` inside `shape`, shuffled with
    /// `seed` (Fisher-Yates). The caller bounds [`Emitter::lattice_size`] first.
    pub fn lattice(shape: &Shape, spacing: f32, seed: u64) -> Vec<Vec3> {
        let (lo, hi) = shape.bounds();
        // Whole sub-cells (a size within 1e-4 sub-cell of a whole number is that number).
        let n = ((hi - lo) / spacing - 1e-4)
            .ceil()
            .max(Vec3::ONE)
            .as_uvec3();
        // Centred in the bounding box, so a box of whole sub-cells is tiled exactly.
        let origin = 0.5 * (lo + hi) - 0.5 * spacing * n.as_vec3();
        let mut cells = Vec::new();
        for i in 0..n.x {
            for j in 0..n.y {
                for k in 0..n.z {
                    let x = origin + spacing * (glam::UVec3::new(i, j, k).as_vec3() + 0.5);
                    if shape.contains(x) {
                        cells.push(x);
                    }
                }
            }
        }
        let mut h = seed;
        for i in (1..cells.len()).rev() {
            h = splitmix64(h);
            cells.swap(i, (h % (i as u64 + 1)) as usize);
        }
        cells
    }

    /// Particles emitted by time `t`.
    pub fn count_at(&self, t: f64) -> u64 {
        if t <= self.start {
            return 0;
        }
        let n = (self.rate * (t.min(self.stop) - self.start)).floor();
        (n as u64).min(self.total())
    }

    /// Particles emitted over the whole run.
    pub fn total(&self) -> u64 {
        (self.rate * (self.stop - self.start)).max(0.0).floor() as u64
    }

    /// Area (m^2) of the emitter's shape seen along its velocity: the cross-section its
    /// particles leave through (0 without a velocity).
    pub fn cross_section(&self) -> f64 {
        let Some(d) = self.velocity.as_dvec3().try_normalize() else {
            return 0.0;
        };
        match &self.shape {
            Shape::Box(c) => {
                let e = (c.max - c.min).as_dvec3();
                d.x.abs() * e.y * e.z + d.y.abs() * e.x * e.z + d.z.abs() * e.x * e.y
            }
            Shape::Sphere(s) => std::f64::consts::PI * (s.radius as f64).powi(2),
            Shape::Cylinder(c) => {
                let (r, h) = (c.radius as f64, 2.0 * c.half_height as f64);
                let cos = d.dot(c.axis.as_dvec3()).abs();
                std::f64::consts::PI * r * r * cos + 2.0 * r * h * (1.0 - cos * cos).max(0.0).sqrt()
            }
            // Not an emitter's shape.
            Shape::HalfSpace(_) | Shape::Mesh(_) | Shape::Particles(_) => 0.0,
        }
    }

    /// Particles per second that can leave the emitter at its velocity, one per sub-cell of
    /// its cross-section: `A |v| / spacing^3`.
    pub fn outflow(&self) -> f64 {
        self.cross_section() * self.velocity.length() as f64 / (self.spacing as f64).powi(3)
    }

    /// True when the emitter emits faster than its particles leave it (by more than a quarter),
    /// and more particles in all than its sub-cells hold: they pile up inside it, are
    /// compressed and burst out (a dense cluster).
    pub fn piles_up(&self) -> bool {
        self.total() > self.cells.len() as u64 && self.rate > 1.25 * self.outflow()
    }

    /// Position of particle `j`.
    pub fn position(&self, j: u64) -> Vec3 {
        let m = self.cells.len() as u64;
        let centre = self.cells[(j % m.max(1)) as usize];
        let h = splitmix64(self.seed ^ splitmix64(j));
        let (a, b, c) = (h, splitmix64(h), splitmix64(h ^ 0x5555));
        centre + self.spacing * (Vec3::new(unit(a), unit(b), unit(c)) - 0.5)
    }

    /// Append particles `from..to` of this emitter to `out` (material `m`: its initial
    /// plastic state).
    pub fn emit(&self, from: u64, to: u64, m: &Material, out: &mut Particles) {
        let vol = self.spacing.powi(3);
        let plastic = m.model.initial_plastic();
        for j in from..to {
            out.push(
                self.position(j),
                self.velocity,
                self.particle_mass,
                vol,
                self.material,
                plastic,
            );
        }
    }
}

/// The particles every emitter of a scene emits during `[t0, t1)`, given how many each has
/// emitted so far (`emitted`, updated).
pub fn emit_between(
    emitters: &[Emitter],
    materials: &[Material],
    emitted: &mut [u64],
    t1: f64,
) -> Particles {
    let mut out = Particles::default();
    for (e, done) in emitters.iter().zip(emitted.iter_mut()) {
        let target = e.count_at(t1);
        if target > *done {
            e.emit(*done, target, &materials[e.material as usize], &mut out);
            *done = target;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn emitter(rate: f64) -> Emitter {
        let shape = Shape::Box(rtmpm_geometry::shape::Cuboid {
            min: Vec3::new(0.4, 0.1, 0.4),
            max: Vec3::new(0.6, 0.2, 0.6),
        });
        let spacing = 0.025;
        Emitter {
            name: "e".into(),
            material: 0,
            cells: Emitter::lattice(&shape, spacing, 7),
            shape,
            velocity: Vec3::Y,
            rate,
            start: 0.5,
            stop: 1.5,
            spacing,
            particle_mass: 1000.0 * spacing.powi(3),
            seed: 7,
        }
    }

    #[test]
    fn counts_follow_the_rate_between_start_and_stop() {
        let e = emitter(1000.0);
        assert_eq!(e.count_at(0.0), 0);
        assert_eq!(e.count_at(0.5), 0);
        assert_eq!(e.count_at(1.0), 500);
        assert_eq!(e.count_at(1.5), 1000);
        assert_eq!(e.count_at(9.0), 1000);
        assert_eq!(e.total(), 1000);
        // Within one particle of rate (t - start) at any time.
        for k in 0..200 {
            let t = 0.5 + k as f64 * 0.0049;
            let n = e.count_at(t) as f64;
            assert!((n - 1000.0 * (t - 0.5)).abs() < 1.0, "{t}: {n}");
        }
    }

    #[test]
    fn a_round_of_particles_fills_every_sub_cell_once_inside_the_shape() {
        let e = emitter(1000.0);
        // 8 x 4 x 8 sub-cells of 0.025 m in the 0.2 x 0.1 x 0.2 m box.
        assert_eq!(e.cells.len(), 256);
        let mut seen = std::collections::HashSet::new();
        for j in 0..256u64 {
            let x = e.position(j);
            assert!(e.shape.contains(x), "{x}");
            let cell = ((x - Vec3::new(0.4, 0.1, 0.4)) / 0.025).floor().as_ivec3();
            assert!(seen.insert(cell), "sub-cell {cell} twice");
        }
        // The next round jitters differently.
        assert_ne!(e.position(0), e.position(256));
        assert_eq!(e.position(3), emitter(1000.0).position(3));
    }
}
