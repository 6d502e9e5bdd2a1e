//! The `[time]` table: duration, frame rate, the fixed or CFL time step and settling damping.

use super::core::{R, V};
use crate::schema::RawScene;
use crate::settings::{Damping, StepMode, TimeSettings};

impl V<'_> {
    /// The time settings; the default `min_dt` of a CFL step depends on the materials' sound
    /// speed and on `dx`.
    pub(super) fn time(&self, raw: &RawScene, dx: f32) -> R<TimeSettings> {
        let t = &raw.time;
        let duration = self.positive("time.duration", t.duration, "duration (s)")?;
        let fps = self.positive("time.fps", t.fps.unwrap_or(30.0), "fps")?;
        let step = match (t.dt, t.cfl) {
            (Some(_), Some(_)) => {
                return Err(self.err(
                    "time.cfl",
                    "both dt and cfl are given",
                    "keep dt for a fixed step or cfl for an adaptive one",
                ));
            }
            (Some(dt), None) => {
                if t.min_dt.is_some() {
                    return Err(self.err(
                        "time.min_dt",
                        "min_dt only applies to a CFL step",
                        "remove min_dt, or replace dt by cfl",
                    ));
                }
                if t.max_dt.is_some() {
                    return Err(self.err(
                        "time.max_dt",
                        "max_dt only applies to a CFL step",
                        "remove max_dt, or replace dt by cfl",
                    ));
                }
                StepMode::Fixed {
                    dt: self.positive("time.dt", dt, "dt (s)")?,
                }
            }
            (None, cfl) => {
                let cfl = cfl.unwrap_or(0.4);
                self.finite("time.cfl", cfl)?;
                if !(cfl > 0.0 && cfl <= 1.0) {
                    return Err(self.err(
                        "time.cfl",
                        format!("cfl must be in (0, 1], got {cfl}"),
                        "use a CFL number such as 0.4",
                    ));
                }
                let max_dt =
                    self.positive("time.max_dt", t.max_dt.unwrap_or(1e-3), "max_dt (s)")?;
                // Default: a thousandth of the step the materials' sound speed allows at rest.
                let sound = materials_sound_speed(raw, self);
                let at_rest = if sound > 0.0 {
                    (cfl * dx / sound).min(max_dt)
                } else {
                    max_dt
                };
                let min_dt = match t.min_dt {
                    Some(m) => {
                        let m = self.positive("time.min_dt", m, "min_dt (s)")?;
                        if m > max_dt {
                            return Err(self.err(
                                "time.min_dt",
                                format!("min_dt = {m} s is above max_dt = {max_dt} s"),
                                "use a min_dt well below max_dt, e.g. 1e-7",
                            ));
                        }
                        m
                    }
                    None => at_rest * 1e-3,
                };
                StepMode::Cfl {
                    cfl,
                    max_dt,
                    min_dt,
                }
            }
        };
        if let StepMode::Fixed { dt } = step
            && dt > 1.0 / fps
        {
            {
                return Err(self.err(
                    "time.dt",
                    format!(
                        "dt = {dt} s is longer than a frame (1/fps = {} s)",
                        1.0 / fps
                    ),
                    "use a smaller dt",
                ));
            }
        }
        let damping = Damping {
            rate: self.non_negative("time.damping", t.damping.unwrap_or(0.0), "damping (1/s)")?,
            until: match t.damping_until {
                Some(u) => self.positive("time.damping_until", u, "damping_until (s)")?,
                None => f32::INFINITY,
            },
        };
        let time = TimeSettings {
            duration,
            fps,
            step,
            damping,
        };

        Ok(time)
    }
}

/// Largest sound speed of the scene's materials (0 when one cannot be built yet: its own
/// error is reported when the materials are validated).
fn materials_sound_speed(raw: &RawScene, v: &V<'_>) -> f32 {
    raw.material
        .iter()
        .enumerate()
        .filter_map(|(i, m)| v.material(i, m).ok())
        .map(|m| m.model.sound_speed(m.density))
        .filter(|c| c.is_finite())
        .fold(0.0, f32::max)
}
