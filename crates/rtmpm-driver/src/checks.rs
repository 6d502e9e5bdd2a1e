//! The measurements of the validation checks of rigid bodies and emitters, shared by `rtmpm
//! validate` (cases `archimedes`, `sinking`, `rigid_momentum`, `emitter_mass`, any backend) and
//! the cargo tests `tests/rigid.rs` and `tests/emitters.rs` (CPU). The scenes are the files
//! `validation/{archimedes,sinking,rigid_momentum,emitter_mass}.toml`; [`edit_toml`] changes
//! their resolution or a body's density. Every function runs a [`Simulation`] to the end of its
//! scene and measures; the body states come from [`Backend::rigid_bodies`], so a backend that
//! couples no bodies is caught ([`CheckError::NoBodies`]) rather than measured as if it did.

use crate::Simulation;
use glam::DVec3;
use rtmpm_physics::Particles;
use rtmpm_sim::{Backend, SimError};

/// Why a check could not measure.
#[derive(Debug, thiserror::Error)]
pub enum CheckError {
    /// The simulation failed (a blow-up, or the backend refused the scene).
    #[error(transparent)]
    Sim(#[from] SimError),
    /// The backend reports fewer rigid bodies than the scene has.
    #[error(
        "the backend `{backend}` reports {found} rigid bodies, the scene has {expected}: it does \
         not couple [[rigid_body]] tables"
    )]
    NoBodies {
        backend: String,
        found: usize,
        expected: usize,
    },
    /// The scene is not the one the check expects.
    #[error("{0}")]
    Scene(String),
}

/// The scene text `text` with `edits` applied: each a dotted path (`domain.dx`,
/// `rigid_body.0.density`; numbers index arrays of tables) and the new value. Comments and the
/// other lines are kept.
pub fn edit_toml(text: &str, edits: &[(&str, toml_edit::Value)]) -> Result<String, String> {
    let mut doc: toml_edit::DocumentMut = text.parse().map_err(|e| format!("{e}"))?;
    for (path, value) in edits {
        let mut item = doc.as_item_mut();
        for seg in path.split('.') {
            let next = match seg.parse::<usize>() {
                Ok(i) => item.get_mut(i),
                Err(_) => item.get_mut(seg),
            };
            item = next.ok_or_else(|| format!("`{path}`: no `{seg}` in the scene"))?;
        }
        *item = toml_edit::Item::Value(value.clone());
    }
    Ok(doc.to_string())
}

/// The scene text at `factor` times the resolution of `text`: `domain.dx` divided by `factor`
/// and `walls.thickness` (3 cells when absent) multiplied by it, so the walls keep their
/// thickness in metres and the material its place.
pub fn refine(text: &str, factor: u32) -> Result<String, String> {
    let doc: toml_edit::DocumentMut = text.parse().map_err(|e| format!("{e}"))?;
    let dx = doc["domain"]["dx"]
        .as_float()
        .ok_or("the scene's domain.dx is not a number")?;
    let thickness = doc
        .get("walls")
        .and_then(|w| w.get("thickness"))
        .and_then(|t| t.as_integer())
        .unwrap_or(3);
    let mut text = edit_toml(text, &[("domain.dx", (dx / factor as f64).into())])?;
    let mut doc: toml_edit::DocumentMut = text.parse().map_err(|e| format!("{e}"))?;
    doc["walls"]["thickness"] = toml_edit::value(thickness * factor as i64);
    text = doc.to_string();
    Ok(text)
}

/// The body states after making sure the backend couples every body of the scene.
fn bodies<B: Backend + ?Sized>(
    sim: &Simulation<B>,
) -> Result<Vec<rtmpm_rigid::BodyState>, CheckError> {
    let s = sim.backend.rigid_bodies();
    let expected = sim.scene.rigid_bodies.len();
    if s.len() != expected {
        return Err(CheckError::NoBodies {
            backend: sim.backend.name(),
            found: s.len(),
            expected,
        });
    }
    Ok(s)
}

/// Linear momentum of the particles, summed in f64.
pub fn momentum(p: &Particles) -> DVec3 {
    (0..p.len()).fold(DVec3::ZERO, |a, i| a + p.v[i].as_dvec3() * p.mass[i] as f64)
}

/// A floating body, measured by [`float`].
#[derive(Clone, Copy, Debug)]
pub struct Floating {
    /// Submerged fraction of the body's height (its height in its initial orientation), below
    /// the surface of each of the last frames, averaged.
    pub fraction: f64,
    /// The body's centre height (m), averaged over the last frames.
    pub centre: f64,
    /// The free surface's height away from the body (m), averaged over the last frames.
    pub surface: f64,
    /// How far the body has turned from its initial orientation at the end (degrees).
    pub tilt_degrees: f64,
    /// A box's submerged fraction of its volume, in the pose and below the surface of each of
    /// the last frames, averaged: Archimedes' displaced volume whatever the tilt (for an
    /// upright box it is [`Floating::fraction`]; a box tilted by `t` with its centre `h` above
    /// the surface has `h / cos t` where the fraction of height has `h`). `None` for other
    /// shapes.
    pub volume_fraction: Option<f64>,
    /// The tilt from the initial orientation averaged over the last frames (degrees).
    pub mean_tilt_degrees: f64,
    /// The body's height in its initial orientation (m), the one the fractions are of.
    pub height: f64,
}

/// The fraction of the volume of a box with half-extents `half`, centre `center` and
/// body-to-world rotation `rotation`, that lies below the plane `y = surface`: the submerged
/// length along the box's local y axis integrated over its local x-z face (a 256 x 256 midpoint
/// rule; exact where no column is cut by the clamps, the length being linear across the face).
pub fn box_submerged_fraction(
    half: glam::Vec3,
    center: glam::Vec3,
    rotation: glam::Mat3,
    surface: f64,
) -> f64 {
    const N: usize = 256;
    let (h, a_y) = (half.as_dvec3(), rotation.y_axis.y as f64);
    let (ex, ez) = (rotation.x_axis.y as f64, rotation.z_axis.y as f64);
    let depth = surface - center.y as f64;
    let mut sum = 0.0;
    for i in 0..N {
        let x = ((i as f64 + 0.5) / N as f64 * 2.0 - 1.0) * h.x;
        for k in 0..N {
            let z = ((k as f64 + 0.5) / N as f64 * 2.0 - 1.0) * h.z;
            // Height of the column's axis point (x, 0, z) above the centre; along the local y
            // axis the height changes by a_y per metre.
            let d = depth - (ex * x + ez * z);
            let below = if a_y.abs() < 1e-12 {
                if d > 0.0 { 2.0 * h.y } else { 0.0 }
            } else {
                // local y in [-h.y, h.y] with a_y t < d
                let t = d / a_y;
                if a_y > 0.0 { t + h.y } else { h.y - t }
            };
            sum += below.clamp(0.0, 2.0 * h.y);
        }
    }
    sum / (N * N) as f64 / (2.0 * h.y)
}

/// Frames over whose end the floating body's height is averaged.
const AVERAGE_FRAMES: u64 = 10;

/// A floating body's pose and the open water's surface height (m) in one averaged frame.
struct Pose {
    center: glam::Vec3,
    rotation: glam::Mat3,
    tilt: f64,
    surface: f64,
}

/// Run `sim` to the end of its scene and measure how deep its first rigid body floats, in each
/// of the last 10 frames, averaged: its centre height, the free surface of the open water
/// ([`free_surface`] over the columns 3 cells or more from the walls and from the body's
/// footprint where it started) and the submerged fraction of its height in its initial
/// orientation (a box's height, a lying cylinder's diameter) below that frame's surface.
/// `each_frame(time, centre height)` is called after every frame.
pub fn float<B: Backend + ?Sized>(
    sim: &mut Simulation<B>,
    mut each_frame: impl FnMut(f64, f64),
) -> Result<Floating, CheckError> {
    let spec = sim
        .scene
        .rigid_bodies
        .first()
        .ok_or_else(|| CheckError::Scene("the scene has no rigid body".into()))?
        .clone();
    let initial = glam::Mat3::from_quat(spec.rotation);
    let half_height = spec.shape.half_extents(initial).y as f64;
    let frames = sim.scene.time.frames();
    // The open water: columns 3 cells or more from the walls and from the body's footprint where
    // it started (it drifts by millimetres). The node-based boundaries hold a rim of water up to
    // 0.3 dx higher within about 3 cells of them (measured in the Archimedes scene at dx = 0.02:
    // 6 mm at the walls), which is not the level whose pressure holds the body up.
    let half = spec.shape.half_extents(initial);
    let dx = sim.scene.dx;
    let margin = 3.0 * dx;
    let walls = sim.scene.walls.thickness as f32 * dx + margin;
    let (lo, hi) = (sim.scene.domain_min + walls, sim.scene.domain_max - walls);
    let (cx, cz) = (spec.position.x, spec.position.z);
    let open = |x: f32, z: f32| {
        (lo.x..=hi.x).contains(&x)
            && (lo.z..=hi.z).contains(&z)
            && ((x - cx).abs() - half.x).max((z - cz).abs() - half.z) >= margin
    };
    let mut last = None;
    // The body's pose and the open water's surface in each of the last frames, over which the
    // measures average: the water and the body bob together (by about a millimetre at dx = 0.02,
    // a twentieth of the light box's draft), so each frame's draft is taken against that frame's
    // surface.
    let mut poses = Vec::new();
    let tilt = |b: &rtmpm_rigid::BodyState| {
        let turn = glam::Quat::from_mat3(&(b.rotation * initial.transpose()));
        turn.to_axis_angle().1.to_degrees() as f64
    };
    let mut p = Particles::default();
    for f in 0..frames {
        sim.advance_frame()?;
        let b = bodies(sim)?[0].clone();
        each_frame(sim.time, b.center.y as f64);
        if f + AVERAGE_FRAMES >= frames {
            sim.backend.read_particles(&mut p)?;
            let surface = free_surface(p.x.iter(), dx, open).ok_or_else(|| {
                CheckError::Scene(
                    "no material 3 cells or more from the body and the walls to measure the \
                     surface"
                        .into(),
                )
            })?;
            poses.push(Pose {
                center: b.center,
                rotation: b.rotation,
                tilt: tilt(&b),
                surface,
            });
        }
        last = Some(b);
    }
    let b = last.ok_or_else(|| CheckError::Scene("the scene has no frames".into()))?;
    let mean = |v: &dyn Fn(&Pose) -> f64| poses.iter().map(v).sum::<f64>() / poses.len() as f64;
    let draft = |q: &Pose| q.surface - (q.center.y as f64 - half_height);
    let volume_fraction = match spec.shape {
        rtmpm_geometry::Shape::Box(c) => Some(mean(&|q| {
            box_submerged_fraction(c.half_size(), q.center, q.rotation, q.surface)
        })),
        _ => None,
    };
    Ok(Floating {
        fraction: mean(&draft) / (2.0 * half_height),
        centre: mean(&|q| q.center.y as f64),
        surface: mean(&|q| q.surface),
        tilt_degrees: tilt(&b),
        volume_fraction,
        mean_tilt_degrees: mean(&|q| q.tilt),
        height: 2.0 * half_height,
    })
}

/// The height of a resting free surface (m): the median over the columns of the grid (`dx` by
/// `dx` in x and z) whose centre `(x, z)` passes `keep` of the highest particle in each, plus
/// half a particle spacing (`dx / 4` at 8 particles per cell). The median ignores drops and splashes; the highest particle of a column
/// is its top layer whatever the depth (a percentile of all the heights is not: the 98th falls
/// below the top layer once the water holds more than 50 layers, 2.5 mm low at dx = 0.005 in
/// the Archimedes scene). `None` without particles.
pub fn free_surface<'a>(
    positions: impl Iterator<Item = &'a glam::Vec3>,
    dx: f32,
    keep: impl Fn(f32, f32) -> bool,
) -> Option<f64> {
    let mut top = std::collections::HashMap::<(i64, i64), f32>::new();
    for x in positions {
        let column = ((x.x / dx).floor() as i64, (x.z / dx).floor() as i64);
        if !keep((column.0 as f32 + 0.5) * dx, (column.1 as f32 + 0.5) * dx) {
            continue;
        }
        let t = top.entry(column).or_insert(x.y);
        *t = t.max(x.y);
    }
    let mut tops: Vec<f32> = top.into_values().collect();
    if tops.is_empty() {
        return None;
    }
    tops.sort_by(f32::total_cmp);
    Some((tops[tops.len() / 2] + 0.25 * dx) as f64)
}

/// Run `sim` to the end of its scene; the rigid bodies' final states.
pub fn settle<B: Backend + ?Sized>(
    sim: &mut Simulation<B>,
) -> Result<Vec<rtmpm_rigid::BodyState>, CheckError> {
    for _ in 0..sim.scene.time.frames() {
        sim.advance_frame()?;
    }
    bodies(sim)
}

/// The momentum exchange between a thrown body of material and one free rigid body, measured by
/// [`collide`].
#[derive(Clone, Copy, Debug)]
pub struct Collision {
    /// Momentum of the material at t = 0.
    pub start: DVec3,
    /// Momentum of the material at the end.
    pub material: DVec3,
    /// Momentum of the rigid body at the end.
    pub body: DVec3,
    /// The rigid body's final velocity along x (m/s).
    pub body_speed: f64,
    /// The elastic-collision estimate of that speed, `2 m1 v1 / (m1 + m2)` (m/s), with `m1` the
    /// material's mass and `v1` its initial speed along x.
    pub elastic: f64,
}

impl Collision {
    /// |total momentum at the end - at the start| / |at the start|.
    pub fn momentum_error(&self) -> f64 {
        (self.material + self.body - self.start).length() / self.start.length()
    }
}

/// Run `sim` (zero gravity, material thrown along +x at a free rigid body at rest) to the end
/// of its scene and measure the momentum of material plus body.
pub fn collide<B: Backend + ?Sized>(sim: &mut Simulation<B>) -> Result<Collision, CheckError> {
    let mut p = Particles::default();
    sim.backend.read_particles(&mut p)?;
    let start = momentum(&p);
    let m1: f64 = p.mass.iter().map(|&m| m as f64).sum();
    let body_mass = sim
        .scene
        .rigid_bodies
        .first()
        .ok_or_else(|| CheckError::Scene("the scene has no rigid body".into()))?
        .mass as f64;
    let b = settle(sim)?[0].clone();
    sim.backend.read_particles(&mut p)?;
    let v1 = start.x / m1;
    Ok(Collision {
        start,
        material: momentum(&p),
        body: b.velocity.as_dvec3() * body_mass,
        body_speed: b.velocity.x as f64,
        elastic: 2.0 * m1 * v1 / (m1 + body_mass),
    })
}

/// The emitted mass against rate x t, measured by [`emission`].
#[derive(Clone, Copy, Debug, Default)]
pub struct Emission {
    /// Largest |emitted mass - rate x t x particle mass| over the frames, in particles.
    pub worst_particles: f64,
    /// Particles the first emitter emitted by the end.
    pub emitted: u64,
    /// Its rate times its emitting time, `rate (stop - start)`, when the run ends after `stop`.
    pub expected: f64,
}

/// Run `sim` to the end of its scene and compare, after every frame, the mass of the first
/// emitter's material (less its mass at t = 0) with `rate (min(t, stop) - start)` particles.
pub fn emission<B: Backend + ?Sized>(sim: &mut Simulation<B>) -> Result<Emission, CheckError> {
    let em = sim
        .scene
        .emitters
        .first()
        .ok_or_else(|| CheckError::Scene("the scene has no emitter".into()))?
        .clone();
    let m = em.particle_mass as f64;
    let mut p = Particles::default();
    let material_mass = |p: &Particles| -> f64 {
        (0..p.len())
            .filter(|&i| p.material[i] == em.material)
            .map(|i| p.mass[i] as f64)
            .sum()
    };
    sim.backend.read_particles(&mut p)?;
    let base = material_mass(&p);
    let mut out = Emission::default();
    for _ in 0..sim.scene.time.frames() {
        sim.advance_frame()?;
        sim.backend.read_particles(&mut p)?;
        let expect = em.rate * (sim.time.min(em.stop) - em.start).max(0.0) * m;
        let got = material_mass(&p) - base;
        out.worst_particles = out.worst_particles.max((got - expect).abs() / m);
    }
    out.emitted = sim.emitted().first().copied().unwrap_or(0);
    out.expected = em.rate * (em.stop - em.start);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::{box_submerged_fraction, free_surface};
    use glam::{Mat3, Vec3};

    #[test]
    fn a_box_s_submerged_volume_is_its_draft_upright_and_h_over_cos_tilted() {
        let half = Vec3::new(0.06, 0.05, 0.06);
        // Upright, the centre 2.5 cm above the surface: a quarter of the volume below.
        let up = box_submerged_fraction(half, Vec3::new(0.3, 0.275, 0.3), Mat3::IDENTITY, 0.25);
        assert!((up - 0.25).abs() < 1e-6, "{up}");
        // Tilted by t about x or about a horizontal diagonal, no edge out of the water: the
        // submerged length along the axis at the face's centre is 0.05 - 0.025 / cos t.
        // (Past 12 degrees about the diagonal a corner of the bottom leaves the water.)
        for (t, axes) in [(5.0f32, 2), (12.0, 2), (20.0, 1)] {
            for axis in [Vec3::X, Vec3::new(1.0, 0.0, 1.0).normalize()]
                .into_iter()
                .take(axes)
            {
                let r = Mat3::from_axis_angle(axis, t.to_radians());
                let f = box_submerged_fraction(half, Vec3::new(0.3, 0.275, 0.3), r, 0.25);
                let expect = (0.05 - 0.025 / (t.to_radians() as f64).cos()) / 0.1;
                assert!((f - expect).abs() < 1e-6, "{t} {axis}: {f} vs {expect}");
            }
        }
        // Fully below, fully above, and upside down (the same volume).
        let flip = Mat3::from_axis_angle(Vec3::X, std::f32::consts::PI);
        assert!(
            (box_submerged_fraction(half, Vec3::ZERO, Mat3::IDENTITY, 1.0) - 1.0).abs() < 1e-12
        );
        assert!(box_submerged_fraction(half, Vec3::ZERO, Mat3::IDENTITY, -1.0).abs() < 1e-12);
        let f = box_submerged_fraction(half, Vec3::new(0.0, 0.025, 0.0), flip, 0.0);
        assert!((f - 0.25).abs() < 1e-6, "{f}");
    }

    #[test]
    fn the_free_surface_is_the_top_layer_at_any_depth_and_ignores_drops() {
        // 8 regular particles per cell (spacing dx / 2) over 0.4 x 0.4 m, the top layer at
        // 0.2 + dx / 4 - dx / 2: the surface is at 0.2 whatever the number of layers (20 to 160),
        // with drops flying above a tenth of the grid's columns.
        for dx in [0.02f32, 0.01, 0.005, 0.0025] {
            let s = dx / 2.0;
            let (nxz, ny) = ((0.4 / s).round() as i32, (0.2 / s).round() as i32);
            let mut x = Vec::new();
            for i in 0..nxz {
                for k in 0..nxz {
                    for j in 0..ny {
                        x.push(Vec3::new(
                            (i as f32 + 0.5) * s,
                            (j as f32 + 0.5) * s,
                            (k as f32 + 0.5) * s,
                        ));
                    }
                    if i % 2 == 0 && k % 2 == 0 && (i / 2 * 7 + k / 2) % 10 == 0 {
                        x.push(Vec3::new((i as f32 + 0.5) * s, 0.3, (k as f32 + 0.5) * s));
                    }
                }
            }
            let surface = free_surface(x.iter(), dx, |_, _| true).unwrap();
            assert!((surface - 0.2).abs() < 1e-5, "dx = {dx}: {surface}");
        }
        assert_eq!(free_surface([].iter(), 0.01, |_, _| true), None);
        // Only the columns kept: the drops' columns alone.
        let drop = [Vec3::new(0.005, 0.3, 0.005), Vec3::new(0.015, 0.1, 0.005)];
        assert_eq!(
            free_surface(drop.iter(), 0.01, |x, _| x < 0.01),
            Some((0.3f32 + 0.25 * 0.01f32) as f64)
        );
    }
}
