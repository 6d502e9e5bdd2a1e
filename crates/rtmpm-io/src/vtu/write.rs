//! The `.vtu` writer: an UnstructuredGrid of points, cells and named point arrays, its arrays
//! appended (zlib-compressed or raw) or inline; and the particle frame written with it.

use std::io::{self, Write};
use std::path::Path;

use base64::Engine;
use base64::engine::general_purpose::STANDARD;
use rayon::prelude::*;

use crate::atomic::write_atomic_with;
use crate::bgeo::symmetric_to_full;
use crate::fields::FrameFields;
use crate::frame::{FrameBytes, FrameFormat};
use rtmpm_physics::Particles;

/// VTU frames (`frame_NNNNN.vtu`, listed in `frames.pvd`) for ParaView; whole frames.
pub static FORMAT: FrameFormat = FrameFormat {
    name: "vtu",
    extension: "vtu",
    about: "VTK XML UnstructuredGrid with a .pvd time series (ParaView)",
    // Uncompressed appended arrays: an upper bound of the zlib-compressed default.
    bytes: FrameBytes {
        base: 57,
        jacobian: 4,
        stress: 36,
    },
    write: |path, f| {
        write_particles_vtu(path, f.particles, &f.fields, Encoding::appended(f.compress))
    },
    pvd: true,
    chunks: None,
};

/// Uncompressed bytes per compressed block (ParaView's default).
const BLOCK: usize = 32 * 1024;

/// How the arrays of a `.vtu` file are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// In one `AppendedData` section (`encoding="raw"`), each zlib-compressed in 32 KiB blocks
    /// (`vtkZLibDataCompressor`), as ParaView writes them: rtmpm's frames and meshes.
    Zlib,
    /// In one `AppendedData` section, uncompressed.
    Raw,
    /// Inside each `DataArray` (`format="binary"`): base64 of the `UInt64` byte count, then,
    /// encoded separately as VTK does, base64 of the data. One third larger; text only.
    Inline,
}

impl Encoding {
    /// Appended arrays, zlib-compressed when `compress`.
    pub fn appended(compress: bool) -> Encoding {
        if compress {
            Encoding::Zlib
        } else {
            Encoding::Raw
        }
    }
}

/// VTK cell types used here.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CellKind {
    /// `VTK_VERTEX` (1): one cell per point.
    Vertices,
    /// `VTK_TRIANGLE` (5).
    Triangles,
}

/// One named point array to write: little-endian bytes of `len` tuples of `ncomp` values.
pub struct OutArray {
    /// VTK type name (`Float32`, `Int32`, ...).
    pub ty: &'static str,
    /// Array name.
    pub name: String,
    /// Components per tuple.
    pub ncomp: usize,
    /// The little-endian bytes.
    pub bytes: Vec<u8>,
}

impl OutArray {
    /// A Float32 array from flat values.
    pub fn f32(name: &str, ncomp: usize, values: impl Iterator<Item = f32>) -> OutArray {
        OutArray {
            ty: "Float32",
            name: name.into(),
            ncomp,
            bytes: values.flat_map(f32::to_le_bytes).collect(),
        }
    }

    /// An Int32 array.
    pub fn i32(name: &str, values: impl Iterator<Item = i32>) -> OutArray {
        OutArray {
            ty: "Int32",
            name: name.into(),
            ncomp: 1,
            bytes: values.flat_map(i32::to_le_bytes).collect(),
        }
    }
}

/// The stored form of one array: appended, its `UInt64` header and data (zlib-compressed in
/// blocks for [`Encoding::Zlib`]); inline, the base64 of its header and of its data.
fn encode(bytes: &[u8], encoding: Encoding) -> io::Result<Vec<u8>> {
    if encoding == Encoding::Inline {
        let mut out = STANDARD
            .encode((bytes.len() as u64).to_le_bytes())
            .into_bytes();
        out.extend_from_slice(STANDARD.encode(bytes).as_bytes());
        return Ok(out);
    }
    if encoding == Encoding::Raw {
        let mut out = Vec::with_capacity(8 + bytes.len());
        out.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
        out.extend_from_slice(bytes);
        return Ok(out);
    }
    let blocks: Vec<Vec<u8>> = bytes
        .par_chunks(BLOCK)
        .map(|b| {
            let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
            z.write_all(b)?;
            z.finish()
        })
        .collect::<io::Result<_>>()?;
    let last = match bytes.len() % BLOCK {
        0 if !bytes.is_empty() => BLOCK,
        r => r,
    };
    let mut out =
        Vec::with_capacity(8 * (3 + blocks.len()) + blocks.iter().map(Vec::len).sum::<usize>());
    for h in [blocks.len(), BLOCK, last] {
        out.extend_from_slice(&(h as u64).to_le_bytes());
    }
    for b in &blocks {
        out.extend_from_slice(&(b.len() as u64).to_le_bytes());
    }
    for b in &blocks {
        out.extend_from_slice(b);
    }
    Ok(out)
}

/// One array of a file in file order: its section (`Points`, `Cells`, `PointData`), VTK type,
/// name, components per tuple and little-endian bytes.
struct Entry<'a> {
    section: &'static str,
    ty: &'a str,
    name: &'a str,
    ncomp: usize,
    bytes: &'a [u8],
}

/// The geometry of a piece as VTK stores it: the points' coordinates and the cells'
/// connectivity, offsets and types, little endian.
struct Geometry {
    n_cells: usize,
    points: Vec<u8>,
    connectivity: Vec<u8>,
    offsets: Vec<u8>,
    types: Vec<u8>,
}

impl Geometry {
    /// `points` with cells `kind` (`cells`: the point indices of each triangle; ignored for
    /// vertices, one per point).
    fn of(points: &[[f32; 3]], kind: CellKind, cells: &[[u32; 3]]) -> Geometry {
        let n = points.len();
        let (n_cells, connectivity, offsets, ty): (usize, Vec<u8>, Vec<u8>, u8) = match kind {
            CellKind::Vertices => (
                n,
                (0..n as i64).flat_map(i64::to_le_bytes).collect(),
                (1..=n as i64).flat_map(i64::to_le_bytes).collect(),
                1,
            ),
            CellKind::Triangles => (
                cells.len(),
                cells
                    .iter()
                    .flat_map(|t| t.iter().flat_map(|&i| (i as i64).to_le_bytes()))
                    .collect(),
                (1..=cells.len() as i64)
                    .flat_map(|k| (3 * k).to_le_bytes())
                    .collect(),
                5,
            ),
        };
        Geometry {
            n_cells,
            points: points
                .iter()
                .flatten()
                .flat_map(|c| c.to_le_bytes())
                .collect(),
            connectivity,
            offsets,
            types: vec![ty; n_cells],
        }
    }

    /// Every array of the file in file order: the points, the cells, then `arrays`.
    fn entries<'a>(&'a self, arrays: &'a [OutArray]) -> Vec<Entry<'a>> {
        let entry = |section, ty, name, ncomp, bytes| Entry {
            section,
            ty,
            name,
            ncomp,
            bytes,
        };
        let mut list = vec![
            entry("Points", "Float32", "Points", 3, &self.points[..]),
            entry("Cells", "Int64", "connectivity", 1, &self.connectivity),
            entry("Cells", "Int64", "offsets", 1, &self.offsets),
            entry("Cells", "UInt8", "types", 1, &self.types),
        ];
        for a in arrays {
            list.push(entry("PointData", a.ty, &a.name, a.ncomp, &a.bytes));
        }
        list
    }
}

/// Write an UnstructuredGrid of `points` with cells `kind` (`cells`: the point indices of
/// each triangle; ignored for vertices) and the point arrays, atomically at `path`, the arrays
/// stored as `encoding` says. `active` names the piece's active arrays (`("Scalars",
/// "material")`, `("Vectors", ...)`, `("Tensors", ...)`).
pub fn write_unstructured(
    path: &Path,
    points: &[[f32; 3]],
    kind: CellKind,
    cells: &[[u32; 3]],
    arrays: &[OutArray],
    active: &[(&str, &str)],
    encoding: Encoding,
) -> io::Result<()> {
    let n = points.len();
    for a in arrays {
        if a.bytes.len() != n * a.ncomp * 4 {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "array {} has {} bytes for {n} points",
                    a.name,
                    a.bytes.len()
                ),
            ));
        }
    }
    let geometry = Geometry::of(points, kind, cells);
    let list = geometry.entries(arrays);
    let encoded: Vec<Vec<u8>> = list
        .iter()
        .map(|e| encode(e.bytes, encoding))
        .collect::<io::Result<_>>()?;
    let xml = xml_of(n, geometry.n_cells, &list, &encoded, active, encoding);
    write_atomic_with(path, |w| {
        w.write_all(xml.as_bytes())?;
        if encoding != Encoding::Inline {
            for e in &encoded {
                w.write_all(e)?;
            }
            w.write_all(b"\n  </AppendedData>\n")?;
        }
        w.write_all(b"</VTKFile>\n")
    })
}

/// The XML of a file: the piece of `n` points and `n_cells` cells with the arrays `list`
/// (`encoded`: each as stored), up to the appended data (or, inline, up to `</VTKFile>`).
fn xml_of(
    n: usize,
    n_cells: usize,
    list: &[Entry],
    encoded: &[Vec<u8>],
    active: &[(&str, &str)],
    encoding: Encoding,
) -> String {
    let mut xml = String::new();
    xml.push_str("<?xml version=\"1.0\"?>\n");
    xml.push_str(crate::signature::XML_COMMENT);
    xml.push('\n');
    xml.push_str("<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\"");
    if encoding == Encoding::Zlib {
        xml.push_str(" compressor=\"vtkZLibDataCompressor\"");
    }
    xml.push_str(">\n  <UnstructuredGrid>\n");
    xml.push_str(&format!(
        "    <Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{n_cells}\">\n"
    ));
    let mut offset = 0usize;
    let mut section = "";
    for (e, stored) in list.iter().zip(encoded) {
        if e.section != section {
            if !section.is_empty() {
                xml.push_str(&format!("      </{section}>\n"));
            }
            if e.section == "PointData" {
                let attrs: String = active
                    .iter()
                    .map(|(k, v)| format!(" {k}=\"{v}\""))
                    .collect();
                xml.push_str(&format!("      <PointData{attrs}>\n"));
            } else {
                xml.push_str(&format!("      <{}>\n", e.section));
            }
            section = e.section;
        }
        xml.push_str(&data_array(e, stored, offset, encoding));
        offset += stored.len();
    }
    xml.push_str(&format!("      </{section}>\n"));
    xml.push_str("    </Piece>\n  </UnstructuredGrid>\n");
    if encoding != Encoding::Inline {
        xml.push_str("  <AppendedData encoding=\"raw\">\n   _");
    }
    xml
}

/// The `DataArray` element of `e`: appended, a tag pointing at `offset` in the appended data;
/// inline, with its base64 text `stored`.
fn data_array(e: &Entry, stored: &[u8], offset: usize, encoding: Encoding) -> String {
    let comps = if e.ncomp != 1 {
        format!(" NumberOfComponents=\"{}\"", e.ncomp)
    } else {
        String::new()
    };
    let head = format!(
        "        <DataArray type=\"{}\" Name=\"{}\"{comps}",
        e.ty, e.name
    );
    match encoding {
        Encoding::Inline => format!(
            "{head} format=\"binary\">\n          {}\n        </DataArray>\n",
            String::from_utf8_lossy(stored)
        ),
        Encoding::Zlib | Encoding::Raw => {
            format!("{head} format=\"appended\" offset=\"{offset}\"/>\n")
        }
    }
}

/// Write a particle frame (see the module documentation), its arrays stored as `encoding`.
pub fn write_particles_vtu(
    path: &Path,
    p: &Particles,
    fields: &FrameFields,
    encoding: Encoding,
) -> io::Result<()> {
    crate::contents::check_particles(p)?;
    let n = p.len();
    fields.check_len(n)?;
    if n > i32::MAX as usize || p.material.iter().any(|&m| m > i32::MAX as u32) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "particle ids and material indices must fit Int32",
        ));
    }
    let mut arrays = vec![
        OutArray::f32("velocity", 3, p.v.iter().flat_map(|v| v.to_array())),
        OutArray::i32("material", p.material.iter().map(|&m| m as i32)),
        OutArray::i32("id", 0..n as i32),
        OutArray::f32("plastic", 1, p.plastic.iter().copied()),
        OutArray::f32("mass", 1, p.mass.iter().copied()),
    ];
    if let Some(j) = fields.jacobian {
        arrays.push(OutArray::f32("J", 1, j.iter().copied()));
    }
    let mut active = vec![("Scalars", "material"), ("Vectors", "velocity")];
    if let Some(s) = fields.stress {
        arrays.push(OutArray::f32(
            "stress",
            9,
            s.iter().flat_map(|s| symmetric_to_full(*s)),
        ));
        active.push(("Tensors", "stress"));
    }
    let points: Vec<[f32; 3]> = p.x.iter().map(|x| x.to_array()).collect();
    write_unstructured(
        path,
        &points,
        CellKind::Vertices,
        &[],
        &arrays,
        &active,
        encoding,
    )
}
