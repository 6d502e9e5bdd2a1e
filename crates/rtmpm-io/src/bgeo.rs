//! Houdini's classic binary geometry (`.bgeo`, and gzip-compressed `.bgeo.gz`): particle frames
//! with their attributes, written for Houdini (and any reader of the format, such as partio or
//! splashsurf), and read back for `[[body]] shape = "particles"`.
//!
//! The layout is the classic "Bgeo V5" format that Houdini still reads and that partio
//! (Walt Disney Animation Studios' particle I/O library) writes; every number is big endian:
//!
//! | bytes | content |
//! | --- | --- |
//! | 4 + 1 + 4 | magic `Bgeo`, the character `V`, version `5` (i32) |
//! | 8 x 4 | i32 counts: points, primitives, point groups, primitive groups, point attributes, vertex attributes, primitive attributes, detail attributes |
//! | per point attribute | u16 name length, name, u16 size (components), i32 type (0 float, 1 int, 4 indexed string, 5 vector), `size` i32 default values (the bits of f32 for float types); an indexed string attribute then lists its strings (i32 count, each u16 length + bytes) |
//! | per point | `P` as x, y, z and the homogeneous weight `w` (4 x f32), then each attribute's components (f32, or i32 for int and indexed string) |
//! | 2 | `0x00 0xff`: end of the file's extra sections |
//!
//! [`write_bgeo`] writes these point attributes after `P`: `v` (vector 3, m/s), `id` (int, the
//! particle's index, stable across frames), `material` (int, index into the scene's materials),
//! `plastic` (float, the material's plastic state), `mass` (float, kg), `pscale` (float, half
//! the edge of the particle's initial volume cube, m: Houdini's point radius), and when asked
//! `J` (float, `det F`) and `stress` (float 9: the Cauchy stress as a row-major 3x3 matrix, Pa,
//! Houdini's layout of a matrix3 attribute).
//!
//! [`read_bgeo`] reads any file of this layout (plain or gzip) and checks every size against
//! the bytes present before it allocates: a truncated or hostile file is an error, never a
//! panic or a huge allocation.

use std::io::{self, Read, Write};
use std::path::Path;

use super::atomic::write_atomic_with;
use super::limits::{DATA_MAX_BYTES, decompressed_limit, human_bytes, read_bounded};
use crate::chunks::FrameColumns;
use crate::fields::FrameFields;
use crate::frame::{ChunkEncoder, ChunkRows, Derived, FrameBytes, FrameFormat, Records};
use rtmpm_physics::Particles;

/// Bytes per particle of a BGEO frame: `P` (4), `v` (3), `id`, `material`, `plastic`, `mass`,
/// `pscale`; `J`; the stress as a full 3x3.
const BGEO_BYTES: FrameBytes = FrameBytes {
    base: 48,
    jacobian: 4,
    stress: 36,
};

/// BGEO frames (`frame_NNNNN.bgeo`) for Houdini; written whole or in chunks.
pub static FORMAT: FrameFormat = FrameFormat {
    name: "bgeo",
    extension: "bgeo",
    about: "Houdini's classic binary geometry",
    bytes: BGEO_BYTES,
    write: |path, f| write_bgeo(path, f.particles, &f.fields, false),
    pvd: false,
    chunks: Some(&BgeoChunks { gzip: false }),
};

/// The same, gzip-compressed (`frame_NNNNN.bgeo.gz`).
pub static FORMAT_GZ: FrameFormat = FrameFormat {
    name: "bgeo.gz",
    extension: "bgeo.gz",
    about: "Houdini's classic binary geometry, gzip-compressed",
    bytes: BGEO_BYTES,
    write: |path, f| write_bgeo(path, f.particles, &f.fields, true),
    pvd: false,
    chunks: Some(&BgeoChunks { gzip: true }),
};

/// BGEO records chunk by chunk: the header of [`write_bgeo`], per particle the same big-endian
/// values, the same end.
struct BgeoChunks {
    gzip: bool,
}

impl ChunkEncoder for BgeoChunks {
    fn columns(&self, _derived: Derived) -> FrameColumns {
        FrameColumns {
            mass: true,
            vol0: true,
            ..FrameColumns::default()
        }
    }

    fn header(&self, n: usize, derived: Derived, _comments: &[&str]) -> io::Result<Vec<u8>> {
        let n_i32 = i32::try_from(n).map_err(|_| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                "the particle count does not fit the BGEO format's 32-bit integers",
            )
        })?;
        Ok(frame_header(n_i32, &frame_attributes(derived)))
    }

    fn record_bytes(&self, d: Derived) -> usize {
        BGEO_BYTES.with(d) as usize
    }

    fn encode(&self, r: &ChunkRows, first: usize, count: usize, out: &mut [u8]) -> io::Result<()> {
        let (Some(mass), Some(vol0)) = (r.mass, r.vol0) else {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "frame chunk without masses or initial volumes (BGEO)",
            ));
        };
        let mut o = Records(out);
        for j in first..first + count {
            for row in &r.x {
                o.put(row[j].to_be_bytes());
            }
            o.put(1.0f32.to_be_bytes());
            for row in &r.v {
                o.put(row[j].to_be_bytes());
            }
            o.put(((r.start + j) as i32).to_be_bytes());
            o.put((r.material[j] as i32).to_be_bytes());
            o.put(r.plastic[j].to_be_bytes());
            o.put(mass[j].to_be_bytes());
            o.put((0.5 * vol0[j].max(0.0).cbrt()).to_be_bytes());
            if let Some(jac) = r.jacobian {
                o.put(jac[j].to_be_bytes());
            }
            if let Some(s) = r.stress {
                for c in symmetric_to_full(s[j]) {
                    o.put(c.to_be_bytes());
                }
            }
        }
        Ok(())
    }

    fn trailer(&self) -> &'static [u8] {
        &[0x00, 0xff]
    }

    fn gzip(&self) -> bool {
        self.gzip
    }
}

/// The point attributes of a BGEO frame after `P` (as [`write_bgeo`] writes them).
fn frame_attributes(d: Derived) -> Vec<(&'static str, BgeoType, usize)> {
    let mut a = vec![
        ("v", BgeoType::Vector, 3),
        ("id", BgeoType::Int, 1),
        ("material", BgeoType::Int, 1),
        ("plastic", BgeoType::Float, 1),
        ("mass", BgeoType::Float, 1),
        ("pscale", BgeoType::Float, 1),
    ];
    if d.jacobian {
        a.push(("J", BgeoType::Float, 1));
    }
    if d.stress {
        a.push(("stress", BgeoType::Float, 9));
    }
    a
}

/// Errors of [`read_bgeo`].
#[derive(Debug, thiserror::Error)]
pub enum BgeoError {
    /// The file could not be read.
    #[error("BGEO I/O error: {0}")]
    Io(#[from] io::Error),
    /// The file is not a classic BGEO file this reader handles, or it is damaged.
    #[error("malformed BGEO file: {0}")]
    Malformed(String),
}

fn malformed(msg: impl Into<String>) -> BgeoError {
    BgeoError::Malformed(msg.into())
}

/// Attribute types of the classic format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BgeoType {
    /// 32-bit floats (type 0).
    Float,
    /// 32-bit signed integers (type 1).
    Int,
    /// An index into a per-attribute string table (type 4); stored as i32.
    IndexedString,
    /// Floats transformed as a vector (type 5).
    Vector,
}

impl BgeoType {
    fn code(self) -> i32 {
        match self {
            BgeoType::Float => 0,
            BgeoType::Int => 1,
            BgeoType::IndexedString => 4,
            BgeoType::Vector => 5,
        }
    }

    fn from_code(code: i32) -> Result<Self, BgeoError> {
        Ok(match code {
            0 => BgeoType::Float,
            1 => BgeoType::Int,
            4 => BgeoType::IndexedString,
            5 => BgeoType::Vector,
            2 => return Err(malformed("string attributes (type 2) are not supported")),
            other => return Err(malformed(format!("unknown attribute type {other}"))),
        })
    }
}

/// Values of one attribute, flattened (component fastest).
#[derive(Clone, Debug, PartialEq)]
pub enum BgeoValues {
    /// Float and vector attributes.
    Float(Vec<f32>),
    /// Int and indexed-string attributes.
    Int(Vec<i32>),
}

/// One point attribute of a BGEO file.
#[derive(Clone, Debug, PartialEq)]
pub struct BgeoAttribute {
    /// Name, e.g. `v`.
    pub name: String,
    /// Type.
    pub ty: BgeoType,
    /// Components per point.
    pub size: usize,
    /// `count * size` values.
    pub values: BgeoValues,
    /// The string table of an indexed-string attribute (empty otherwise).
    pub strings: Vec<String>,
}

/// The points of a BGEO file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BgeoData {
    /// Positions `P`.
    pub positions: Vec<[f32; 3]>,
    /// The point attributes, in file order.
    pub attributes: Vec<BgeoAttribute>,
}

impl BgeoData {
    /// The attribute named `name`, if any.
    pub fn attribute(&self, name: &str) -> Option<&BgeoAttribute> {
        self.attributes.iter().find(|a| a.name == name)
    }

    /// The float (or vector) attribute `name` with `size` components, if present.
    pub fn floats(&self, name: &str, size: usize) -> Option<&[f32]> {
        match self.attribute(name)? {
            BgeoAttribute {
                values: BgeoValues::Float(v),
                size: s,
                ..
            } if *s == size => Some(v),
            _ => None,
        }
    }

    /// The int attribute `name` (one component), if present.
    pub fn ints(&self, name: &str) -> Option<&[i32]> {
        match self.attribute(name)? {
            BgeoAttribute {
                values: BgeoValues::Int(v),
                size: 1,
                ..
            } => Some(v),
            _ => None,
        }
    }
}

/// The full symmetric 3x3 matrix, row-major, of `[xx, yy, zz, xy, yz, xz]`.
pub fn symmetric_to_full(s: [f32; 6]) -> [f32; 9] {
    let [xx, yy, zz, xy, yz, xz] = s;
    [xx, xy, xz, xy, yy, yz, xz, yz, zz]
}

/// Appends point `i`'s big-endian values of one attribute to a buffer.
type PutFn<'a> = Box<dyn Fn(usize, &mut Vec<u8>) + 'a>;

/// One attribute to write: name, type, components, and its values.
struct OutAttr<'a> {
    name: &'static str,
    ty: BgeoType,
    size: usize,
    put: PutFn<'a>,
}

/// Write `particles` (and the optional `fields`) as a classic BGEO file at `path`, atomically,
/// gzip-compressed when `gzip` is true (name such files `.bgeo.gz`). See the module
/// documentation for the attributes.
pub fn write_bgeo(
    path: &Path,
    particles: &Particles,
    fields: &FrameFields,
    gzip: bool,
) -> io::Result<()> {
    crate::contents::check_particles(particles)?;
    let n = particles.len();
    fields.check_len(n)?;
    let too_big = |what: &str| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{what} does not fit the BGEO format's 32-bit integers"),
        )
    };
    let n_i32 = i32::try_from(n).map_err(|_| too_big("the particle count"))?;
    if n > 0 && i32::try_from(n - 1).is_err() {
        return Err(too_big("a particle id"));
    }
    if let Some(m) = particles.material.iter().find(|&&m| m > i32::MAX as u32) {
        return Err(too_big(&format!("material index {m}")));
    }
    let p = particles;
    let f32s = |out: &mut Vec<u8>, vals: &[f32]| {
        for v in vals {
            out.extend_from_slice(&v.to_be_bytes());
        }
    };
    let mut attrs: Vec<OutAttr> = vec![
        OutAttr {
            name: "v",
            ty: BgeoType::Vector,
            size: 3,
            put: Box::new(move |i, o| f32s(o, &p.v[i].to_array())),
        },
        OutAttr {
            name: "id",
            ty: BgeoType::Int,
            size: 1,
            put: Box::new(|i, o| o.extend_from_slice(&(i as i32).to_be_bytes())),
        },
        OutAttr {
            name: "material",
            ty: BgeoType::Int,
            size: 1,
            put: Box::new(move |i, o| o.extend_from_slice(&(p.material[i] as i32).to_be_bytes())),
        },
        OutAttr {
            name: "plastic",
            ty: BgeoType::Float,
            size: 1,
            put: Box::new(move |i, o| f32s(o, &[p.plastic[i]])),
        },
        OutAttr {
            name: "mass",
            ty: BgeoType::Float,
            size: 1,
            put: Box::new(move |i, o| f32s(o, &[p.mass[i]])),
        },
        OutAttr {
            name: "pscale",
            ty: BgeoType::Float,
            size: 1,
            put: Box::new(move |i, o| f32s(o, &[0.5 * p.vol0[i].max(0.0).cbrt()])),
        },
    ];
    if let Some(j) = fields.jacobian {
        attrs.push(OutAttr {
            name: "J",
            ty: BgeoType::Float,
            size: 1,
            put: Box::new(move |i, o| f32s(o, &[j[i]])),
        });
    }
    if let Some(s) = fields.stress {
        attrs.push(OutAttr {
            name: "stress",
            ty: BgeoType::Float,
            size: 9,
            put: Box::new(move |i, o| f32s(o, &symmetric_to_full(s[i]))),
        });
    }

    let list: Vec<(&str, BgeoType, usize)> = attrs.iter().map(|a| (a.name, a.ty, a.size)).collect();
    let header = frame_header(n_i32, &list);

    write_atomic_with(path, |w| {
        let body = |w: &mut dyn Write| -> io::Result<()> {
            w.write_all(&header)?;
            let mut buf: Vec<u8> = Vec::with_capacity(64 * 1024);
            for i in 0..n {
                let x = p.x[i];
                f32s(&mut buf, &[x.x, x.y, x.z, 1.0]);
                for a in &attrs {
                    (a.put)(i, &mut buf);
                }
                if buf.len() >= 60 * 1024 {
                    w.write_all(&buf)?;
                    buf.clear();
                }
            }
            buf.extend_from_slice(&[0x00, 0xff]);
            w.write_all(&buf)
        };
        if gzip {
            let mut gz = flate2::write::GzEncoder::new(w, flate2::Compression::fast());
            body(&mut gz)?;
            gz.finish()?;
            Ok(())
        } else {
            body(w)
        }
    })
}

/// The header of a point file of `n` points with the point attributes `attrs` (name, type,
/// components), see the module documentation (shared with the chunk encoder).
fn frame_header(n_i32: i32, attrs: &[(&str, BgeoType, usize)]) -> Vec<u8> {
    let mut header = Vec::new();
    header.extend_from_slice(b"BgeoV");
    let counts = [5, n_i32, 0, 0, 0, attrs.len() as i32, 0, 0, 0];
    for c in counts {
        header.extend_from_slice(&c.to_be_bytes());
    }
    for &(name, ty, size) in attrs {
        header.extend_from_slice(&(name.len() as u16).to_be_bytes());
        header.extend_from_slice(name.as_bytes());
        header.extend_from_slice(&(size as u16).to_be_bytes());
        header.extend_from_slice(&ty.code().to_be_bytes());
        for _ in 0..size {
            header.extend_from_slice(&0i32.to_be_bytes());
        }
    }

    header
}

/// Read the points and point attributes of a classic BGEO file (plain, or gzip-compressed:
/// detected from its first bytes, whatever its name).
pub fn read_bgeo(path: &Path) -> Result<BgeoData, BgeoError> {
    let raw = read_bounded(path, DATA_MAX_BYTES, "BGEO file")?;
    if raw.starts_with(&[0x1f, 0x8b]) {
        // Deflate expands at most about 1032:1, so the output is bounded by what the file
        // holds (and by the memory available); it is read incrementally (no allocation ahead
        // of the data).
        let limit = decompressed_limit(raw.len() as u64);
        let mut bytes = Vec::new();
        flate2::read::MultiGzDecoder::new(&raw[..])
            .take(limit.saturating_add(1))
            .read_to_end(&mut bytes)
            .map_err(|e| malformed(format!("gzip data is damaged: {e}")))?;
        if bytes.len() as u64 > limit {
            return Err(malformed(format!(
                "{} expands to more than {} (the memory available, or a damaged file)",
                path.display(),
                human_bytes(limit)
            )));
        }
        drop(raw);
        parse_bgeo(&bytes)
    } else {
        parse_bgeo(&raw)
    }
}

/// A bounds-checked big-endian cursor.
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], BgeoError> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or_else(|| {
                malformed(format!(
                    "the file ends inside {what} (byte {} of {}; truncated file?)",
                    self.pos,
                    self.bytes.len()
                ))
            })?;
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    fn i32(&mut self, what: &str) -> Result<i32, BgeoError> {
        let b = self.take(4, what)?;
        Ok(i32::from_be_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn u16(&mut self, what: &str) -> Result<u16, BgeoError> {
        let b = self.take(2, what)?;
        Ok(u16::from_be_bytes([b[0], b[1]]))
    }

    fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }
}

fn parse_bgeo(bytes: &[u8]) -> Result<BgeoData, BgeoError> {
    let mut c = Cursor { bytes, pos: 0 };
    let magic = c.take(5, "the header")?;
    if magic.starts_with(&[0x7f, b'N', b'S', b'J']) {
        return Err(malformed(
            "this is Houdini's newer JSON-based binary geometry (Houdini 12 and later), not the classic format; save it from Houdini with the classic format (e.g. as .bgeo through partio, or as .ply)",
        ));
    }
    if &magic[..4] != b"Bgeo" {
        return Err(malformed("no `Bgeo` magic at the start (not a BGEO file)"));
    }
    let version = c.i32("the header")?;
    if magic[4] != b'V' || version != 5 {
        return Err(malformed(format!(
            "version {}{version} is not supported (only V5, the classic format)",
            magic[4] as char
        )));
    }
    let mut counts = [0i32; 8];
    for k in &mut counts {
        *k = c.i32("the header")?;
    }
    if let Some(bad) = counts.iter().find(|&&k| k < 0) {
        return Err(malformed(format!("negative count {bad} in the header")));
    }
    let n = counts[0] as usize;
    let n_attr = counts[4] as usize;

    let mut defs: Vec<(String, BgeoType, usize, Vec<String>)> = Vec::new();
    let mut stride = 16usize; // P and w.
    for k in 0..n_attr {
        let what = format!("the definition of point attribute {k}");
        let len = c.u16(&what)? as usize;
        let name = std::str::from_utf8(c.take(len, &what)?)
            .map_err(|_| malformed(format!("point attribute {k}: name is not UTF-8")))?
            .to_string();
        let size = c.u16(&what)? as usize;
        if size == 0 {
            return Err(malformed(format!("attribute `{name}` has 0 components")));
        }
        let ty = BgeoType::from_code(c.i32(&what)?)
            .map_err(|e| malformed(format!("attribute `{name}`: {e}")))?;
        c.take(4 * size, &what)?; // Default values.
        let mut strings = Vec::new();
        if ty == BgeoType::IndexedString {
            let count = c.i32(&what)?;
            if count < 0 || count as usize > c.remaining() / 2 {
                return Err(malformed(format!(
                    "attribute `{name}`: string count {count} does not fit the file"
                )));
            }
            for _ in 0..count {
                let l = c.u16(&what)? as usize;
                strings.push(String::from_utf8_lossy(c.take(l, &what)?).into_owned());
            }
        }
        stride += 4 * size;
        defs.push((name, ty, size, strings));
    }
    let need = stride.checked_mul(n).filter(|&b| b <= c.remaining());
    if need.is_none() {
        return Err(malformed(format!(
            "the header announces {n} points of {stride} bytes, but only {} bytes follow (truncated file?)",
            c.remaining()
        )));
    }
    // Every size is now backed by bytes of the file: allocate.
    let mut positions = Vec::with_capacity(n);
    let mut attributes: Vec<BgeoAttribute> = defs
        .into_iter()
        .map(|(name, ty, size, strings)| BgeoAttribute {
            values: match ty {
                BgeoType::Float | BgeoType::Vector => {
                    BgeoValues::Float(Vec::with_capacity(n * size))
                }
                _ => BgeoValues::Int(Vec::with_capacity(n * size)),
            },
            name,
            ty,
            size,
            strings,
        })
        .collect();
    let body = c.take(stride * n, "the points")?;
    let be_f32 = |b: &[u8]| f32::from_be_bytes([b[0], b[1], b[2], b[3]]);
    for rec in body.chunks_exact(stride) {
        positions.push([be_f32(&rec[0..]), be_f32(&rec[4..]), be_f32(&rec[8..])]);
        let mut off = 16;
        for a in &mut attributes {
            for _ in 0..a.size {
                let b = &rec[off..off + 4];
                match &mut a.values {
                    BgeoValues::Float(v) => v.push(be_f32(b)),
                    BgeoValues::Int(v) => v.push(i32::from_be_bytes([b[0], b[1], b[2], b[3]])),
                }
                off += 4;
            }
        }
    }
    Ok(BgeoData {
        positions,
        attributes,
    })
}

#[cfg(test)]
pub(crate) mod tests;
