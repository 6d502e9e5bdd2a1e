//! Validation: raw serde structs -> [`Scene`], with field paths, positions and hints.

use super::schema::*;
use super::spans::{is_table, line_col, path_at, path_by_text, span_in_doc};
use super::{Damping, Scene, SceneError, StepMode, TimeSettings, sampling};
use rtmpm_physics::material::table::backticked;
use rtmpm_physics::material::{Material, MaterialParams};
use rtmpm_physics::math::Vec3;
use std::path::{Path, PathBuf};

type R<T> = Result<T, SceneError>;

#[path = "validate_emitter.rs"]
mod emitters;
#[path = "validate_io.rs"]
mod io_fields;
#[path = "validate_joint.rs"]
mod joints;
#[path = "validate_motion.rs"]
mod motion;
#[path = "validate_rigid.rs"]
mod rigid;
#[path = "validate_settings.rs"]
mod settings;
#[path = "validate_shapes.rs"]
mod shapes;

/// Grid cells of margin around a mesh's signed distance grid.
pub(super) const MESH_MARGIN: u32 = 3;

struct V<'a> {
    text: &'a str,
    origin: &'a str,
    doc: Option<toml_edit::Document<&'a str>>,
}

/// Convert a toml parse/deserialize error into a positioned [`SceneError`].
fn toml_error(text: &str, origin: &str, e: &toml::de::Error) -> SceneError {
    let message = e.message().trim().to_string();
    let offset = e.span().map(|s| s.start);
    let (line, column) = match offset {
        Some(o) => {
            let (l, c) = line_col(text, o);
            (Some(l), Some(c))
        }
        None => (None, None),
    };
    let doc = toml_edit::Document::parse(text).ok();
    let at = match (&doc, offset) {
        (Some(d), Some(o)) => path_at(d, o),
        (None, Some(o)) => path_by_text(text, o),
        _ => None,
    };
    let (field, hint) = if let Some(name) = backticked(&message, "unknown field ") {
        let field = match &at {
            Some(p) if p.ends_with(name) => p.clone(),
            Some(p) => format!("{p}.{name}"),
            None => name.to_string(),
        };
        (
            Some(field),
            "remove the field or fix its spelling (the fields are listed in docs/scene-format.md)"
                .to_string(),
        )
    } else if let Some(name) = backticked(&message, "missing field ") {
        // The error points into the table that lacks the field: name that table (the root
        // when the position is on a plain key such as `name`).
        let mut table = at.clone().unwrap_or_default();
        if let Some(d) = &doc {
            while !table.is_empty() && !is_table(d, &table) {
                table = match table.rfind(['.', '[']) {
                    Some(i) => table[..i].to_string(),
                    None => String::new(),
                };
            }
        }
        let (field, hint) = if table.is_empty() {
            (
                name.to_string(),
                format!("add the [{name}] table or `{name} = ...` (see docs/scene-format.md)"),
            )
        } else {
            (
                format!("{table}.{name}"),
                "add the field; it has no default".to_string(),
            )
        };
        (Some(field), hint)
    } else if message.contains("unknown variant") {
        (at, "use one of the listed values".to_string())
    } else if let Some(ty) = integer_out_of_range(&message) {
        (at, ty)
    } else if doc.is_none() {
        (at, "fix the TOML syntax at this position".to_string())
    } else {
        (
            at,
            "check the value's type: numbers without quotes, names in quotes, vectors as [x, y, z]"
                .to_string(),
        )
    };
    SceneError {
        origin: origin.to_string(),
        line,
        column,
        field,
        message,
        hint: Some(hint),
    }
}

/// The fix for an integer too large (or negative) for its field, from serde's message
/// (`invalid value: integer `-1`, expected u32`, `... as i128, expected u64`).
fn integer_out_of_range(message: &str) -> Option<String> {
    if !message.contains("integer") {
        return None;
    }
    let ty = message.rsplit("expected ").next()?.trim();
    let range = match ty {
        "u32" => format!("0 to {}", u32::MAX),
        "u64" => format!("0 to {}", u64::MAX),
        "i64" => format!("{} to {}", i64::MIN, i64::MAX),
        _ => return None,
    };
    Some(format!(
        "the number is out of range for this field: use a whole number from {range}"
    ))
}

/// Parse and validate scene text.
pub(super) fn parse(text: &str, origin: &str, base: &Path, stem: Option<&str>) -> R<Scene> {
    let raw: RawScene = toml::from_str(text).map_err(|e| toml_error(text, origin, &e))?;
    let v = V {
        text,
        origin,
        doc: toml_edit::Document::parse(text).ok(),
    };
    v.resolve(raw, base, stem)
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

fn fmt3(v: Vec3) -> String {
    format!("[{}, {}, {}]", v.x, v.y, v.z)
}

impl V<'_> {
    fn err(
        &self,
        field: impl Into<String>,
        message: impl Into<String>,
        hint: impl Into<String>,
    ) -> SceneError {
        let field = field.into();
        let pos = self
            .doc
            .as_ref()
            .and_then(|d| span_in_doc(d, &field))
            .map(|o| line_col(self.text, o));
        SceneError {
            origin: self.origin.to_string(),
            line: pos.map(|p| p.0),
            column: pos.map(|p| p.1),
            field: Some(field),
            message: message.into(),
            hint: Some(hint.into()),
        }
    }

    fn finite(&self, field: &str, x: f32) -> R<f32> {
        if x.is_finite() {
            Ok(x)
        } else {
            Err(self.err(
                field,
                format!("{x} is not a finite number"),
                "write a finite number",
            ))
        }
    }

    fn positive(&self, field: &str, x: f32, what: &str) -> R<f32> {
        self.finite(field, x)?;
        if x > 0.0 {
            Ok(x)
        } else {
            Err(self.err(
                field,
                format!("{what} must be > 0, got {x}"),
                format!("give a positive {what}"),
            ))
        }
    }

    fn non_negative(&self, field: &str, x: f32, what: &str) -> R<f32> {
        self.finite(field, x)?;
        if x >= 0.0 {
            Ok(x)
        } else {
            Err(self.err(
                field,
                format!("{what} must be >= 0, got {x}"),
                format!("use 0 or a positive {what}"),
            ))
        }
    }

    fn vec3(&self, field: &str, v: V3) -> R<Vec3> {
        let x = Vec3::from_array(v);
        if x.is_finite() {
            Ok(x)
        } else {
            Err(self.err(
                field,
                format!("{} has a non-finite component", fmt3(x)),
                "write finite numbers",
            ))
        }
    }

    fn unit(&self, field: &str, v: V3, what: &str) -> R<Vec3> {
        let x = self.vec3(field, v)?;
        x.try_normalize()
            .filter(|_| x.length() > 1e-12)
            .ok_or_else(|| {
                self.err(
                    field,
                    format!("the {what} {} has zero length", fmt3(x)),
                    format!("give a nonzero {what}, e.g. [0, 1, 0]"),
                )
            })
    }

    fn resolve(&self, raw: RawScene, base: &Path, stem: Option<&str>) -> R<Scene> {
        let name = raw
            .name
            .clone()
            .or_else(|| stem.map(str::to_string))
            .unwrap_or_else(|| "scene".into());
        self.file_name_ok(&name, raw.name.is_some())?;
        // Domain.
        let dx = self.positive("domain.dx", raw.domain.dx, "the grid spacing dx")?;
        let dmin = self.vec3("domain.min", raw.domain.min)?;
        let dmax = self.vec3("domain.max", raw.domain.max)?;
        for a in 0..3 {
            if dmax[a] <= dmin[a] {
                return Err(self.err(
                    format!("domain.max[{a}]"),
                    format!(
                        "domain max {} is not above min {} along axis {a}",
                        fmt3(dmax),
                        fmt3(dmin)
                    ),
                    "make every component of max larger than that of min",
                ));
            }
        }
        let cells = (dmax - dmin) / dx;
        for a in 0..3 {
            let n = cells[a];
            if n.round() < 1.0 {
                return Err(self.err(
                    "domain.dx",
                    format!(
                        "dx = {dx} is larger than the domain along axis {a} ({} m)",
                        dmax[a] - dmin[a]
                    ),
                    "use a dx that divides the domain into cells (e.g. a 64th of its size)",
                ));
            }
            if (n - n.round()).abs() > 1e-3 * n.max(1.0) {
                let fixed = dmin[a] + n.round().max(1.0) * dx;
                return Err(self.err(
                    format!("domain.max[{a}]"),
                    format!("the domain is {n} cells long along axis {a}, not a whole number of cells of dx = {dx}"),
                    format!("set domain.max[{a}] = {fixed} (a whole number of cells) or change dx"),
                ));
            }
            if n.round() > 4096.0 {
                return Err(self.err(
                    "domain.dx",
                    format!("{} cells along axis {a} is too many", n.round()),
                    "use a larger dx (at most 4096 cells per axis)",
                ));
            }
        }
        let gravity = match raw.gravity {
            Some(g) => self.vec3("gravity", g)?,
            None => Vec3::new(0.0, -9.81, 0.0),
        };

        // Time.
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
                let sound = materials_sound_speed(&raw, self);
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

        // Walls.
        let walls = self.walls(raw.walls.as_ref(), cells)?;

        // Materials.
        let mut materials: Vec<Material> = Vec::new();
        for (i, m) in raw.material.iter().enumerate() {
            let mat = self.material(i, m)?;
            if materials.iter().any(|o| o.name == mat.name) {
                return Err(self.err(
                    format!("material[{i}].name"),
                    format!("material name {:?} is used twice", mat.name),
                    "give every material a unique name",
                ));
            }
            materials.push(mat);
        }

        // Bodies.
        let thick = walls.thickness as f32 * dx;
        let (imin, imax) = (dmin + thick, dmax - thick);
        let mut bodies = Vec::new();
        for (i, b) in raw.body.iter().enumerate() {
            bodies.push(self.body(i, b, &materials, base, dx, (imin, imax))?);
        }

        // Colliders.
        let mut colliders = Vec::new();
        for (i, c) in raw.collider.iter().enumerate() {
            colliders.push(self.collider(i, c, base, dx)?);
        }

        // Emitters (validate_emitter.rs).
        let seed = raw.seed.unwrap_or(0);
        let cx = emitters::EmitterContext {
            materials: &materials,
            base,
            dx,
            interior: (imin, imax),
            duration,
            seed,
        };
        let emitters = raw
            .emitter
            .iter()
            .enumerate()
            .map(|(i, e)| self.emitter(i, e, &cx))
            .collect::<R<Vec<_>>>()?;

        // Rigid bodies (validate_rigid.rs).
        let rigid_bodies = raw
            .rigid_body
            .iter()
            .enumerate()
            .map(|(i, b)| self.rigid_body(i, b, base, dx, (imin, imax)))
            .collect::<R<Vec<_>>>()?;
        let joints = raw
            .joint
            .iter()
            .enumerate()
            .map(|(i, j)| self.joint(i, j, &rigid_bodies, (dmin, dmax)))
            .collect::<R<Vec<_>>>()?;
        self.rigid_overlaps(&rigid_bodies, &joints)?;

        // Output and surfaces (validate_io.rs).
        let output = self.output(
            raw.output.as_ref(),
            raw.surface.as_ref(),
            &materials,
            PathBuf::from("out").join(&name),
        )?;

        let render = self.render(raw.render.as_ref())?;
        let solver = self.solver(raw.solver.as_ref())?;

        let scene = Scene {
            name,
            source: None,
            domain_min: dmin,
            domain_max: dmax,
            dx,
            gravity,
            time,
            materials,
            bodies,
            colliders,
            emitters,
            rigid_bodies,
            joints,
            walls,
            output,
            render,
            seed,
            solver,
            precision: raw
                .solver
                .as_ref()
                .and_then(|s| s.precision)
                .unwrap_or_default(),
            particle_state: raw
                .solver
                .as_ref()
                .and_then(|s| s.particle_state)
                .unwrap_or_default(),
        };
        if scene.particle_state == super::ParticleState::Compact
            && scene.precision == super::Precision::F64
        {
            return Err(self.err(
                "solver.particle_state",
                "particle_state = \"compact\" is single precision only (it stores the velocity \
                 and C in 32-bit shared-exponent words)",
                "remove particle_state, or use precision = \"f32\"",
            ));
        }
        // Every body must produce particles (found without storing them: the first one is
        // enough; the size of the whole scene is checked by the budget, scene::budget).
        for i in 0..scene.bodies.len() {
            let empty = sampling::body_is_empty(&scene, i).map_err(|e| {
                self.err(format!("body[{i}]"), e.message, e.hint.unwrap_or_default())
            })?;
            if empty {
                return Err(self.err(
                    format!("body[{i}]"),
                    "the body produces 0 particles",
                    "make it larger than a particle spacing (dx / round(cbrt(particles_per_cell))) or raise particles_per_cell/count",
                ));
            }
        }
        Ok(scene)
    }

    /// The scene name names the output folder `out/<name>`: it must be one plain folder name
    /// (no `/`, `\\`, `..`, control characters, not hidden), so it cannot write outside `out/`.
    fn file_name_ok(&self, name: &str, given: bool) -> R<()> {
        let bad = if name.trim().is_empty() {
            Some("is empty")
        } else if name.contains(['/', '\\']) {
            Some("contains a path separator")
        } else if name.starts_with('.') {
            Some("starts with `.` (a hidden folder, or `..` which climbs out of out/)")
        } else if name.chars().any(char::is_control) {
            Some("contains control characters")
        } else if name.len() > 200 {
            Some("is longer than 200 bytes")
        } else {
            None
        };
        match bad {
            None => Ok(()),
            Some(why) => Err(self.err(
                if given { "name" } else { "<file name>" },
                format!("the scene name {name:?} {why}; it names the output folder out/<name>"),
                "use letters, digits, `-` and `_` (e.g. name = \"dam_break\"); choose the folder with [output] dir",
            )),
        }
    }

    fn material(&self, i: usize, m: &RawMaterial) -> R<Material> {
        let p = |f: &str| format!("material[{i}].{f}");
        if m.name.trim().is_empty() {
            return Err(self.err(
                p("name"),
                "the material name is empty",
                "give the material a name, e.g. name = \"water\"",
            ));
        }
        let density = self.positive(&p("density"), m.density, "density (kg/m^3)")?;
        let params = MaterialParams {
            kind: m.kind.clone(),
            fields: m.fields.clone(),
        };
        // The model checks its own fields (material/<model>.rs).
        Material::new(&m.name, density, params).map_err(|e| {
            let field = if e.field.is_empty() {
                "type"
            } else {
                e.field.as_str()
            };
            self.err(p(field), e.message, e.hint)
        })
    }
}
