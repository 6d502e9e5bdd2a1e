//! VTK XML UnstructuredGrid (`.vtu`) frames and `.pvd` time collections.
//!
//! Each particle is one `VTK_VERTEX` cell. Arrays are written inline with `format="binary"`:
//! base64 of a `UInt64` little-endian byte count, followed (encoded separately, as VTK does) by
//! base64 of the little-endian data. ParaView, VTK and meshio read these files.
//!
//! Point data arrays: `velocity` (Float32, 3 components), `material` (Int32), `plastic`
//! (Float32), `mass` (Float32), optional `J` (Float32) and optional `stress` (Float32, 6
//! components `xx, yy, zz, xy, yz, xz`, the ordering of VTK's symmetric tensors).

use std::fs;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use base64::Engine;
use base64::engine::general_purpose::STANDARD;
use base64::write::EncoderWriter;

use super::atomic::{write_atomic, write_atomic_with};
use super::limits::{DATA_MAX_BYTES, PVD_MAX_BYTES, read_text_bounded};
use crate::fields::FrameFields;
use rtmpm_physics::Particles;

/// Errors of [`read_vtu`] and [`PvdWriter::resume`].
#[derive(Debug, thiserror::Error)]
pub enum VtuError {
    /// The file could not be read.
    #[error("VTK I/O error: {0}")]
    Io(#[from] io::Error),
    /// The file is not in the subset of the VTK XML format that we write.
    #[error("unsupported or malformed VTK XML file: {0}")]
    Format(String),
}

fn format_err(msg: impl Into<String>) -> VtuError {
    VtuError::Format(msg.into())
}

/// Write one `DataArray` element with inline base64 binary data produced by `data`, which must
/// write exactly `nbytes` bytes.
fn write_data_array<W: Write>(
    w: &mut W,
    ty: &str,
    name: Option<&str>,
    ncomp: usize,
    nbytes: usize,
    data: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> io::Result<()> {
    write!(w, "        <DataArray type=\"{ty}\"")?;
    if let Some(name) = name {
        write!(w, " Name=\"{name}\"")?;
    }
    if ncomp != 1 {
        write!(w, " NumberOfComponents=\"{ncomp}\"")?;
    }
    writeln!(w, " format=\"binary\">")?;
    write!(w, "          ")?;
    w.write_all(STANDARD.encode((nbytes as u64).to_le_bytes()).as_bytes())?;
    let mut enc = EncoderWriter::new(&mut *w, &STANDARD);
    data(&mut enc)?;
    enc.finish()?;
    drop(enc);
    writeln!(w)?;
    writeln!(w, "        </DataArray>")
}

/// Write a slice of `N`-byte little-endian values through `to_le`.
fn write_le<T: Copy, const N: usize>(
    w: &mut dyn Write,
    values: impl Iterator<Item = T>,
    to_le: impl Fn(T) -> [u8; N],
) -> io::Result<()> {
    // Batch small writes; the base64 encoder is itself buffered, but one call per value is slow.
    let mut buf = Vec::with_capacity(64 * 1024);
    for v in values {
        buf.extend_from_slice(&to_le(v));
        if buf.len() >= 60 * 1024 {
            w.write_all(&buf)?;
            buf.clear();
        }
    }
    w.write_all(&buf)
}

/// Write `particles` (and the optional `fields`) as a VTK XML UnstructuredGrid at `path`,
/// atomically. See the module documentation for the arrays.
pub fn write_vtu(path: &Path, particles: &Particles, fields: &FrameFields) -> io::Result<()> {
    crate::contents::check_particles(particles)?;
    let n = particles.len();
    fields.check_len(n)?;
    write_atomic_with(path, |w| write_vtu_to(w, particles, fields))
}

fn write_vtu_to(
    w: &mut BufWriter<fs::File>,
    p: &Particles,
    fields: &FrameFields,
) -> io::Result<()> {
    let n = p.len();
    let f32le = |x: f32| x.to_le_bytes();
    writeln!(w, "<?xml version=\"1.0\"?>")?;
    writeln!(w, "{}", super::signature::XML_COMMENT)?;
    writeln!(
        w,
        "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">"
    )?;
    writeln!(w, "  <UnstructuredGrid>")?;
    writeln!(
        w,
        "    <Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{n}\">"
    )?;

    writeln!(w, "      <Points>")?;
    write_data_array(w, "Float32", Some("Points"), 3, n * 12, |e| {
        write_le(e, p.x.iter().flat_map(|x| x.to_array()), f32le)
    })?;
    writeln!(w, "      </Points>")?;

    writeln!(w, "      <Cells>")?;
    write_data_array(w, "Int64", Some("connectivity"), 1, n * 8, |e| {
        write_le(e, 0..n as i64, |i: i64| i.to_le_bytes())
    })?;
    write_data_array(w, "Int64", Some("offsets"), 1, n * 8, |e| {
        write_le(e, 1..=n as i64, |i: i64| i.to_le_bytes())
    })?;
    // VTK_VERTEX = 1.
    write_data_array(w, "UInt8", Some("types"), 1, n, |e| {
        write_le(e, std::iter::repeat_n(1u8, n), |t: u8| [t])
    })?;
    writeln!(w, "      </Cells>")?;

    writeln!(
        w,
        "      <PointData Scalars=\"material\" Vectors=\"velocity\">"
    )?;
    write_data_array(w, "Float32", Some("velocity"), 3, n * 12, |e| {
        write_le(e, p.v.iter().flat_map(|v| v.to_array()), f32le)
    })?;
    write_data_array(w, "Int32", Some("material"), 1, n * 4, |e| {
        write_le(e, p.material.iter().map(|&m| m as i32), |m: i32| {
            m.to_le_bytes()
        })
    })?;
    write_data_array(w, "Float32", Some("plastic"), 1, n * 4, |e| {
        write_le(e, p.plastic.iter().copied(), f32le)
    })?;
    write_data_array(w, "Float32", Some("mass"), 1, n * 4, |e| {
        write_le(e, p.mass.iter().copied(), f32le)
    })?;
    if let Some(j) = fields.jacobian {
        write_data_array(w, "Float32", Some("J"), 1, n * 4, |e| {
            write_le(e, j.iter().copied(), f32le)
        })?;
    }
    if let Some(s) = fields.stress {
        write_data_array(w, "Float32", Some("stress"), 6, n * 24, |e| {
            write_le(e, s.iter().flat_map(|s| s.iter().copied()), f32le)
        })?;
    }
    writeln!(w, "      </PointData>")?;
    writeln!(w, "    </Piece>")?;
    writeln!(w, "  </UnstructuredGrid>")?;
    writeln!(w, "</VTKFile>")
}

/// Values of one VTK `DataArray`, flattened (component index fastest).
#[derive(Clone, Debug, PartialEq)]
pub enum VtuValues {
    /// `Float32`.
    Float32(Vec<f32>),
    /// `Float64`.
    Float64(Vec<f64>),
    /// `Int32`.
    Int32(Vec<i32>),
    /// `Int64`.
    Int64(Vec<i64>),
    /// `UInt8`.
    UInt8(Vec<u8>),
}

impl VtuValues {
    /// Number of scalar values (tuples times components).
    pub fn len(&self) -> usize {
        match self {
            VtuValues::Float32(v) => v.len(),
            VtuValues::Float64(v) => v.len(),
            VtuValues::Int32(v) => v.len(),
            VtuValues::Int64(v) => v.len(),
            VtuValues::UInt8(v) => v.len(),
        }
    }

    /// True when there are no values.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// One named `DataArray`.
#[derive(Clone, Debug, PartialEq)]
pub struct VtuArray {
    /// The `Name` attribute.
    pub name: String,
    /// The `NumberOfComponents` attribute (1 when absent).
    pub num_components: usize,
    /// The decoded values.
    pub values: VtuValues,
}

/// The content of a `.vtu` file as written by [`write_vtu`] (single piece).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VtuData {
    /// `NumberOfPoints` of the piece.
    pub num_points: usize,
    /// `NumberOfCells` of the piece.
    pub num_cells: usize,
    /// Point coordinates.
    pub points: Vec<[f32; 3]>,
    /// The arrays of the `Cells` section (`connectivity`, `offsets`, `types`).
    pub cells: Vec<VtuArray>,
    /// The arrays of the `PointData` section, in file order.
    pub point_data: Vec<VtuArray>,
}

impl VtuData {
    /// The point data array named `name`, if any.
    pub fn point_array(&self, name: &str) -> Option<&VtuArray> {
        self.point_data.iter().find(|a| a.name == name)
    }
}

/// Value of attribute `name` in the start tag `tag` (the text between `<` and `>`).
pub(super) fn attr<'a>(tag: &'a str, name: &str) -> Option<&'a str> {
    let mut rest = tag;
    loop {
        let i = rest.find(name)?;
        let before_ok = i == 0 || rest.as_bytes()[i - 1].is_ascii_whitespace();
        let after = rest[i + name.len()..].trim_start();
        let after_eq = if before_ok {
            after.strip_prefix('=')
        } else {
            None
        };
        if let Some(after_eq) = after_eq {
            let after_eq = after_eq.trim_start();
            let quote = after_eq.chars().next()?;
            if quote == '"' || quote == '\'' {
                let body = &after_eq[1..];
                let end = body.find(quote)?;
                return Some(&body[..end]);
            }
            return None;
        }
        rest = &rest[i + name.len()..];
    }
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
        .replace('\'', "&apos;")
}

pub(super) fn xml_unescape(s: &str) -> String {
    s.replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&quot;", "\"")
        .replace("&apos;", "'")
        .replace("&amp;", "&")
}

/// Decode inline base64 binary data with a `UInt64` header. Accepts the header encoded
/// separately (as VTK and [`write_vtu`] do) or together with the data.
fn decode_binary(text: &str) -> Result<Vec<u8>, VtuError> {
    let s: String = text.chars().filter(|c| !c.is_ascii_whitespace()).collect();
    if !s.is_ascii() {
        return Err(format_err(
            "binary data holds characters that are not base64",
        ));
    }
    if s.len() < 12 {
        return Err(format_err("binary data shorter than its header"));
    }
    let bad = |e: base64::DecodeError| format_err(format!("bad base64 data: {e}"));
    let (nbytes, data) = if s.as_bytes()[11] == b'=' {
        let h = STANDARD.decode(&s[..12]).map_err(bad)?;
        if h.len() < 8 {
            return Err(format_err("binary data header is not 8 bytes"));
        }
        let nbytes = u64::from_le_bytes(h[..8].try_into().unwrap());
        (nbytes, STANDARD.decode(&s[12..]).map_err(bad)?)
    } else {
        let all = STANDARD.decode(&s).map_err(bad)?;
        if all.len() < 8 {
            return Err(format_err("binary data shorter than its header"));
        }
        let nbytes = u64::from_le_bytes(all[..8].try_into().unwrap());
        (nbytes, all[8..].to_vec())
    };
    if data.len() as u64 != nbytes {
        return Err(format_err(format!(
            "binary data has {} bytes, header says {nbytes}",
            data.len()
        )));
    }
    Ok(data)
}

pub(super) fn parse_values(ty: &str, data: &[u8]) -> Result<VtuValues, VtuError> {
    fn chunks<const N: usize, T>(data: &[u8], f: impl Fn([u8; N]) -> T) -> Vec<T> {
        data.chunks_exact(N)
            .map(|c| f(c.try_into().unwrap()))
            .collect()
    }
    let size = match ty {
        "Float32" | "Int32" => 4,
        "Float64" | "Int64" => 8,
        "UInt8" => 1,
        other => return Err(format_err(format!("unsupported DataArray type {other}"))),
    };
    if !data.chunks_exact(size).remainder().is_empty() {
        return Err(format_err(format!(
            "{ty} data length {} is not a multiple of {size}",
            data.len()
        )));
    }
    Ok(match ty {
        "Float32" => VtuValues::Float32(chunks(data, f32::from_le_bytes)),
        "Float64" => VtuValues::Float64(chunks(data, f64::from_le_bytes)),
        "Int32" => VtuValues::Int32(chunks(data, i32::from_le_bytes)),
        "Int64" => VtuValues::Int64(chunks(data, i64::from_le_bytes)),
        _ => VtuValues::UInt8(data.to_vec()),
    })
}

/// Read a `.vtu` file in the format written by [`write_vtu`]: one piece, inline
/// `format="binary"` arrays, little endian, `UInt64` headers. This is a minimal parser meant for
/// tests and tools, not a general VTK reader.
pub fn read_vtu(path: &Path) -> Result<VtuData, VtuError> {
    let text = read_text_bounded(path, DATA_MAX_BYTES, "VTU file")?;
    parse_vtu(&text)
}

/// Decode the text of a `.vtu` file (see [`read_vtu`]). Never panics; allocates no more than
/// the decoded arrays, whose sizes are bounded by the text.
pub fn parse_vtu(text: &str) -> Result<VtuData, VtuError> {
    check_root(text)?;
    let (piece_start, mut out) = piece(text)?;
    let mut section = Section::None;
    let mut pos = piece_start;
    while let Some(off) = text[pos..].find('<') {
        let start = pos + off;
        let end = start
            + text[start..]
                .find('>')
                .ok_or_else(|| format_err("unterminated tag"))?;
        let tag = &text[start + 1..end];
        pos = end + 1;
        let tag_name = tag.split_whitespace().next().unwrap_or("");
        match tag_name {
            "Points" => section = Section::Points,
            "Cells" => section = Section::Cells,
            "PointData" => section = Section::PointData,
            "/Points" | "/Cells" | "/PointData" | "CellData" | "/CellData" | "CellData/" => {
                section = Section::None
            }
            "/Piece" => break,
            "DataArray" => {
                if tag.ends_with('/') {
                    return Err(format_err("empty DataArray element"));
                }
                let close = text[pos..]
                    .find("</DataArray>")
                    .ok_or_else(|| format_err("unterminated DataArray"))?;
                let body = &text[pos..pos + close];
                pos += close + "</DataArray>".len();
                if section == Section::None {
                    continue;
                }
                out.place(&section, data_array(tag, body)?)?;
            }
            _ => {}
        }
    }
    if out.points.len() != out.num_points {
        return Err(format_err("missing <Points> array"));
    }
    Ok(out)
}

/// The part of a `<Piece>` that a `DataArray` belongs to.
#[derive(PartialEq)]
enum Section {
    None,
    Points,
    Cells,
    PointData,
}

/// The `<VTKFile>` element is one this reader decodes: an uncompressed little-endian
/// UnstructuredGrid with 64-bit headers.
fn check_root(text: &str) -> Result<(), VtuError> {
    let root_start = text
        .find("<VTKFile")
        .ok_or_else(|| format_err("no <VTKFile> element"))?;
    let root_tag = &text[root_start..root_start + text[root_start..].find('>').unwrap_or(0)];
    if attr(root_tag, "type") != Some("UnstructuredGrid") {
        return Err(format_err("not an UnstructuredGrid file"));
    }
    if attr(root_tag, "byte_order") != Some("LittleEndian") {
        return Err(format_err("only byte_order=\"LittleEndian\" is supported"));
    }
    if attr(root_tag, "header_type") != Some("UInt64") {
        return Err(format_err("only header_type=\"UInt64\" is supported"));
    }
    if attr(root_tag, "compressor").is_some() {
        return Err(format_err("compressed files are not supported"));
    }
    Ok(())
}

/// Where the `<Piece>` element starts, and the data with its point and cell counts.
fn piece(text: &str) -> Result<(usize, VtuData), VtuError> {
    let piece_start = text
        .find("<Piece")
        .ok_or_else(|| format_err("no <Piece> element"))?;
    let piece_tag = &text[piece_start..piece_start + text[piece_start..].find('>').unwrap_or(0)];
    let count = |name: &str| -> Result<usize, VtuError> {
        attr(piece_tag, name)
            .and_then(|v| v.trim().parse().ok())
            .ok_or_else(|| format_err(format!("<Piece> has no valid {name}")))
    };
    let out = VtuData {
        num_points: count("NumberOfPoints")?,
        num_cells: count("NumberOfCells")?,
        ..Default::default()
    };
    Ok((piece_start, out))
}

/// A binary `DataArray` element: its tag's attributes (`tag`, without the brackets) and its
/// base64 `body`.
fn data_array(tag: &str, body: &str) -> Result<VtuArray, VtuError> {
    if attr(tag, "format") != Some("binary") {
        return Err(format_err(
            "only format=\"binary\" DataArrays are supported",
        ));
    }
    let ty = attr(tag, "type").ok_or_else(|| format_err("DataArray without type"))?;
    let name = attr(tag, "Name").map(xml_unescape).unwrap_or_default();
    let num_components = match attr(tag, "NumberOfComponents") {
        Some(c) => c
            .trim()
            .parse()
            .map_err(|_| format_err(format!("bad NumberOfComponents {c}")))?,
        None => 1,
    };
    let values = parse_values(ty, &decode_binary(body)?)?;
    Ok(VtuArray {
        name,
        num_components,
        values,
    })
}

impl VtuData {
    /// Put an array of `section` in its place: the points (three Float32 per point), a cell
    /// array, or a point array (its components times the point count).
    fn place(&mut self, section: &Section, array: VtuArray) -> Result<(), VtuError> {
        match section {
            Section::Points => {
                let VtuValues::Float32(v) = &array.values else {
                    return Err(format_err("Points must be Float32"));
                };
                if array.num_components != 3 || Some(v.len()) != self.num_points.checked_mul(3) {
                    return Err(format_err(format!(
                        "Points has {} values, expected 3 x {}",
                        v.len(),
                        self.num_points
                    )));
                }
                self.points = v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
            }
            Section::Cells => self.cells.push(array),
            Section::PointData => {
                if Some(array.values.len()) != array.num_components.checked_mul(self.num_points) {
                    return Err(format_err(format!(
                        "point array {} has {} values, expected {} x {}",
                        array.name,
                        array.values.len(),
                        array.num_components,
                        self.num_points
                    )));
                }
                self.point_data.push(array);
            }
            // Arrays outside the three sections are skipped before they are decoded.
            Section::None => {}
        }
        Ok(())
    }
}

/// A ParaView `.pvd` collection listing one file per output frame with its time.
///
/// The file is rewritten atomically after each [`add`](PvdWriter::add), so it is always valid
/// and lists exactly the frames written so far.
#[derive(Clone, Debug)]
pub struct PvdWriter {
    path: PathBuf,
    entries: Vec<(f64, String)>,
}

impl PvdWriter {
    /// Start a new, empty collection at `path` (an existing file is replaced).
    pub fn new(path: impl Into<PathBuf>) -> io::Result<Self> {
        let w = PvdWriter {
            path: path.into(),
            entries: Vec::new(),
        };
        w.write()?;
        Ok(w)
    }

    /// Continue the collection at `path` after resuming from a checkpoint at time
    /// `keep_frames_before_time`: entries with `time < keep_frames_before_time` are kept, later
    /// ones (frames that will be written again) are dropped, and the file is rewritten. A missing
    /// file starts an empty collection.
    pub fn resume(
        path: impl Into<PathBuf>,
        keep_frames_before_time: f64,
    ) -> Result<Self, VtuError> {
        let path = path.into();
        let entries = match read_text_bounded(&path, PVD_MAX_BYTES, "ParaView collection") {
            Ok(text) => parse_pvd(&text)?,
            Err(e) if e.kind() == io::ErrorKind::NotFound => Vec::new(),
            Err(e) => return Err(e.into()),
        };
        let w = PvdWriter {
            path,
            entries: entries
                .into_iter()
                .filter(|(t, _)| *t < keep_frames_before_time)
                .collect(),
        };
        w.write()?;
        Ok(w)
    }

    /// Append the frame `file` (a path relative to the `.pvd`'s folder) at `time` and rewrite
    /// the collection.
    pub fn add(&mut self, time: f64, file: &str) -> io::Result<()> {
        self.entries.push((time, file.to_string()));
        self.write()
    }

    /// Path of the `.pvd` file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// `(time, file)` entries, in order.
    pub fn entries(&self) -> &[(f64, String)] {
        &self.entries
    }

    fn write(&self) -> io::Result<()> {
        let mut s = String::new();
        s.push_str("<?xml version=\"1.0\"?>\n");
        s.push_str(super::signature::XML_COMMENT);
        s.push('\n');
        s.push_str("<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n");
        s.push_str("  <Collection>\n");
        for (t, f) in &self.entries {
            // `{}` prints the shortest representation that parses back to the same f64.
            s.push_str(&format!(
                "    <DataSet timestep=\"{t}\" group=\"\" part=\"0\" file=\"{}\"/>\n",
                xml_escape(f)
            ));
        }
        s.push_str("  </Collection>\n");
        s.push_str("</VTKFile>\n");
        write_atomic(&self.path, s.as_bytes())
    }
}

/// Parse the `DataSet` entries `(time, file)` of a `.pvd` collection; times must be finite.
pub fn parse_pvd(text: &str) -> Result<Vec<(f64, String)>, VtuError> {
    if !text.contains("type=\"Collection\"") {
        return Err(format_err("not a VTK Collection (.pvd) file"));
    }
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(i) = rest.find("<DataSet") {
        let end = rest[i..]
            .find('>')
            .ok_or_else(|| format_err("unterminated DataSet tag"))?;
        let tag = &rest[i..i + end];
        let t = attr(tag, "timestep")
            .and_then(|t| t.trim().parse::<f64>().ok())
            .filter(|t| t.is_finite())
            .ok_or_else(|| format_err(format!("DataSet without a valid timestep: {tag}")))?;
        let f = attr(tag, "file").ok_or_else(|| format_err("DataSet without file"))?;
        out.push((t, xml_unescape(f)));
        rest = &rest[i + end..];
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
