//! The `[batch]` table: its worlds' count and sweeps, and their expansion into world tables.

use super::path::{self, Seg, Target};
use toml::{Table, Value};

/// Most worlds a batch may hold: far more than one GPU holds at useful sizes; the memory of
/// the worlds is what refuses a batch long before (see [`BatchScene::budget`]).
pub const MAX_WORLDS: usize = 1 << 16;

/// Most bytes of scene text all the worlds' scenes may add up to (the file's size times the
/// count), so that a small file cannot ask for millions of copies of itself.
pub const MAX_BATCH_TEXT_BYTES: usize = 256 << 20;

/// Largest whole number a sweep writes into an integer field: every whole number up to it is
/// exact in the f64 the sweep's values are (2^53 is about 9.007e15).
const MAX_EXACT_INTEGER: f64 = 9.0e15;

/// The scene's gravity when the file gives none (m/s^2), written into the worlds' tables so that
/// its components can be swept.
const DEFAULT_GRAVITY: [f64; 3] = [0.0, -9.81, 0.0];

/// `[batch]`: how many worlds, and what differs between them.
#[derive(Clone, Debug, PartialEq)]
pub struct Batch {
    /// Worlds (at least 1, at most [`MAX_WORLDS`]).
    pub count: usize,
    /// The swept values, in the order of the file.
    pub sweeps: Vec<Sweep>,
}

/// One field swept over the worlds.
#[derive(Clone, Debug, PartialEq)]
pub struct Sweep {
    /// The field's path as written, e.g. `material[0].yield_stress`.
    pub path: String,
    pub(crate) segs: Vec<Seg>,
    /// The value of each world: one number, or the components of a vector (all of one length).
    pub values: Vec<Vec<f64>>,
    /// The values are vectors (`[x, y, z]`) rather than numbers.
    pub vector: bool,
}

/// What is wrong with a `[batch]` table: the field (`batch.count`, or a sweep's path as
/// `batch.sweep."material[0].yield_stress"`), the problem and the fix.
#[derive(Clone, Debug, PartialEq)]
pub struct BatchIssue {
    /// The sweep's path (`None`: the `[batch]` table or its `count`).
    pub sweep: Option<String>,
    /// The key inside `[batch]` (`count`, `sweep`), when the problem is not a sweep's.
    pub key: Option<&'static str>,
    pub message: String,
    pub hint: String,
}

impl BatchIssue {
    pub(crate) fn of_key(key: &'static str, message: String, hint: &str) -> BatchIssue {
        BatchIssue {
            sweep: None,
            key: Some(key),
            message,
            hint: hint.into(),
        }
    }

    fn of_sweep(path: &str, message: String, hint: &str) -> BatchIssue {
        BatchIssue {
            sweep: Some(path.to_string()),
            key: None,
            message,
            hint: hint.into(),
        }
    }

    /// The field the issue is about, as an error message names it.
    pub fn field(&self) -> String {
        match (&self.sweep, self.key) {
            (Some(p), _) => format!("batch.sweep.\"{p}\""),
            (None, Some(k)) => format!("batch.{k}"),
            (None, None) => "batch".into(),
        }
    }
}

const SWEEP_HINT: &str = "give one number per world (`\"material[0].yield_stress\" = [50, 100, \
                          ...]`) or a range (`{ from = 50, to = 500 }`, optionally `spacing = \
                          \"log\"`)";

impl Batch {
    /// Read `[batch]` (`raw`, the value of the file's `batch` key). Refuses a count that is not
    /// a whole number from 1 to [`MAX_WORLDS`] before anything is expanded.
    pub fn parse(raw: &Value) -> Result<Batch, BatchIssue> {
        let Some(table) = raw.as_table() else {
            return Err(BatchIssue {
                sweep: None,
                key: None,
                message: "`batch` must be a table".into(),
                hint: "write `[batch]` with `count = N` under it".into(),
            });
        };
        for key in table.keys() {
            if key != "count" && key != "sweep" {
                return Err(BatchIssue {
                    sweep: None,
                    key: None,
                    message: format!("unknown field `{key}` in [batch]"),
                    hint: "[batch] holds `count` and the table `[batch.sweep]` \
                           (docs/scene-format.md)"
                        .into(),
                });
            }
        }
        let count = count(table.get("count"))?;
        let sweeps: Vec<Sweep> = match table.get("sweep") {
            None => Vec::new(),
            Some(Value::Table(t)) => t
                .iter()
                .map(|(path, spec)| Sweep::parse(path, spec, count))
                .collect::<Result<_, _>>()?,
            Some(_) => {
                return Err(BatchIssue::of_key(
                    "sweep",
                    "`batch.sweep` must be a table of field paths".into(),
                    "write `[batch.sweep]` and under it `\"material[0].yield_stress\" = { from \
                     = 50, to = 500 }`",
                ));
            }
        };
        refuse_overlaps(&sweeps)?;
        Ok(Batch { count, sweeps })
    }

    /// The scene table of every world: `base` (the file's table) with each sweep's value of that
    /// world written at its path, and without `[batch]`. Refuses a sweep of a field the file
    /// cannot hold (its table or list does not exist) or of one that is not numeric.
    pub fn expand(&self, base: &Table) -> Result<Vec<Table>, BatchIssue> {
        let mut template = base.clone();
        template.remove("batch");
        // Fields the file may leave out whose components can be swept: their defaults.
        template
            .entry("gravity")
            .or_insert_with(|| Value::Array(DEFAULT_GRAVITY.map(Value::Float).to_vec()));
        let kinds = self
            .sweeps
            .iter()
            .map(|s| s.target_kind(&template))
            .collect::<Result<Vec<_>, _>>()?;
        (0..self.count)
            .map(|w| {
                let mut t = template.clone();
                for (s, kind) in self.sweeps.iter().zip(&kinds) {
                    path::set(&mut t, &s.segs, s.value_of(w, *kind))
                        .map_err(|m| BatchIssue::of_sweep(&s.path, m, SWEEP_HINT))?;
                }
                Ok(t)
            })
            .collect()
    }

    /// What sets world `w` apart, e.g. `material[0].yield_stress = 150`; `world w` when nothing
    /// is swept.
    pub fn label(&self, w: usize) -> String {
        if self.sweeps.is_empty() {
            return format!("world {w}");
        }
        self.sweeps
            .iter()
            .map(|s| format!("{} = {}", s.path, s.format_value(w)))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// Two sweeps of which one sets a part of the other (`gravity` and `gravity[1]`, or the same
/// field written twice): the later would silently replace the earlier's values.
fn refuse_overlaps(sweeps: &[Sweep]) -> Result<(), BatchIssue> {
    for (i, a) in sweeps.iter().enumerate() {
        for b in &sweeps[i + 1..] {
            let n = a.segs.len().min(b.segs.len());
            if a.segs[..n] == b.segs[..n] {
                return Err(BatchIssue::of_sweep(
                    &b.path,
                    format!(
                        "it sets the same field as the sweep \"{}\": one would replace the \
                         other's values",
                        a.path
                    ),
                    "sweep each field once: either the whole vector or its components",
                ));
            }
        }
    }
    Ok(())
}

/// Fields a batch's worlds share, because the worlds advance frame by frame together: the
/// frame rate and the duration (the number of frames) are the file's.
const SHARED_FIELDS: [&str; 2] = ["fps", "duration"];

fn count(raw: Option<&Value>) -> Result<usize, BatchIssue> {
    const FIX: &str = "give the number of worlds, a whole number from 1, e.g. `count = 16`";
    let n = match raw {
        None => {
            return Err(BatchIssue::of_key(
                "count",
                "[batch] needs `count`, the number of worlds".into(),
                FIX,
            ));
        }
        Some(Value::Integer(n)) => *n,
        Some(other) => {
            return Err(BatchIssue::of_key(
                "count",
                format!("`count` must be a whole number, got {other}"),
                FIX,
            ));
        }
    };
    if n < 1 {
        return Err(BatchIssue::of_key(
            "count",
            format!("`count` = {n}: a batch has at least one world"),
            FIX,
        ));
    }
    if n as u64 > MAX_WORLDS as u64 {
        return Err(BatchIssue::of_key(
            "count",
            format!("`count` = {n} is more than the {MAX_WORLDS} worlds a batch may hold"),
            "use fewer worlds, or run the batch as several files",
        ));
    }
    Ok(n as usize)
}

/// How a swept value is written into the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    /// The file has an integer there: whole values only.
    Integer,
    /// The file has a float there (or an integer it means as one).
    Float,
    /// The file leaves the field out: whole values as integers (read as floats where a float is
    /// meant), others as floats.
    Absent,
}

impl Sweep {
    fn parse(path: &str, spec: &Value, count: usize) -> Result<Sweep, BatchIssue> {
        let segs = path::parse(path).map_err(|m| {
            BatchIssue::of_sweep(
                path,
                format!("the path is not a field path: {m}"),
                "write the field as the error messages name it, e.g. \
                 \"material[0].yield_stress\", \"gravity[1]\", \"time.damping\"",
            )
        })?;
        if matches!(segs.first(), Some(Seg::Key(k)) if k == "batch") {
            return Err(BatchIssue::of_sweep(
                path,
                "[batch] itself cannot be swept".into(),
                "sweep a field of the scene",
            ));
        }
        if let [Seg::Key(t), Seg::Key(f), ..] = segs.as_slice()
            && t == "time"
            && SHARED_FIELDS.contains(&f.as_str())
        {
            return Err(BatchIssue::of_sweep(
                path,
                format!(
                    "`time.{f}` is the same in every world: the worlds of a batch advance frame \
                     by frame together, so they share the frame rate and the number of frames"
                ),
                "set time.fps and time.duration once in the file (the time step fields, \
                 time.max_dt, time.cfl, time.dt, can be swept), or write one scene file per value",
            ));
        }
        let values = match spec {
            Value::Array(list) => list_values(path, list, count)?,
            Value::Table(range) => range_values(path, range, count)?,
            other => {
                return Err(BatchIssue::of_sweep(
                    path,
                    format!("a sweep is a list or a range, got {other}"),
                    SWEEP_HINT,
                ));
            }
        };
        let vector = values.first().is_some_and(|v| v.len() != 1)
            || matches!(spec, Value::Array(l) if l.first().is_some_and(Value::is_array))
            || matches!(spec, Value::Table(t) if t.get("from").is_some_and(Value::is_array));
        Ok(Sweep {
            path: path.to_string(),
            segs,
            values,
            vector,
        })
    }

    /// How the file holds the swept field; refuses one it cannot hold or that is not numeric.
    fn target_kind(&self, base: &Table) -> Result<Kind, BatchIssue> {
        let fix_path = "sweep a field the scene has: the path as error messages and \
                        docs/scene-format.md name it, with indices from 0";
        match path::lookup(base, &self.segs) {
            Target::Missing(why) => Err(BatchIssue::of_sweep(
                &self.path,
                format!("unknown field: {why}"),
                fix_path,
            )),
            Target::Absent => Ok(Kind::Absent),
            Target::Found(v) => self.kind_of(v),
        }
    }

    fn kind_of(&self, v: &Value) -> Result<Kind, BatchIssue> {
        let not_numeric = |what: String| {
            BatchIssue::of_sweep(
                &self.path,
                format!("only numbers can be swept, and this field holds {what}"),
                "sweep a numeric field (a number, or a vector of numbers such as `gravity`); \
                 a material's type or a shape cannot be swept: write one scene file per choice",
            )
        };
        match v {
            Value::Integer(_) | Value::Float(_) if self.vector => Err(BatchIssue::of_sweep(
                &self.path,
                format!("the field is a number ({v}) and the sweep gives vectors"),
                "give one number per world",
            )),
            Value::Integer(_) => {
                if let Some((w, x)) = self.first_fraction() {
                    return Err(BatchIssue::of_sweep(
                        &self.path,
                        format!("the field is a whole number and world {w} would get {x}"),
                        "give whole numbers (a range whose step is whole, or a list)",
                    ));
                }
                if let Some((w, x)) = self.first_beyond(MAX_EXACT_INTEGER) {
                    return Err(BatchIssue::of_sweep(
                        &self.path,
                        format!(
                            "the field is a whole number and world {w} would get {x:e}, beyond \
                             the {MAX_EXACT_INTEGER:e} up to which a sweep holds whole numbers \
                             exactly"
                        ),
                        "give whole numbers within +-9.0e15",
                    ));
                }
                Ok(Kind::Integer)
            }
            Value::Float(_) => Ok(Kind::Float),
            Value::Array(a) if a.iter().all(|x| x.is_integer() || x.is_float()) => {
                if !self.vector {
                    return Err(BatchIssue::of_sweep(
                        &self.path,
                        format!(
                            "the field is a vector of {} numbers and the sweep gives one number \
                             per world",
                            a.len()
                        ),
                        "sweep one component (`\"gravity[1]\"`) or give a vector per world",
                    ));
                }
                let n = self.values[0].len();
                if n != a.len() {
                    return Err(BatchIssue::of_sweep(
                        &self.path,
                        format!(
                            "the field is a vector of {} numbers and the sweep's are of {n}",
                            a.len()
                        ),
                        "give vectors of the field's length",
                    ));
                }
                Ok(Kind::Float)
            }
            Value::String(s) => Err(not_numeric(format!("the text \"{s}\""))),
            Value::Boolean(b) => Err(not_numeric(format!("the boolean {b}"))),
            Value::Table(_) => Err(not_numeric("a table".into())),
            Value::Array(_) => Err(not_numeric("a list that is not of numbers".into())),
            Value::Datetime(_) => Err(not_numeric("a date".into())),
        }
    }

    fn first_beyond(&self, max: f64) -> Option<(usize, f64)> {
        self.values
            .iter()
            .enumerate()
            .find_map(|(w, v)| v.iter().find(|x| x.abs() > max).map(|&x| (w, x)))
    }

    fn first_fraction(&self) -> Option<(usize, f64)> {
        self.values
            .iter()
            .enumerate()
            .find_map(|(w, v)| v.iter().find(|x| x.fract() != 0.0).map(|&x| (w, x)))
    }

    /// World `w`'s value as the scene table holds it.
    fn value_of(&self, w: usize, kind: Kind) -> Value {
        let number = |x: f64| {
            let whole = x.fract() == 0.0 && x.abs() <= MAX_EXACT_INTEGER;
            match kind {
                Kind::Integer => Value::Integer(x as i64),
                Kind::Absent if whole => Value::Integer(x as i64),
                _ => Value::Float(x),
            }
        };
        let v = &self.values[w];
        if self.vector {
            Value::Array(v.iter().map(|&x| number(x)).collect())
        } else {
            number(v[0])
        }
    }

    /// World `w`'s value as written in labels, to 4 significant digits: `150`, `32.99`,
    /// `[0, -1.62, 0]`.
    pub fn format_value(&self, w: usize) -> String {
        let v = &self.values[w];
        // Through f32 for short decimals (0.3, not 0.30000000000000004); very large or small
        // magnitudes in exponent form (1e30, 1e-12); beyond f32's range (a value the scene
        // then refuses) the value as given, never `inf`.
        let f = |x: &f64| {
            let r = significant(*x, 4);
            let a = r.abs();
            if a > f32::MAX as f64 {
                format!("{x:e}")
            } else if a == 0.0 || (1e-4..1e7).contains(&a) {
                format!("{}", r as f32)
            } else {
                format!("{:e}", r as f32)
            }
        };
        if self.vector {
            format!("[{}]", v.iter().map(f).collect::<Vec<_>>().join(", "))
        } else {
            f(&v[0])
        }
    }
}

/// `x` rounded to `digits` significant digits.
fn significant(x: f64, digits: i32) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let scale = 10f64.powi(digits - 1 - x.abs().log10().floor() as i32);
    (x * scale).round() / scale
}

/// A number of a sweep, finite.
fn number(path: &str, v: &Value, what: &str) -> Result<f64, BatchIssue> {
    let x = match v {
        Value::Integer(i) => *i as f64,
        Value::Float(f) => *f,
        other => {
            return Err(BatchIssue::of_sweep(
                path,
                format!("{what} must be a number, got {other}"),
                SWEEP_HINT,
            ));
        }
    };
    if !x.is_finite() {
        return Err(BatchIssue::of_sweep(
            path,
            format!("{what} must be finite, got {x}"),
            "give finite numbers",
        ));
    }
    Ok(x)
}

/// A number or a vector of numbers.
fn numbers(path: &str, v: &Value, what: &str) -> Result<Vec<f64>, BatchIssue> {
    match v {
        Value::Array(a) if a.is_empty() => Err(BatchIssue::of_sweep(
            path,
            format!("{what} is an empty list"),
            SWEEP_HINT,
        )),
        Value::Array(a) => a
            .iter()
            .enumerate()
            .map(|(i, x)| number(path, x, &format!("{what}[{i}]")))
            .collect(),
        v => Ok(vec![number(path, v, what)?]),
    }
}

/// `[v0, v1, ...]`: one value per world.
fn list_values(path: &str, list: &[Value], count: usize) -> Result<Vec<Vec<f64>>, BatchIssue> {
    if list.len() != count {
        return Err(BatchIssue::of_sweep(
            path,
            format!(
                "the list has {} values and the batch {count} worlds",
                list.len()
            ),
            "give exactly one value per world (batch.count), or a range `{ from = .., to = .. }`",
        ));
    }
    let values = list
        .iter()
        .enumerate()
        .map(|(w, v)| numbers(path, v, &format!("the value of world {w}")))
        .collect::<Result<Vec<_>, _>>()?;
    same_widths(path, &values)?;
    Ok(values)
}

fn same_widths(path: &str, values: &[Vec<f64>]) -> Result<(), BatchIssue> {
    let n = values.first().map_or(1, Vec::len);
    if let Some(w) = values.iter().position(|v| v.len() != n) {
        return Err(BatchIssue::of_sweep(
            path,
            format!(
                "world 0's value has {n} components and world {w}'s {}",
                values[w].len()
            ),
            "give every world a value of the same shape",
        ));
    }
    Ok(())
}

/// `{ from = a, to = b, spacing = "linear" | "log" }`: world `w` of `n` at `w / (n - 1)` of the
/// way (evenly, or evenly in the logarithm); the ends exact.
fn range_values(path: &str, range: &Table, count: usize) -> Result<Vec<Vec<f64>>, BatchIssue> {
    for key in range.keys() {
        if !matches!(key.as_str(), "from" | "to" | "spacing") {
            return Err(BatchIssue::of_sweep(
                path,
                format!("unknown field `{key}` in the range"),
                "a range is `{ from = a, to = b }`, optionally with `spacing = \"log\"`",
            ));
        }
    }
    let get = |k: &str| {
        range.get(k).ok_or_else(|| {
            BatchIssue::of_sweep(path, format!("the range has no `{k}`"), SWEEP_HINT)
        })
    };
    let from = numbers(path, get("from")?, "`from`")?;
    let to = numbers(path, get("to")?, "`to`")?;
    if from.len() != to.len() {
        return Err(BatchIssue::of_sweep(
            path,
            format!("`from` has {} components and `to` {}", from.len(), to.len()),
            "give `from` and `to` of the same shape",
        ));
    }
    let log = match range.get("spacing") {
        None => false,
        Some(Value::String(s)) if s == "linear" => false,
        Some(Value::String(s)) if s == "log" => true,
        Some(other) => {
            return Err(BatchIssue::of_sweep(
                path,
                format!("`spacing` must be \"linear\" or \"log\", got {other}"),
                "write `spacing = \"linear\"` (the default) or `spacing = \"log\"`",
            ));
        }
    };
    if log && from.iter().chain(&to).any(|&x| x <= 0.0) {
        return Err(BatchIssue::of_sweep(
            path,
            "a log range needs `from` and `to` above 0".into(),
            "give positive ends, or `spacing = \"linear\"`",
        ));
    }
    Ok((0..count)
        .map(|w| {
            from.iter()
                .zip(&to)
                .map(|(&a, &b)| interpolate(a, b, w, count, log))
                .collect()
        })
        .collect())
}

fn interpolate(a: f64, b: f64, w: usize, n: usize, log: bool) -> f64 {
    if w == 0 || n == 1 {
        return a;
    }
    if w + 1 == n {
        return b;
    }
    let s = w as f64 / (n - 1) as f64;
    if log {
        a * (b / a).powf(s)
    } else {
        a + (b - a) * s
    }
}
