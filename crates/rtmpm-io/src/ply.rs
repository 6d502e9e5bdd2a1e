//! Binary little-endian PLY point clouds, one vertex per particle.
//!
//! [`write_ply`] writes a `vertex` element with these properties, in this order:
//!
//! | property                          | PLY type | meaning                                   |
//! |-----------------------------------|----------|-------------------------------------------|
//! | `x y z`                           | `float`  | position (m)                              |
//! | `vx vy vz`                        | `float`  | velocity (m/s)                            |
//! | `material`                        | `int`    | material index (32-bit signed; indices are `u32` in memory and must be below 2^31) |
//! | `plastic`                         | `float`  | the material's scalar plastic state       |
//! | `J` (optional)                    | `float`  | volume ratio `det F`                      |
//! | `sxx syy szz sxy syz sxz` (opt.)  | `float`  | Cauchy stress (Pa)                        |
//!
//! `int` is used for `material` rather than `uint` because more tools (e.g. Houdini, some
//! Blender importers) handle signed integers.
//!
//! [`read_ply`] reads any `binary_little_endian 1.0` PLY file whose elements have scalar
//! properties (list properties are skipped in elements other than `vertex`) and returns the
//! `vertex` columns by name.

use std::io::{self, Write};
use std::path::Path;

use super::atomic::write_atomic_with;
use super::limits::{DATA_MAX_BYTES, read_bounded};
use crate::chunks::FrameColumns;
use crate::fields::FrameFields;
use crate::frame::{ChunkEncoder, ChunkRows, Derived, FrameBytes, FrameFormat, Records};
use rtmpm_physics::Particles;

/// PLY frames (`frame_NNNNN.ply`), the default: read by ParaView, Houdini, Blender and `rtmpm
/// render`; written whole or in chunks.
pub static FORMAT: FrameFormat = FrameFormat {
    name: "ply",
    extension: "ply",
    about: "binary PLY point cloud (ParaView, Houdini, Blender, rtmpm render)",
    bytes: FrameBytes {
        base: 32,
        jacobian: 4,
        stress: 24,
    },
    write: |path, f| write_ply_with_comments(path, f.particles, &f.fields, f.comments),
    pvd: false,
    chunks: Some(&PlyChunks),
};

/// PLY records chunk by chunk: the header of [`write_ply_with_comments`], then per particle
/// the same little-endian values.
struct PlyChunks;

impl ChunkEncoder for PlyChunks {
    fn columns(&self, _derived: Derived) -> FrameColumns {
        FrameColumns::default()
    }

    fn header(&self, n: usize, derived: Derived, comments: &[&str]) -> io::Result<Vec<u8>> {
        if let Some(c) = comments.iter().find(|c| c.contains(['\n', '\r'])) {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("PLY comment {c:?} spans several lines"),
            ));
        }
        Ok(frame_header(n, comments, derived.jacobian, derived.stress).into_bytes())
    }

    fn record_bytes(&self, d: Derived) -> usize {
        32 + 4 * (d.jacobian as usize + if d.stress { 6 } else { 0 })
    }

    fn encode(&self, r: &ChunkRows, first: usize, count: usize, out: &mut [u8]) -> io::Result<()> {
        let mut o = Records(out);
        for j in first..first + count {
            for row in r.x.iter().chain(&r.v) {
                o.put(row[j].to_le_bytes());
            }
            o.put((r.material[j] as i32).to_le_bytes());
            o.put(r.plastic[j].to_le_bytes());
            if let Some(jac) = r.jacobian {
                o.put(jac[j].to_le_bytes());
            }
            if let Some(s) = r.stress {
                for c in s[j] {
                    o.put(c.to_le_bytes());
                }
            }
        }
        Ok(())
    }
}

/// Errors of [`read_ply`].
#[derive(Debug, thiserror::Error)]
pub enum PlyError {
    /// The file could not be read.
    #[error("PLY I/O error: {0}")]
    Io(#[from] io::Error),
    /// The file is a PLY file in a format this reader does not handle (ASCII, big endian).
    #[error("unsupported PLY format `{0}`: only binary_little_endian 1.0 is read")]
    UnsupportedFormat(String),
    /// The file is not a well-formed PLY file.
    #[error("malformed PLY file: {0}")]
    Malformed(String),
}

/// One column of a PLY element, with the values widened to a common Rust type.
#[derive(Clone, Debug, PartialEq)]
pub enum PlyColumn {
    /// A `float` / `float32` property.
    Float(Vec<f32>),
    /// A `double` / `float64` property.
    Double(Vec<f64>),
    /// Any integer property (`char`, `uchar`, `short`, `ushort`, `int`, `uint` and their
    /// `int8`... aliases), widened to `i64`.
    Int(Vec<i64>),
}

impl PlyColumn {
    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            PlyColumn::Float(v) => v.len(),
            PlyColumn::Double(v) => v.len(),
            PlyColumn::Int(v) => v.len(),
        }
    }

    /// True when the column is empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The `vertex` element of a PLY file: its columns by name, in file order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlyData {
    /// Number of vertices.
    pub count: usize,
    /// `(property name, values)`, in the order of the header.
    pub columns: Vec<(String, PlyColumn)>,
    /// `comment` lines of the header (without the `comment ` prefix).
    pub comments: Vec<String>,
}

impl PlyData {
    /// The column named `name`, if any.
    pub fn column(&self, name: &str) -> Option<&PlyColumn> {
        self.columns.iter().find(|(n, _)| n == name).map(|(_, c)| c)
    }

    /// The `float` column named `name`, if it exists and has that type.
    pub fn f32(&self, name: &str) -> Option<&[f32]> {
        match self.column(name)? {
            PlyColumn::Float(v) => Some(v),
            _ => None,
        }
    }

    /// The integer column named `name`, if it exists and has an integer type.
    pub fn int(&self, name: &str) -> Option<&[i64]> {
        match self.column(name)? {
            PlyColumn::Int(v) => Some(v),
            _ => None,
        }
    }

    /// Property names, in file order.
    pub fn names(&self) -> Vec<&str> {
        self.columns.iter().map(|(n, _)| n.as_str()).collect()
    }
}

/// Write `particles` (and the optional `fields`) as a binary little-endian PLY point cloud at
/// `path`, atomically. See the module documentation for the property list.
pub fn write_ply(path: &Path, particles: &Particles, fields: &FrameFields) -> io::Result<()> {
    write_ply_with_comments(path, particles, fields, &[])
}

/// [`write_ply`] with extra `comment` lines in the header (e.g. the run a frame belongs to);
/// a comment must be one line.
pub fn write_ply_with_comments(
    path: &Path,
    particles: &Particles,
    fields: &FrameFields,
    comments: &[&str],
) -> io::Result<()> {
    crate::contents::check_particles(particles)?;
    if let Some(c) = comments.iter().find(|c| c.contains(['\n', '\r'])) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("PLY comment {c:?} spans several lines"),
        ));
    }
    let n = particles.len();
    fields.check_len(n)?;
    if let Some(m) = particles.material.iter().find(|&&m| m > i32::MAX as u32) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("material index {m} does not fit the PLY int property"),
        ));
    }

    let header = frame_header(
        n,
        comments,
        fields.jacobian.is_some(),
        fields.stress.is_some(),
    );

    write_atomic_with(path, |w| {
        w.write_all(header.as_bytes())?;
        let mut row: Vec<u8> = Vec::with_capacity(15 * 4);
        for i in 0..n {
            row.clear();
            let x = particles.x[i];
            let v = particles.v[i];
            for c in [x.x, x.y, x.z, v.x, v.y, v.z] {
                row.extend_from_slice(&c.to_le_bytes());
            }
            row.extend_from_slice(&(particles.material[i] as i32).to_le_bytes());
            row.extend_from_slice(&particles.plastic[i].to_le_bytes());
            if let Some(j) = fields.jacobian {
                row.extend_from_slice(&j[i].to_le_bytes());
            }
            if let Some(s) = fields.stress {
                for c in s[i] {
                    row.extend_from_slice(&c.to_le_bytes());
                }
            }
            w.write_all(&row)?;
        }
        Ok(())
    })
}

/// The header of a particle frame of `n` vertices (see [`write_ply_with_comments`]; shared with
/// the chunk encoder).
fn frame_header(n: usize, comments: &[&str], jacobian: bool, stress: bool) -> String {
    let mut header = String::new();
    header.push_str("ply\nformat binary_little_endian 1.0\n");
    header.push_str("comment rtmpm particles\n");
    for c in comments {
        header.push_str(&format!("comment {c}\n"));
    }
    header.push_str(&format!("element vertex {n}\n"));
    for p in ["x", "y", "z", "vx", "vy", "vz"] {
        header.push_str(&format!("property float {p}\n"));
    }
    header.push_str("property int material\n");
    header.push_str("property float plastic\n");
    if jacobian {
        header.push_str("property float J\n");
    }
    if stress {
        for p in ["sxx", "syy", "szz", "sxy", "syz", "sxz"] {
            header.push_str(&format!("property float {p}\n"));
        }
    }
    header.push_str("end_header\n");
    header
}

/// Scalar property types of PLY.
#[derive(Clone, Copy, Debug, PartialEq)]
enum ScalarType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl ScalarType {
    fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "char" | "int8" => ScalarType::I8,
            "uchar" | "uint8" => ScalarType::U8,
            "short" | "int16" => ScalarType::I16,
            "ushort" | "uint16" => ScalarType::U16,
            "int" | "int32" => ScalarType::I32,
            "uint" | "uint32" => ScalarType::U32,
            "float" | "float32" => ScalarType::F32,
            "double" | "float64" => ScalarType::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            ScalarType::I8 | ScalarType::U8 => 1,
            ScalarType::I16 | ScalarType::U16 => 2,
            ScalarType::I32 | ScalarType::U32 | ScalarType::F32 => 4,
            ScalarType::F64 => 8,
        }
    }

    fn empty_column(self, cap: usize) -> PlyColumn {
        match self {
            ScalarType::F32 => PlyColumn::Float(Vec::with_capacity(cap)),
            ScalarType::F64 => PlyColumn::Double(Vec::with_capacity(cap)),
            _ => PlyColumn::Int(Vec::with_capacity(cap)),
        }
    }

    /// Read an integer value (used for list counts and integer columns). `b` has `size()` bytes.
    fn read_int(self, b: &[u8]) -> i64 {
        match self {
            ScalarType::I8 => b[0] as i8 as i64,
            ScalarType::U8 => b[0] as i64,
            ScalarType::I16 => i16::from_le_bytes([b[0], b[1]]) as i64,
            ScalarType::U16 => u16::from_le_bytes([b[0], b[1]]) as i64,
            ScalarType::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as i64,
            ScalarType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as i64,
            ScalarType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as i64,
            ScalarType::F64 => f64::from_le_bytes(b[..8].try_into().unwrap()) as i64,
        }
    }
}

#[derive(Debug)]
enum Property {
    Scalar { name: String, ty: ScalarType },
    List { count: ScalarType, item: ScalarType },
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

fn malformed(msg: impl Into<String>) -> PlyError {
    PlyError::Malformed(msg.into())
}

/// Longest PLY header read (the header is text before the binary body).
const MAX_HEADER_BYTES: usize = 1 << 20;
/// Most elements and properties a header may declare.
const MAX_HEADER_ITEMS: usize = 4096;

/// Parse the header; returns the elements, the comments and the offset of the binary body.
fn parse_header(bytes: &[u8]) -> Result<(Vec<Element>, Vec<String>, usize), PlyError> {
    if !bytes.starts_with(b"ply\n") && !bytes.starts_with(b"ply\r\n") {
        return Err(malformed("missing `ply` magic line (not a PLY file)"));
    }
    let mut pos = 0usize;
    let mut elements: Vec<Element> = Vec::new();
    let mut comments = Vec::new();
    let mut items = 0usize;
    let mut saw_format = false;
    loop {
        if pos > MAX_HEADER_BYTES || items > MAX_HEADER_ITEMS {
            return Err(malformed(format!(
                "header longer than {MAX_HEADER_BYTES} bytes or {MAX_HEADER_ITEMS} lines \
                 without `end_header`"
            )));
        }
        let rest = &bytes[pos..];
        let nl = rest
            .iter()
            .position(|&b| b == b'\n')
            .ok_or_else(|| malformed("header not terminated by `end_header`"))?;
        let line = std::str::from_utf8(&rest[..nl])
            .map_err(|_| malformed("header is not valid UTF-8"))?
            .trim_end_matches('\r');
        pos += nl + 1;
        items += 1;
        let mut words = line.split_whitespace();
        match words.next() {
            Some("ply") | None => {}
            Some("format") => {
                let fmt = words.next().unwrap_or("");
                let version = words.next().unwrap_or("");
                if fmt != "binary_little_endian" || version != "1.0" {
                    return Err(PlyError::UnsupportedFormat(format!("{fmt} {version}")));
                }
                saw_format = true;
            }
            Some("comment") | Some("obj_info") => {
                let text = line.split_once(' ').map(|x| x.1).unwrap_or("");
                comments.push(text.to_string());
            }
            Some("element") => {
                let name = words
                    .next()
                    .ok_or_else(|| malformed(format!("bad element line `{line}`")))?;
                let count = words
                    .next()
                    .and_then(|c| c.parse::<u64>().ok())
                    .and_then(|c| usize::try_from(c).ok())
                    .ok_or_else(|| malformed(format!("bad element count in `{line}`")))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            Some("property") => {
                let el = elements
                    .last_mut()
                    .ok_or_else(|| malformed("property before any element"))?;
                let ty = words.next().unwrap_or("");
                let bad = || malformed(format!("bad property line `{line}`"));
                if ty == "list" {
                    let count = ScalarType::parse(words.next().unwrap_or("")).ok_or_else(bad)?;
                    let item = ScalarType::parse(words.next().unwrap_or("")).ok_or_else(bad)?;
                    words.next().ok_or_else(bad)?;
                    el.props.push(Property::List { count, item });
                } else {
                    let ty = ScalarType::parse(ty).ok_or_else(bad)?;
                    let name = words.next().ok_or_else(bad)?;
                    el.props.push(Property::Scalar {
                        name: name.to_string(),
                        ty,
                    });
                }
            }
            Some("end_header") => break,
            Some(other) => return Err(malformed(format!("unknown header keyword `{other}`"))),
        }
    }
    if !saw_format {
        return Err(malformed("missing `format` line"));
    }
    Ok((elements, comments, pos))
}

/// Read the `vertex` element of a binary little-endian PLY file (such as those written by
/// [`write_ply`]) and return its columns by name. The file's size is checked before it is read
/// ([`super::limits`]) and the counts of the header against the file before anything is
/// allocated.
pub fn read_ply(path: &Path) -> Result<PlyData, PlyError> {
    let bytes = read_bounded(path, DATA_MAX_BYTES, "PLY file")?;
    parse_ply(&bytes)
}

/// Decode a PLY file's bytes (see [`read_ply`]). Never panics and never allocates more than
/// the body the header announces, which must be present in `bytes`.
pub fn parse_ply(bytes: &[u8]) -> Result<PlyData, PlyError> {
    let (elements, comments, mut pos) = parse_header(bytes)?;
    let mut vertices: Option<(PlyData, usize)> = None;
    for el in &elements {
        let remaining = (bytes.len() - pos) as u64;
        // Every record holds at least the scalars and the list counts: a count that cannot fit
        // in the rest of the file is refused before any loop or allocation.
        let min_record = el.min_record_bytes();
        if (el.count as u64)
            .checked_mul(min_record)
            .is_none_or(|b| b > remaining)
        {
            return Err(truncated());
        }
        if el.name != "vertex" {
            if min_record > 0 {
                pos = el.skip(bytes, pos)?;
            }
            continue;
        }
        let (data, stride, end) = el.read_vertices(bytes, pos, &comments)?;
        pos = end;
        if vertices.is_some() {
            return Err(malformed("two `vertex` elements"));
        }
        vertices = Some((data, stride));
    }
    let Some((data, stride)) = vertices else {
        return Err(malformed("no `vertex` element"));
    };
    // Every byte is the header's: more data than it announces means its counts are wrong (or
    // the file is not what it says), and the particles read would not be the file's.
    let extra = bytes.len() - pos;
    if extra > 0 {
        let only_vertices = elements.len() == 1;
        return Err(malformed(if only_vertices {
            format!(
                "{extra} bytes after the {} vertices the header announces (`element vertex {}`): \
                 the data holds about {} vertices of {stride} bytes; the header's count does not \
                 match the data",
                data.count,
                data.count,
                data.count as u64 + (extra / stride) as u64
            )
        } else {
            format!(
                "{extra} bytes after the elements the header announces: its element counts do \
                 not match the data"
            )
        }));
    }
    Ok(data)
}

/// The error of a body shorter than its header announces.
fn truncated() -> PlyError {
    malformed("body is shorter than the header announces (truncated file?)")
}

impl Element {
    /// The fewest bytes a record of this element holds: its scalars and its lists' counts.
    fn min_record_bytes(&self) -> u64 {
        self.props
            .iter()
            .map(|p| match p {
                Property::Scalar { ty, .. } => ty.size() as u64,
                Property::List { count, .. } => count.size() as u64,
            })
            .sum()
    }

    /// Where this element's records, which start at `pos`, end: skipped record by record (list
    /// lengths vary).
    fn skip(&self, bytes: &[u8], mut pos: usize) -> Result<usize, PlyError> {
        for _ in 0..self.count {
            for p in &self.props {
                let size = match p {
                    Property::Scalar { ty, .. } => ty.size(),
                    Property::List { count, item } => {
                        let b = bytes.get(pos..pos + count.size()).ok_or_else(truncated)?;
                        let k = count.read_int(b);
                        if k < 0 {
                            return Err(malformed("negative list length"));
                        }
                        (k as usize)
                            .checked_mul(item.size())
                            .and_then(|s| s.checked_add(count.size()))
                            .ok_or_else(truncated)?
                    }
                };
                pos = pos
                    .checked_add(size)
                    .filter(|&p| p <= bytes.len())
                    .ok_or_else(truncated)?;
            }
        }
        Ok(pos)
    }

    /// The `vertex` element's records from `pos` (which the caller checked fit in `bytes`), as
    /// columns: the data, the bytes of a record and where the records end. Scalars only.
    fn read_vertices(
        &self,
        bytes: &[u8],
        mut pos: usize,
        comments: &[String],
    ) -> Result<(PlyData, usize, usize), PlyError> {
        let mut stride = 0usize;
        let mut types = Vec::new();
        for p in &self.props {
            match p {
                Property::Scalar { name, ty } => {
                    stride += ty.size();
                    types.push((name.clone(), *ty));
                }
                Property::List { .. } => {
                    return Err(malformed("list properties in `vertex` are not supported"));
                }
            }
        }
        if types.is_empty() {
            return Err(malformed("the `vertex` element has no properties"));
        }
        // Checked by the caller: stride * count fits in the rest of the file.
        let mut cols: Vec<(String, ScalarType, PlyColumn)> = types
            .into_iter()
            .map(|(n, ty)| (n, ty, ty.empty_column(self.count)))
            .collect();
        for _ in 0..self.count {
            for (_, ty, col) in cols.iter_mut() {
                let b = &bytes[pos..pos + ty.size()];
                match col {
                    PlyColumn::Float(v) => v.push(f32::from_le_bytes(b.try_into().unwrap())),
                    PlyColumn::Double(v) => v.push(f64::from_le_bytes(b.try_into().unwrap())),
                    PlyColumn::Int(v) => v.push(ty.read_int(b)),
                }
                pos += ty.size();
            }
        }
        debug_assert!(stride > 0);
        let data = PlyData {
            count: self.count,
            columns: cols.into_iter().map(|(n, _, c)| (n, c)).collect(),
            comments: comments.to_vec(),
        };
        Ok((data, stride, pos))
    }
}

#[cfg(test)]
mod tests;
