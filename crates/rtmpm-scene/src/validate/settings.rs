//! Validation of the scene's settings tables: `[solver]`, `[render]` and `[walls]`.

use super::core::{R, V};
use crate::ColorBy;
use crate::render_settings::RenderSettings;
use crate::schema::*;
use rtmpm_physics::boundary::{BoundaryRule, Condition, Walls};
use rtmpm_physics::math::Vec3;
use rtmpm_physics::transfer::{SolverSettings, Transfer, Update};

impl V<'_> {
    /// `[solver]`: defaults to MLS-MPM/APIC; `update` and `flip` only apply to the classic MPM
    /// transfers (gimp, mpm-linear), whose defaults are USL and pure FLIP (flip = 1).
    pub(super) fn solver(&self, s: Option<&RawSolver>) -> R<SolverSettings> {
        let Some(s) = s else {
            return Ok(SolverSettings::default());
        };
        let transfer = match s.transfer.unwrap_or(RawTransfer::Mls) {
            RawTransfer::Mls => Transfer::Mls,
            RawTransfer::Gimp => Transfer::Gimp,
            RawTransfer::MpmLinear => Transfer::MpmLinear,
            RawTransfer::CkMpm => Transfer::CkMpm,
        };
        let update = match s.update.unwrap_or(RawUpdate::Usl) {
            RawUpdate::Usl => Update::Usl,
            RawUpdate::Musl => Update::Musl,
        };
        if transfer.is_apic() {
            if update == Update::Musl {
                return Err(self.err(
                    "solver.update",
                    format!(
                        "update = \"musl\" needs a classic MPM transfer; transfer = \"{}\" (MLS-MPM) folds the stress into P2G (USL only)",
                        transfer.name()
                    ),
                    "use transfer = \"gimp\" or \"mpm-linear\" with musl, or remove update",
                ));
            }
            if s.flip.is_some() {
                return Err(self.err(
                    "solver.flip",
                    format!(
                        "flip does not apply to transfer = \"{}\" (APIC keeps the affine velocity; it has no PIC/FLIP blend)",
                        transfer.name()
                    ),
                    "remove flip, or use transfer = \"gimp\" or \"mpm-linear\"",
                ));
            }
            return Ok(SolverSettings {
                transfer,
                update,
                flip: 0.0,
            });
        }
        let flip = match s.flip {
            Some(f) => {
                self.finite("solver.flip", f)?;
                if !(0.0..=1.0).contains(&f) {
                    return Err(self.err(
                        "solver.flip",
                        format!("flip must be in [0, 1], got {f}"),
                        "use 0 for PIC, 1 for FLIP, or a blend such as 0.99",
                    ));
                }
                f
            }
            None => 1.0,
        };
        Ok(SolverSettings {
            transfer,
            update,
            flip,
        })
    }

    /// Rigid bodies are coupled in the grid update of a USL step on one grid: MUSL's second
    /// grid update and CK-MPM's two grids (each carrying the whole mass) do not couple them.
    /// Refused here, naming the solver field and the first body, rather than by the backend.
    pub(super) fn solver_couples(
        &self,
        s: &SolverSettings,
        bodies: &[rtmpm_rigid::RigidBodySpec],
    ) -> R<()> {
        let Some(first) = bodies.first() else {
            return Ok(());
        };
        let body = match bodies.len() {
            1 => format!("rigid_body[0] `{}`", first.name),
            n => format!("rigid_body[0] `{}` and {} more", first.name, n - 1),
        };
        if s.transfer == Transfer::CkMpm {
            return Err(self.err(
                "solver.transfer",
                format!(
                    "transfer = \"ck-mpm\" does not couple rigid bodies ({body}): each of \
                     CK-MPM's two grids carries the whole mass, which the coupling does not \
                     account for yet"
                ),
                "use transfer = \"mls\" (the default) with [[rigid_body]] tables, or turn the \
                 bodies into [[collider]] tables (moving obstacles, not pushed back)",
            ));
        }
        if s.update == Update::Musl {
            return Err(self.err(
                "solver.update",
                format!(
                    "update = \"musl\" does not couple rigid bodies ({body}): they are \
                     coupled in the grid update of a USL step"
                ),
                "remove update (usl, the default) with [[rigid_body]] tables",
            ));
        }
        Ok(())
    }

    pub(super) fn render(&self, r: Option<&RawRender>) -> R<RenderSettings> {
        let Some(r) = r else {
            return Ok(RenderSettings::default());
        };
        let camera = r
            .camera
            .map(|v| self.vec3("render.camera", v))
            .transpose()?;
        let target = r
            .target
            .map(|v| self.vec3("render.target", v))
            .transpose()?;
        if let (Some(c), Some(t)) = (camera, target)
            && (c - t).length() <= 1e-9
        {
            return Err(self.err(
                "render.target",
                "the camera position and target coincide",
                "move the camera away from the point it looks at",
            ));
        }
        if let Some(fov) = r.fov {
            self.finite("render.fov", fov)?;
            if !(fov > 0.0 && fov < 180.0) {
                return Err(self.err(
                    "render.fov",
                    format!("field of view must be in (0, 180) degrees, got {fov}"),
                    "use e.g. fov = 40",
                ));
            }
        }
        for (field, v) in [("render.width", r.width), ("render.height", r.height)] {
            if let Some(v) = v
                && !(16..=8192).contains(&v)
            {
                return Err(self.err(
                    field,
                    format!("image size {v} is out of range"),
                    "use 16 to 8192 pixels (default 1280x720)",
                ));
            }
        }
        let color_by = match &r.color_by {
            None => None,
            Some(c) => Some(
                c.parse::<ColorBy>()
                    .map_err(|e| self.err("render.color_by", e, "e.g. color_by = \"speed\""))?,
            ),
        };
        Ok(RenderSettings {
            camera,
            target,
            fov: r.fov,
            width: r.width,
            height: r.height,
            color_by,
        })
    }

    /// The rule of a wall, collider or rigid body that gives none: separating, so material
    /// pushes against an obstacle but can always leave it (a slip or sticky ceiling, or the
    /// underside of a slip body, would hold material that touches it from below).
    pub(super) const DEFAULT_CONDITION: RawCondition = RawCondition::Separate;

    pub(super) fn condition(c: RawCondition) -> Condition {
        match c {
            RawCondition::Sticky => Condition::Sticky,
            RawCondition::Slip => Condition::Slip,
            RawCondition::Separate => Condition::Separate,
        }
    }

    pub(super) fn walls(&self, w: Option<&RawWalls>, cells: Vec3) -> R<Walls> {
        let default = RawWalls::default();
        let w = w.unwrap_or(&default);
        let thickness = w.thickness.unwrap_or(3);
        let min_cells = cells.min_element().round() as u32;
        // Nodes 0..=thickness and cells-thickness..=cells are wall nodes: keep one free plane.
        if 2 * thickness + 2 > min_cells {
            return Err(self.err(
                "walls.thickness",
                format!(
                    "walls {thickness} cells thick leave no room in a domain {min_cells} cells wide"
                ),
                "use thinner walls or a larger domain",
            ));
        }
        let condition = Self::condition(w.condition.unwrap_or(Self::DEFAULT_CONDITION));
        let friction =
            self.non_negative("walls.friction", w.friction.unwrap_or(0.0), "friction")?;
        let rule = BoundaryRule {
            condition,
            friction,
        };
        let mut faces = [rule; 6];
        if let Some(f) = &w.faces {
            let list = [&f.x_min, &f.x_max, &f.y_min, &f.y_max, &f.z_min, &f.z_max];
            let names = ["x_min", "x_max", "y_min", "y_max", "z_min", "z_max"];
            for (k, face) in list.iter().enumerate() {
                if let Some(face) = face {
                    if let Some(c) = face.condition {
                        faces[k].condition = Self::condition(c);
                    }
                    if let Some(fr) = face.friction {
                        faces[k].friction = self.non_negative(
                            &format!("walls.faces.{}.friction", names[k]),
                            fr,
                            "friction",
                        )?;
                    }
                }
            }
        }
        Ok(Walls { thickness, faces })
    }
}
