//! The validator ([`V`]): the scene text and its document, the error of a field with its
//! position and hint, and the checks of single values every part of the validation uses.

use crate::error::SceneError;
use crate::schema::*;
use crate::spans::{is_table, line_col, numbers_at, path_at, path_by_text, span_in_doc};
use rtmpm_physics::material::table::backticked;
use rtmpm_physics::material::{Material, MaterialParams};
use rtmpm_physics::math::Vec3;
use std::path::Path;

pub(super) type R<T> = Result<T, SceneError>;

pub(super) struct V<'a> {
    pub(super) text: &'a str,
    pub(super) origin: &'a str,
    pub(super) doc: Option<toml_edit::Document<&'a str>>,
    /// Parsing a checkpoint's scene: a body's file may be gone.
    pub(super) resumed: bool,
    /// The files read so far, with their hashes.
    pub(super) files: std::cell::RefCell<Vec<crate::files::SceneFile>>,
}

/// The shapes each table of shapes allows.
const TABLE_SHAPES: [(&str, &[&str]); 4] = [
    ("body", &["box", "sphere", "cylinder", "mesh", "particles"]),
    (
        "collider",
        &["half_space", "box", "sphere", "cylinder", "mesh"],
    ),
    ("emitter", &["box", "sphere", "cylinder"]),
    ("rigid_body", &["box", "sphere", "cylinder", "mesh"]),
];

/// For the unknown field `field` (e.g. `rigid_body[0].normal`) of a `[[body]]`, `[[collider]]`,
/// `[[emitter]]` or `[[rigid_body]]` table whose `shape` that table does not allow: the shape's
/// field, the message and the fix.
fn shape_not_allowed(
    doc: &toml_edit::Document<&str>,
    field: &str,
    name: &str,
) -> Option<(String, String, String)> {
    let (table, _) = field.rsplit_once('.')?;
    let (kind, index) = table.split_once('[')?;
    let i: usize = index.strip_suffix(']')?.parse().ok()?;
    let (_, allowed) = TABLE_SHAPES.iter().find(|(k, _)| *k == kind)?;
    let shape = doc
        .get(kind)?
        .as_array_of_tables()?
        .get(i)?
        .get("shape")?
        .as_str()?;
    if allowed.contains(&shape) {
        return None;
    }
    Some((
        format!("{table}.shape"),
        format!(
            "shape = \"{shape}\" is not allowed in [[{kind}]] (`{name}` is a field of that \
             shape)"
        ),
        format!(
            "give {table} one of the shapes of [[{kind}]]: {}",
            allowed.join(", ")
        ),
    ))
}

/// Convert a toml parse/deserialize error into a positioned [`SceneError`].
pub(super) fn toml_error(text: &str, origin: &str, e: &toml::de::Error) -> SceneError {
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
        // A field of a shape this table does not allow (a half-space rigid body, a mesh
        // emitter): the shape is the error.
        if let Some((shape_field, message, hint)) = doc
            .as_ref()
            .and_then(|d| shape_not_allowed(d, &field, name))
        {
            return SceneError {
                origin: origin.to_string(),
                line,
                column,
                field: Some(shape_field),
                message,
                hint: Some(hint),
            };
        }
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

pub(super) use rtmpm_geometry::shape::fmt3;

impl V<'_> {
    /// Record that the scene read `path` for `field` (its hash: the bytes now).
    pub(super) fn read_file(&self, field: &str, path: &Path) {
        let hash = crate::files::hash_file(path).ok();
        self.files.borrow_mut().push(crate::files::SceneFile {
            field: field.to_string(),
            path: path.to_path_buf(),
            hash,
        });
    }

    /// In a checkpoint's scene, a body's file that is gone: recorded without a hash; the
    /// caller gives the body no shape to sample.
    pub(super) fn resumed_without(&self, field: &str, path: &Path) -> bool {
        if !self.resumed || path.exists() {
            return false;
        }
        self.files.borrow_mut().push(crate::files::SceneFile {
            field: field.to_string(),
            path: path.to_path_buf(),
            hash: None,
        });
        true
    }

    /// The error of a number the text gives that a 32-bit float cannot hold: beyond about
    /// 3.4e38 (it reads as infinity) or, not zero, below about 1.4e-45 (it reads as 0). `None`
    /// when the numbers written at `field` fit.
    pub(super) fn f32_range_error(&self, field: &str) -> Option<SceneError> {
        let doc = self.doc.as_ref()?;
        let numbers = numbers_at(doc, field);
        if let Some(x) = numbers
            .iter()
            .find(|x| x.is_finite() && x.abs() > f32::MAX as f64)
        {
            return Some(self.err(
                field,
                format!(
                    "{x:e} is too large for a 32-bit float (the largest is about 3.4e38): it \
                     would read as infinity"
                ),
                "write a value within +-3.4e38; check its units (values of a scene are in SI \
                 units: m, s, kg, Pa)",
            ));
        }
        if let Some(x) = numbers
            .iter()
            .find(|x| **x != 0.0 && x.abs() < f32::from_bits(1) as f64)
        {
            return Some(self.err(
                field,
                format!(
                    "{x:e} is too small for a 32-bit float (the smallest is about 1.4e-45): it \
                     would read as 0"
                ),
                "write 0 or a value of at least 1.4e-45 in size; check its units (values of a \
                 scene are in SI units: m, s, kg, Pa)",
            ));
        }
        None
    }

    pub(super) fn err(
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

    pub(super) fn finite(&self, field: &str, x: f32) -> R<f32> {
        if x.is_finite() {
            Ok(x)
        } else if let Some(e) = self.f32_range_error(field) {
            Err(e)
        } else {
            Err(self.err(
                field,
                format!("{x} is not a finite number"),
                "write a finite number",
            ))
        }
    }

    pub(super) fn positive(&self, field: &str, x: f32, what: &str) -> R<f32> {
        self.finite(field, x)?;
        if x > 0.0 {
            Ok(x)
        } else if let Some(e) = self.f32_range_error(field) {
            Err(e)
        } else {
            Err(self.err(
                field,
                format!("{what} must be > 0, got {x}"),
                format!("give a positive value of {what}"),
            ))
        }
    }

    pub(super) fn non_negative(&self, field: &str, x: f32, what: &str) -> R<f32> {
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

    pub(super) fn vec3(&self, field: &str, v: V3) -> R<Vec3> {
        let x = Vec3::from_array(v);
        if x.is_finite() {
            Ok(x)
        } else if let Some(e) = self.f32_range_error(field) {
            Err(e)
        } else {
            Err(self.err(
                field,
                format!("{} has a non-finite component", fmt3(x)),
                "write finite numbers",
            ))
        }
    }

    pub(super) fn unit(&self, field: &str, v: V3, what: &str) -> R<Vec3> {
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

    /// The scene name names the output folder `out/<name>`: it must be one plain folder name
    /// (no `/`, `\\`, `..`, control characters, not hidden), so it cannot write outside `out/`.
    pub(super) fn file_name_ok(&self, name: &str, given: bool) -> R<()> {
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

    pub(super) fn material(&self, i: usize, m: &RawMaterial) -> R<Material> {
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
        let mat = Material::new(&m.name, density, params).map_err(|e| {
            let field = if e.field.is_empty() {
                "type"
            } else {
                e.field.as_str()
            };
            // A value beyond f32 reads as infinity (or 0) before the model sees it.
            self.f32_range_error(&p(field))
                .unwrap_or_else(|| self.err(p(field), e.message, e.hint))
        })?;
        // Stiffness over density beyond a 32-bit float: an infinite sound speed, a step of 0 s.
        if !mat.model.sound_speed(density).is_finite() {
            return Err(self.err(
                p("density"),
                format!(
                    "density {density:e} kg/m^3 is too small for the material's stiffness: its \
                     sound speed (stiffness over density) overflows a 32-bit float, so no time \
                     step can follow it"
                ),
                "give the density in kg/m^3 (water 1000, steel 7850), or a lower stiffness",
            ));
        }
        Ok(mat)
    }
}
