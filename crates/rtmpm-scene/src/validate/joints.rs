//! Validation of `[[joint]]` tables.

use super::core::{R, V, fmt3};
use crate::schema::*;
use rtmpm_physics::math::Vec3;
use rtmpm_rigid::{JointKind, JointSpec, RigidBodySpec, RigidKind};

impl V<'_> {
    /// `joint[i]`: `body` (and `to`, absent for the world) name existing rigid bodies by index
    /// or name, two different bodies, at least one of them dynamic; a finite `anchor` inside the
    /// domain; a non-zero `axis` for a revolute or prismatic joint and none for the others;
    /// `limits = [lo, hi]` with lo <= hi, only on a revolute or prismatic joint.
    pub(super) fn joint(
        &self,
        i: usize,
        j: &RawJoint,
        bodies: &[RigidBodySpec],
        domain: (Vec3, Vec3),
    ) -> R<JointSpec> {
        let f = |n: &str| format!("joint[{i}].{n}");
        let body = self.body_ref(&f("body"), &j.body, bodies)?;
        let to = match &j.to {
            Some(r) => Some(self.body_ref(&f("to"), r, bodies)?),
            None => None,
        };
        if to == Some(body) {
            return Err(self.err(
                f("to"),
                format!("the joint holds rigid_body[{body}] to itself"),
                "name another rigid body in `to`, or remove `to` to hold the body to the world",
            ));
        }
        let movable = |b: usize| bodies[b].kind == RigidKind::Dynamic;
        if !movable(body) && !to.is_some_and(movable) {
            return Err(self.err(
                f("body"),
                "no body of this joint is dynamic: the joint would hold nothing",
                "joint a body of type = \"dynamic\" (the default)",
            ));
        }
        let anchor = self.vec3(&f("anchor"), j.anchor)?;
        let (lo, hi) = domain;
        if anchor.cmplt(lo).any() || anchor.cmpgt(hi).any() {
            return Err(self.err(
                f("anchor"),
                format!("the anchor {} is outside the domain", fmt3(anchor)),
                format!(
                    "put the anchor inside the domain {} .. {}",
                    fmt3(lo),
                    fmt3(hi)
                ),
            ));
        }
        let limits = self.joint_limits(i, j)?;
        let axis = |needed: bool| self.joint_axis(i, j, needed);
        let kind = match j.kind {
            RawJointKind::Fixed => {
                axis(false)?;
                JointKind::Fixed
            }
            RawJointKind::Spherical => {
                axis(false)?;
                JointKind::Spherical
            }
            RawJointKind::Revolute => JointKind::Revolute {
                axis: axis(true)?.unwrap_or(Vec3::Z),
                limits,
            },
            RawJointKind::Prismatic => JointKind::Prismatic {
                axis: axis(true)?.unwrap_or(Vec3::X),
                limits,
            },
        };
        Ok(JointSpec {
            kind,
            body,
            to,
            anchor,
        })
    }

    /// The joint's unit axis: given and non-zero where `needed` (a revolute or prismatic
    /// joint), absent otherwise.
    fn joint_axis(&self, i: usize, j: &RawJoint, needed: bool) -> R<Option<Vec3>> {
        let f = |n: &str| format!("joint[{i}].{n}");
        match (j.axis, needed) {
            (Some(a), true) => {
                let a = self.vec3(&f("axis"), a)?;
                a.try_normalize().map(Some).ok_or_else(|| {
                    self.err(
                        f("axis"),
                        "the axis is zero",
                        "give the hinge or slide direction, e.g. axis = [0, 0, 1]",
                    )
                })
            }
            (None, true) => Err(self.err(
                f("axis"),
                format!("a {:?} joint needs an axis", j.kind).to_lowercase(),
                "add axis = [x, y, z] (the hinge or slide direction in the world at t = 0)",
            )),
            (Some(_), false) => Err(self.err(
                f("axis"),
                format!("a {:?} joint has no axis", j.kind).to_lowercase(),
                "remove axis, or use type = \"revolute\" or \"prismatic\"",
            )),
            (None, false) => Ok(None),
        }
    }

    /// The joint's `limits = [lo, hi]`: two finite values, lo <= hi, only on a revolute or
    /// prismatic joint.
    fn joint_limits(&self, i: usize, j: &RawJoint) -> R<Option<[f32; 2]>> {
        let f = |n: &str| format!("joint[{i}].{n}");
        let limits = match j.limits.as_deref() {
            Some(l) if l.len() != 2 => {
                return Err(self.err(
                    f("limits"),
                    format!(
                        "limits has {} values; a joint's limits are two, [lower, upper]",
                        l.len()
                    ),
                    "write limits = [lower, upper] (rad for a revolute joint, m for a prismatic \
                     one)",
                ));
            }
            Some(&[a, b]) => {
                if !matches!(j.kind, RawJointKind::Revolute | RawJointKind::Prismatic) {
                    return Err(self.err(
                        f("limits"),
                        "only revolute and prismatic joints have limits",
                        "remove limits",
                    ));
                }
                let (a, b) = (self.finite(&f("limits"), a)?, self.finite(&f("limits"), b)?);
                if a > b {
                    return Err(self.err(
                        f("limits"),
                        format!("limits = [{a}, {b}]: the lower limit is above the upper"),
                        "write limits = [lower, upper]",
                    ));
                }
                Some([a, b])
            }
            _ => None,
        };
        Ok(limits)
    }

    fn body_ref(&self, field: &str, r: &RawBodyRef, bodies: &[RigidBodySpec]) -> R<usize> {
        let names = || {
            bodies
                .iter()
                .enumerate()
                .map(|(i, b)| format!("{i} or \"{}\"", b.name))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let hint = || {
            if bodies.is_empty() {
                "add the [[rigid_body]] tables the joint holds".to_string()
            } else {
                format!("name a rigid body: {}", names())
            }
        };
        match r {
            RawBodyRef::Index(k) => usize::try_from(*k)
                .ok()
                .filter(|&k| k < bodies.len())
                .ok_or_else(|| {
                    self.err(
                        field,
                        format!(
                            "there is no rigid_body[{k}] ({} in the scene)",
                            bodies.len()
                        ),
                        hint(),
                    )
                }),
            RawBodyRef::Name(n) => bodies
                .iter()
                .position(|b| &b.name == n)
                .ok_or_else(|| self.err(field, format!("no rigid body is named \"{n}\""), hint())),
        }
    }
}
