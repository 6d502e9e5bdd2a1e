//! Validation of `[[emitter]]` tables.

use super::core::{R, V};
use crate::emitter::{Emitter, MAX_PARTICLES_PER_EMITTER};
use crate::schema::RawEmitter;
use rtmpm_geometry::Use;
use rtmpm_physics::material::Material;
use rtmpm_physics::math::Vec3;
use std::path::Path;

/// The scene-wide settings an emitter is checked against.
pub(super) struct EmitterContext<'a> {
    pub materials: &'a [Material],
    pub base: &'a Path,
    pub dx: f32,
    /// The domain minus the walls.
    pub interior: (Vec3, Vec3),
    pub duration: f32,
    pub seed: u64,
}

impl V<'_> {
    /// `emitter[i]`: a box, sphere or cylinder inside the domain minus the walls, a known
    /// material, exactly one of `rate` (particles/s) and `volume_rate` (m^3/s), and
    /// `0 <= start < stop`; at most [`MAX_PARTICLES_PER_EMITTER`] particles in all.
    pub(super) fn emitter(&self, i: usize, e: &RawEmitter, cx: &EmitterContext<'_>) -> R<Emitter> {
        let prefix = format!("emitter[{i}]");
        let f = |n: &str| format!("{prefix}.{n}");
        let material = self.material_index(&prefix, &e.material, cx.materials)?;
        let shape = self.shape(&prefix, &e.geometry(), Use::Emitter, cx.base, cx.dx)?;
        self.inside_interior(&prefix, "emitter", shape.bounds(), cx.interior)?;
        let ppc = e.particles_per_cell.unwrap_or(8);
        if ppc == 0 {
            return Err(self.err(
                f("particles_per_cell"),
                "particles_per_cell must be at least 1",
                "use 8 (2 per axis) or 27 (3 per axis)",
            ));
        }
        let per_axis = (ppc as f32).cbrt().round().max(1.0);
        let spacing = cx.dx / per_axis;
        let volume = (spacing as f64).powi(3);
        let rate = match (e.rate, e.volume_rate) {
            (Some(_), Some(_)) => {
                return Err(self.err(
                    f("volume_rate"),
                    "both rate and volume_rate are given",
                    "keep rate (particles per second) or volume_rate (m^3 per second)",
                ));
            }
            (None, None) => {
                return Err(self.err(
                    f("rate"),
                    "an emitter needs a rate",
                    format!(
                        "add rate = <particles per second> or volume_rate = <m^3 per second> (one particle is {volume:.3e} m^3)"
                    ),
                ));
            }
            (Some(r), None) => self.rate(&f("rate"), r, "rate (particles/s)")?,
            (None, Some(v)) => self.rate(&f("volume_rate"), v, "volume_rate (m^3/s)")? / volume,
        };
        let start = match e.start {
            Some(0.0) => 0.0,
            Some(s) => self.rate(&f("start"), s, "start time (s)")?,
            None => 0.0,
        };
        let stop = match e.stop {
            Some(s) => self.rate(&f("stop"), s, "stop time (s)")?,
            None => cx.duration as f64,
        };
        if stop <= start {
            return Err(self.err(
                f(if e.stop.is_some() { "stop" } else { "start" }),
                format!("the emitter stops at {stop} s, not after it starts ({start} s)"),
                "make stop later than start (stop defaults to time.duration)",
            ));
        }
        let velocity = match e.velocity {
            Some(v) => self.vec3(&f("velocity"), v)?,
            None => Vec3::ZERO,
        };
        let seed = cx
            .seed
            .wrapping_mul(0x9e37_79b9_7f4a_7c15)
            .wrapping_add(i as u64 + 1);
        let cells = Emitter::lattice(&shape, spacing, seed);
        if cells.is_empty() {
            return Err(self.err(
                f("shape"),
                "the emitter's shape holds no particle position",
                format!(
                    "make it larger than the particle spacing {spacing} m (dx / round(cbrt(particles_per_cell)))"
                ),
            ));
        }
        let em = Emitter {
            name: e.name.clone().unwrap_or_else(|| format!("emitter{i}")),
            material: material as u32,
            shape,
            velocity,
            rate,
            start,
            stop,
            spacing,
            particle_mass: cx.materials[material].density * volume as f32,
            cells,
            seed,
        };
        if em.total() > MAX_PARTICLES_PER_EMITTER {
            return Err(self.err(
                f(if e.rate.is_some() { "rate" } else { "volume_rate" }),
                format!(
                    "the emitter would emit {} particles from {start} s to {stop} s, more than the {MAX_PARTICLES_PER_EMITTER} an emitter may",
                    em.total()
                ),
                "lower the rate, shorten start..stop, or lower particles_per_cell",
            ));
        }
        Ok(em)
    }

    /// A positive finite f64.
    fn rate(&self, field: &str, x: f64, what: &str) -> R<f64> {
        if x.is_finite() && x > 0.0 {
            Ok(x)
        } else {
            Err(self.err(
                field,
                format!("{what} must be a finite number > 0, got {x}"),
                format!("give a positive {what}"),
            ))
        }
    }
}
