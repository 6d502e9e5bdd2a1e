//! Validation of prescribed motion: the keyframes of a collider.

use super::core::{R, V, fmt3};
use crate::schema::*;
use glam::Quat;
use rtmpm_geometry::{Keyframe, Keyframes};
use rtmpm_physics::math::Vec3;

impl V<'_> {
    /// `collider[i].keyframes`: at least one key, finite values, strictly increasing times,
    /// turns of less than half a revolution between consecutive keys (slerp takes the shorter
    /// arc), and no constant `velocity` / `angular_velocity` beside them. A key without
    /// `position` keeps the pivot where the rest pose has it.
    pub(super) fn keyframes(
        &self,
        prefix: &str,
        c: &RawCollider,
        keys: &[RawKeyframe],
        pivot: Vec3,
    ) -> R<Keyframes> {
        for (name, given) in [
            ("velocity", c.velocity.is_some()),
            ("angular_velocity", c.angular_velocity.is_some()),
        ] {
            if given {
                return Err(self.err(
                    format!("{prefix}.{name}"),
                    format!("a collider with keyframes cannot also have a constant `{name}`"),
                    format!(
                        "remove `{name}` (the keyframes give the motion, and the velocity follows from them) or remove `keyframes`"
                    ),
                ));
            }
        }
        if keys.is_empty() {
            return Err(self.err(
                format!("{prefix}.keyframes"),
                "keyframes is empty",
                "give at least one key, e.g. keyframes = [{ t = 0.0, position = [0.5, 0.5, 0.5], rotation = [0.0, 0.0, 0.0] }], or remove keyframes",
            ));
        }
        let mut out = Vec::with_capacity(keys.len());
        let mut previous: Option<Vec3> = None;
        for (k, key) in keys.iter().enumerate() {
            let f = |n: &str| format!("{prefix}.keyframes[{k}].{n}");
            let t = self.non_negative(&f("t"), key.t, "key time t (s)")?;
            let position = match key.position {
                Some(p) => self.vec3(&f("position"), p)?,
                None => pivot,
            };
            let r = match key.rotation {
                Some(r) => self.vec3(&f("rotation"), r)?,
                None => Vec3::ZERO,
            };
            if let Some(prev) = previous {
                let turn = (r - prev).length();
                if turn >= std::f32::consts::PI {
                    return Err(self.err(
                        f("rotation"),
                        format!(
                            "the rotation turns by {turn:.4} rad from key {} to key {k} (from {} to {}); the rotation between two keys is interpolated along the shorter arc, so a turn of pi (half a revolution) or more is ambiguous",
                            k - 1,
                            fmt3(prev),
                            fmt3(r)
                        ),
                        "add keys in between so that consecutive keys turn by less than pi rad (e.g. a key every quarter turn)",
                    ));
                }
            }
            previous = Some(r);
            out.push(Keyframe {
                t,
                position,
                rotation: Quat::from_scaled_axis(r),
            });
        }
        Keyframes::new(out).map_err(|e| {
            let field = if e.field.is_empty() {
                format!("{prefix}.keyframes")
            } else {
                format!("{prefix}.keyframes[{}].{}", e.key, e.field)
            };
            self.err(field, e.message, e.hint)
        })
    }
}
