//! Filling bodies with particles.
//!
//! * `regular`: a lattice of `n = round(cbrt(ppc))` particles per axis and cell, at the centres
//!   of the sub-cells of the *global* grid (so neighbouring bodies tile seamlessly); each
//!   particle has volume `(dx/n)^3`.
//! * `jittered`: the same lattice, each particle moved uniformly within its sub-cell
//!   (Pcg64 seeded from the scene seed and the body index: deterministic).
//! * `random`: uniform positions in the body's bounding box, rejected outside the shape, until
//!   `count` (or `round(ppc * volume / dx^3)`) particles are placed; volume `volume / count`.
//!
//! * `particles` bodies (`shape = "particles"`) take the points of a file as they are (see
//!   [`rtmpm_io::points`]): volume per particle from the file's `volume`, else its `mass` over
//!   the material's density, else `dx^3 / particles_per_cell`; velocities from the file unless
//!   the body gives `velocity` or `angular_velocity`.
//!
//! Lattice and jittered particles are kept when their (jittered) position is inside the shape
//! (mesh: signed distance < 0). Velocities are `v0 + w x (x - c)` with `c` the centroid of the
//! body's particles.

pub use crate::body::{BodyPositions, SampledBody};
use crate::error::SceneError;
use crate::fill;
use crate::scene::Scene;
pub use crate::settings::Sampling;
use crate::walk::{self, Counter, Mode, Walked};
pub use crate::walk::{Lattice, RandomTries};
use rand::SeedableRng;
use rand_pcg::Pcg64;
use rtmpm_geometry::{PointSet, Shape};
use rtmpm_io::contents::check_particle_values;
use rtmpm_physics::Particles;
use rtmpm_physics::material::Material;
use rtmpm_physics::math::{Mat3, Vec3};

/// Particles per axis and cell for a particles-per-cell count: `round(cbrt(ppc))`, at least 1.
pub fn per_axis(ppc: u32) -> u32 {
    ((ppc as f64).cbrt().round() as u32).max(1)
}

fn body_error(i: usize, message: String, hint: &str) -> SceneError {
    SceneError {
        origin: String::new(),
        line: None,
        column: None,
        field: Some(format!("body[{i}]")),
        message,
        hint: Some(hint.to_string()),
    }
}

/// Most random positions tried for one body (random sampling of a thin shape would otherwise
/// run for hours before failing); the walk is parallel, so this is minutes on many cores.
pub const MAX_RANDOM_TRIES: u64 = 100_000_000_000;

/// Most lattice points the walk of one body visits (its bounding box on the sub-cell lattice):
/// a bound on the time of the walk, not on the particles (those are bounded by the memory budget,
/// [`crate::budget::Budget`]).
pub const MAX_LATTICE_POINTS: u64 = 1 << 40;

/// Estimated particle count of body `index`, without sampling: `volume / h^3` for the lattice
/// samplings (exact for boxes aligned with the lattice), the count for random sampling, the
/// number of points for a particles body (exact).
pub fn estimate_body(scene: &Scene, index: usize) -> u64 {
    let Some(body) = scene.bodies.get(index) else {
        return 0;
    };
    if let Shape::Particles(p) = &body.shape {
        return p.points.positions.len() as u64;
    }
    let volume = body.shape.volume().max(0.0) as f64;
    let est = match body.sampling {
        Sampling::Regular | Sampling::Jittered => {
            let h = scene.dx as f64 / per_axis(body.particles_per_cell) as f64;
            volume / (h * h * h)
        }
        Sampling::Random => match body.count {
            Some(c) => c as f64,
            None => body.particles_per_cell as f64 * volume / (scene.dx as f64).powi(3),
        },
    };
    if est.is_finite() {
        est.round().max(0.0) as u64
    } else {
        u64::MAX
    }
}

/// The seed of body `index`'s random stream (`Pcg64::seed_from_u64`): the scene's seed and the
/// body's index.
pub(crate) fn body_seed(scene: &Scene, index: usize) -> u64 {
    scene.seed ^ (index as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

/// The sub-cell lattice that regular and jittered sampling walk for body `index`: its bounding
/// box on the lattice of `n = round(cbrt(ppc))` points per axis and cell of the global grid.
pub(crate) fn body_lattice(scene: &Scene, index: usize) -> Result<Lattice, SceneError> {
    let body = scene
        .bodies
        .get(index)
        .ok_or_else(|| body_error(index, "no such body".into(), "use an existing body index"))?;
    let (lo, hi) = body.shape.bounds();
    let n = per_axis(body.particles_per_cell);
    let h = scene.dx / n as f32;
    let first = ((lo - scene.domain_min) / h).floor();
    let last = ((hi - scene.domain_min) / h).ceil();
    let count = (last - first + 1.0).max(Vec3::ZERO);
    let total = count.x as f64 * count.y as f64 * count.z as f64;
    if !total.is_finite() || total > MAX_LATTICE_POINTS as f64 {
        return Err(body_error(
            index,
            format!(
                "the body's bounding box holds about {total:.3e} lattice points, more \
                 than the {MAX_LATTICE_POINTS:.3e} a walk may visit"
            ),
            "make the body smaller, dx larger, or particles_per_cell smaller",
        ));
    }
    Ok(Lattice {
        origin: scene.domain_min,
        h,
        first: [first.x as i64, first.y as i64, first.z as i64],
        count: [count.x as u64, count.y as u64, count.z as u64],
        jitter: body.sampling == Sampling::Jittered,
    })
}

/// Walk the particle positions of body `index` (in parallel, the same positions for any number
/// of threads: see [`super::walk`]); returns them and the volume of one particle. `counter`
/// hears of the work done.
pub(crate) fn walk_body(
    scene: &Scene,
    index: usize,
    mode: Mode,
    counter: &Counter,
) -> Result<(Walked, f32), SceneError> {
    let body = scene
        .bodies
        .get(index)
        .ok_or_else(|| body_error(index, "no such body".into(), "use an existing body index"))?;
    let dx = scene.dx;
    let shape = &body.shape;
    if let Shape::Particles(p) = shape {
        let n = p.points.positions.len() as u64;
        let walked = match mode {
            Mode::Keep => Walked {
                chunks: vec![p.points.positions.clone()],
                count: n,
                ..Walked::default()
            },
            Mode::Count => Walked {
                count: n,
                ..Walked::default()
            },
            Mode::First => Walked {
                count: n.min(1),
                ..Walked::default()
            },
        };
        // Volumes differ per point (see `sample_points`); this is the default one.
        return Ok((walked, dx * dx * dx / body.particles_per_cell.max(1) as f32));
    }
    let (lo, hi) = shape.bounds();
    let rng = Pcg64::seed_from_u64(body_seed(scene, index));
    match body.sampling {
        Sampling::Regular | Sampling::Jittered => {
            let lattice = body_lattice(scene, index)?;
            let h = lattice.h;
            Ok((lattice.walk(shape, &rng, mode, counter), h * h * h))
        }
        Sampling::Random => {
            let volume = shape.volume();
            let count = estimate_body(scene, index);
            // Expected tries: count / (fraction of the bounding box inside the shape).
            let bbox = (hi - lo).max(Vec3::ZERO).element_product() as f64;
            let fill = if bbox > 0.0 {
                (volume as f64 / bbox).min(1.0)
            } else {
                0.0
            };
            let expected = count as f64 / fill.max(1e-30);
            if count > 0 && (!expected.is_finite() || expected > MAX_RANDOM_TRIES as f64 / 4.0) {
                return Err(body_error(
                    index,
                    format!(
                        "random sampling would need about {expected:.2e} tries: the shape fills \
                         {:.2e} of its bounding box",
                        fill
                    ),
                    "use sampling = \"regular\" or \"jittered\", or fewer particles",
                ));
            }
            let max_attempts = count.saturating_mul(1000).clamp(10_000, MAX_RANDOM_TRIES);
            let walked = walk::random(
                shape,
                lo,
                hi,
                count,
                fill,
                max_attempts,
                &rng,
                mode,
                counter,
            );
            let target = if mode == Mode::First {
                count.min(1)
            } else {
                count
            };
            if walked.count < target {
                return Err(body_error(
                    index,
                    format!("placed only {} of {count} random particles", walked.count),
                    "the shape is too thin for random sampling; use sampling = \"regular\"",
                ));
            }
            let vol0 = if count > 0 {
                volume / count as f32
            } else {
                0.0
            };
            Ok((walked, vol0))
        }
    }
}

/// Number of particles body `index` gets, counted without storing them.
pub fn count_body(scene: &Scene, index: usize) -> Result<u64, SceneError> {
    Ok(
        walk_body(scene, index, Mode::Count, &Counter::new(&|_, _| {}))?
            .0
            .count,
    )
}

/// True when body `index` gets no particle (stops at the first one; stores none).
pub fn body_is_empty(scene: &Scene, index: usize) -> Result<bool, SceneError> {
    Ok(
        walk_body(scene, index, Mode::First, &Counter::new(&|_, _| {}))?
            .0
            .count
            == 0,
    )
}

/// How far the sampling of a scene is: body `body` of `bodies`, `done` of about `total` units
/// of work (lattice points visited, or random positions tried).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SampleProgress {
    pub body: usize,
    pub bodies: usize,
    pub done: u64,
    pub total: u64,
}

/// The material of body `index`, or the error naming it.
fn body_material(scene: &Scene, index: usize) -> Result<&Material, SceneError> {
    let body = scene
        .bodies
        .get(index)
        .ok_or_else(|| body_error(index, "no such body".into(), "use an existing body index"))?;
    scene.materials.get(body.material as usize).ok_or_else(|| {
        body_error(
            index,
            format!("material index {} out of range", body.material),
            "fix the material",
        )
    })
}

/// Body `index` sampled: its positions and shared values (or, for a particles body, its whole
/// particles), before anything is written per particle.
pub fn sample_positions(
    scene: &Scene,
    index: usize,
    progress: &(dyn Fn(SampleProgress) + Sync),
) -> Result<SampledBody, SceneError> {
    let material = body_material(scene, index)?;
    let body = &scene.bodies[index];
    if let Shape::Particles(p) = &body.shape {
        let p = sample_points(scene, index, material, &p.points, body.file_velocity)?;
        return Ok(SampledBody::Points(p));
    }
    let bodies = scene.bodies.len();
    let report = |done, total| {
        progress(SampleProgress {
            body: index,
            bodies,
            done,
            total,
        })
    };
    let (walked, vol0) = walk_body(scene, index, Mode::Keep, &Counter::new(&report))?;
    let count = walked.count as usize;
    Ok(SampledBody::Shape(shared_of(
        scene,
        index,
        walked.chunks,
        count,
        vol0,
    )?))
}

/// Body `index`'s walked positions `chunks` (`count` of them, each of volume `vol0`) with what
/// every particle of the body shares.
pub(crate) fn shared_of(
    scene: &Scene,
    index: usize,
    chunks: Vec<Vec<Vec3>>,
    count: usize,
    vol0: f32,
) -> Result<BodyPositions, SceneError> {
    let material = body_material(scene, index)?;
    let body = &scene.bodies[index];
    let (v0, w) = (body.velocity, body.angular_velocity);
    Ok(BodyPositions {
        centre: BodyPositions::centroid(&chunks, count, v0, w),
        chunks,
        count,
        vol0,
        mass: material.density * vol0,
        plastic: material.model.initial_plastic(),
        material: body.material,
        velocity: v0,
        angular_velocity: w,
        c: spin_matrix(w),
    })
}

/// Every body of the scene sampled by [`sample_positions`], in order: 12 bytes a particle, from
/// which the particles (or a backend's own image of them) are written in one pass.
pub fn sample_bodies(
    scene: &Scene,
    progress: &(dyn Fn(SampleProgress) + Sync),
) -> Result<Vec<SampledBody>, SceneError> {
    (0..scene.bodies.len())
        .map(|i| sample_positions(scene, i, progress))
        .collect()
}

/// The particles of sampled bodies ([`sample_bodies`]), written once into their columns:
/// `particles_of(sample_bodies(scene, ..)?)` is `scene.sample_particles()`.
pub fn particles_of(bodies: Vec<SampledBody>) -> Particles {
    let mut all = Particles::default();
    fill::reserve(&mut all, bodies.iter().map(|s| s.len()).sum());
    for s in bodies {
        fill::append(&mut all, s);
    }
    all
}

/// Sample body `index` of the scene.
pub fn sample_body(scene: &Scene, index: usize) -> Result<Particles, SceneError> {
    let sampled = sample_positions(scene, index, &|_| {})?;
    let mut out = Particles::default();
    fill::reserve(&mut out, sampled.len());
    fill::append(&mut out, sampled);
    Ok(out)
}

/// APIC: C is the velocity gradient of the initial field v0 + w x (x - c), the cross-product
/// matrix of w (zero for a pure translation), so P2G carries the rotation from step 0.
fn spin_matrix(w: Vec3) -> Mat3 {
    Mat3::from_cols(
        Vec3::new(0.0, w.z, -w.y),
        Vec3::new(-w.z, 0.0, w.x),
        Vec3::new(w.y, -w.x, 0.0),
    )
}

/// The particles of a particles body: one per point of the file, volume from the file's
/// `volume`, else its `mass` over the material's density, else `dx^3 / particles_per_cell`;
/// velocity from the file (C = 0: the file has no gradient) unless the body gives its own
/// (then `v0 + w x (x - c)` as for the other shapes). The values are checked
/// ([`check_particle_values`]): an error names the file and the point.
fn sample_points(
    scene: &Scene,
    index: usize,
    material: &Material,
    points: &PointSet,
    file_velocity: bool,
) -> Result<Particles, SceneError> {
    let body = &scene.bodies[index];
    let plastic = material.model.initial_plastic();
    let n = points.positions.len();
    let uniform = scene.dx.powi(3) / body.particles_per_cell.max(1) as f32;
    let centre = points.positions.iter().fold(Vec3::ZERO, |a, b| a + *b) / n.max(1) as f32;
    let file_v = points.velocities.as_ref().filter(|_| file_velocity);
    let c = match file_v {
        Some(_) => Mat3::ZERO,
        None => spin_matrix(body.angular_velocity),
    };
    let mut out = Particles::default();
    for (i, &x) in points.positions.iter().enumerate() {
        let vol0 = match (&points.volumes, &points.masses) {
            (Some(v), _) => v[i],
            (None, Some(m)) => m[i] / material.density,
            (None, None) => uniform,
        };
        let v = match file_v {
            Some(v) => v[i],
            None => body.velocity + body.angular_velocity.cross(x - centre),
        };
        out.push(x, v, material.density * vol0, vol0, body.material, plastic);
        if let Some(last) = out.c.last_mut() {
            *last = c;
        }
    }
    check_particle_values(&out).map_err(|e| {
        body_error(
            index,
            format!(
                "{}: point {}: {}",
                points.source.display(),
                e.index,
                e.message
            ),
            "fix the file's values (volume, mass) or the material's density",
        )
    })?;
    Ok(out)
}

/// Sample every body of the scene, in order.
pub fn sample_scene(scene: &Scene) -> Result<Particles, SceneError> {
    sample_scene_with(scene, &|_| {})
}

/// [`sample_scene`], telling `progress` how far it is (from several threads, often: it should
/// only look at the clock before printing). Every body's positions are found first (12 bytes a
/// particle), then the particles are written once, straight into their columns.
pub fn sample_scene_with(
    scene: &Scene,
    progress: &(dyn Fn(SampleProgress) + Sync),
) -> Result<Particles, SceneError> {
    Ok(particles_of(sample_bodies(scene, progress)?))
}

impl Scene {
    /// Fill the bodies with particles (deterministic for a given seed, the same for any number of
    /// threads).
    pub fn sample_particles(&self) -> Result<rtmpm_physics::Particles, SceneError> {
        self.sample_particles_with(&|_| {})
    }

    /// [`Scene::sample_particles`], telling `progress` how far it is (see
    /// [`sample_scene_with`]).
    pub fn sample_particles_with(
        &self,
        progress: &(dyn Fn(SampleProgress) + Sync),
    ) -> Result<rtmpm_physics::Particles, SceneError> {
        sample_scene_with(self, progress).map_err(|mut e| {
            // Sampling errors name the body; the scene file names where it is.
            if e.origin.is_empty()
                && let Some(src) = &self.source
            {
                e.origin = src.display().to_string();
            }
            e
        })
    }
}
