//! Validation of `[[emitter]]` tables.

use super::core::{R, V};
use crate::emitter::{Emitter, MAX_EMITTER_SUB_CELLS, MAX_PARTICLES_PER_EMITTER};
use crate::schema::RawEmitter;
use rtmpm_geometry::{Shape, Use};
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
        let spacing = self.emitter_spacing(&prefix, e, &shape, cx.dx)?;
        let volume = (spacing as f64).powi(3);
        let rate = self.emission_rate(&prefix, e, volume)?;
        let (start, stop) = self.emission_window(&prefix, e, cx.duration)?;
        self.emission_total(&prefix, e, rate, (start, stop), volume)?;
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
        Ok(em)
    }

    /// The particle spacing of emitter `e` of `shape`: `dx / round(cbrt(particles_per_cell))`,
    /// refused where the shape is thinner than a spacing along an axis or holds more sub-cells
    /// than an emitter may list.
    fn emitter_spacing(&self, prefix: &str, e: &RawEmitter, shape: &Shape, dx: f32) -> R<f32> {
        let f = |n: &str| format!("{prefix}.{n}");
        let ppc = e.particles_per_cell.unwrap_or(8);
        if ppc == 0 {
            return Err(self.err(
                f("particles_per_cell"),
                "particles_per_cell must be at least 1",
                "use 8 (2 per axis) or 27 (3 per axis)",
            ));
        }
        let per_axis = (ppc as f32).cbrt().round().max(1.0);
        let spacing = dx / per_axis;
        // Each particle appears in a sub-cell of the lattice: a shape thinner than a sub-cell
        // along an axis would emit particles outside itself.
        let (lo, hi) = shape.bounds();
        let extent = hi - lo;
        if let Some(a) = (0..3).find(|&a| extent[a] < spacing * (1.0 - 1e-4)) {
            return Err(self.err(
                f("shape"),
                format!(
                    "the emitter is {} m across along axis {a}, less than its particle spacing \
                     {spacing} m (dx / round(cbrt(particles_per_cell))): its particles would \
                     appear outside it",
                    extent[a]
                ),
                format!(
                    "make the emitter at least {spacing} m across along every axis (a few \
                     spacings for a jet), or raise particles_per_cell"
                ),
            ));
        }
        // The emitter keeps one position per sub-cell of its shape: bounded before they are
        // listed.
        let sub_cells = Emitter::lattice_size(shape, spacing);
        if sub_cells > MAX_EMITTER_SUB_CELLS as f64 {
            return Err(self.err(
                f(if e.particles_per_cell.is_some() {
                    "particles_per_cell"
                } else {
                    "shape"
                }),
                format!(
                    "the emitter's shape holds about {sub_cells:.3e} sub-cells of spacing \
                     {spacing:e} m (dx / round(cbrt(particles_per_cell))), more than the \
                     {MAX_EMITTER_SUB_CELLS} an emitter may list ({} of memory)",
                    rtmpm_io::limits::human_bytes((sub_cells * 12.0).min(u64::MAX as f64) as u64)
                ),
                "make the emitter smaller, dx larger, or particles_per_cell smaller (8: 2 per \
                 axis, 27: 3 per axis)",
            ));
        }
        Ok(spacing)
    }

    /// The emitter's rate in particles per second: exactly one of `rate` and `volume_rate`
    /// (over `volume`, a particle's volume).
    fn emission_rate(&self, prefix: &str, e: &RawEmitter, volume: f64) -> R<f64> {
        let f = |n: &str| format!("{prefix}.{n}");
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
        Ok(rate)
    }

    /// The emitter's `(start, stop)`: `0 <= start < stop`, stop defaulting to `duration`.
    fn emission_window(&self, prefix: &str, e: &RawEmitter, duration: f32) -> R<(f64, f64)> {
        let f = |n: &str| format!("{prefix}.{n}");
        let start = match e.start {
            Some(0.0) => 0.0,
            Some(s) => self.rate(&f("start"), s, "start time (s)")?,
            None => 0.0,
        };
        let stop = match e.stop {
            Some(s) => self.rate(&f("stop"), s, "stop time (s)")?,
            None => duration as f64,
        };
        if stop <= start {
            return Err(self.err(
                f(if e.stop.is_some() { "stop" } else { "start" }),
                format!(
                    "the emitter stops at {} s, not after it starts ({} s)",
                    seconds(stop),
                    seconds(start)
                ),
                "make stop later than start (stop defaults to time.duration)",
            ));
        }
        Ok((start, stop))
    }

    /// The emitter emits at least one particle and at most [`MAX_PARTICLES_PER_EMITTER`] from
    /// `start` to `stop` at `rate`.
    fn emission_total(
        &self,
        prefix: &str,
        e: &RawEmitter,
        rate: f64,
        (start, stop): (f64, f64),
        volume: f64,
    ) -> R<()> {
        let f = |n: &str| format!("{prefix}.{n}");
        // The particles of the whole emission, before anything is listed (an f64: a huge
        // rate must not wrap or saturate into a plausible count).
        let total = rate * (stop - start);
        let rate_field = f(if e.rate.is_some() {
            "rate"
        } else {
            "volume_rate"
        });
        if total < 1.0 {
            return Err(self.err(
                &rate_field,
                format!(
                    "the emitter would emit no particle: {rate:.3e} particles per second from \
                     {} s to {} s is {total:.3e} particles",
                    seconds(start),
                    seconds(stop)
                ),
                format!(
                    "raise the rate to at least {:.3e} particles per second (or volume_rate to \
                     {:.3e} m^3/s; one particle is {volume:.3e} m^3), or emit for longer",
                    1.0 / (stop - start),
                    volume / (stop - start)
                ),
            ));
        }
        if total > MAX_PARTICLES_PER_EMITTER as f64 {
            return Err(self.err(
                &rate_field,
                format!(
                    "the emitter would emit about {total:.3e} particles from {} s to {} s, \
                     more than the {MAX_PARTICLES_PER_EMITTER} an emitter may",
                    seconds(start),
                    seconds(stop)
                ),
                "lower the rate, shorten start..stop, or lower particles_per_cell",
            ));
        }
        Ok(())
    }

    /// A positive finite f64.
    fn rate(&self, field: &str, x: f64, what: &str) -> R<f64> {
        if x.is_finite() && x > 0.0 {
            Ok(x)
        } else {
            Err(self.err(
                field,
                format!("{what} must be a finite number > 0, got {x}"),
                format!("give a positive value of {what}"),
            ))
        }
    }
}

/// Seconds as the scene file would write them: `0.05`, not the f32-to-f64 `0.05000000074505806`.
pub(super) fn seconds(t: f64) -> String {
    if t != 0.0 && !(1e-4..1e6).contains(&t.abs()) {
        return format!("{t:e}");
    }
    let short = (t as f32) as f64;
    if short == t || (t - short).abs() <= 1e-7 * t.abs() {
        format!("{}", t as f32)
    } else {
        format!("{t}")
    }
}
