//! ParaView-grade VTK XML UnstructuredGrid files: binary arrays in one `AppendedData` section
//! (`encoding="raw"`), each zlib-compressed in 32 KiB blocks (`vtkZLibDataCompressor`), as
//! ParaView itself writes them. Compression runs in parallel over the blocks.
//!
//! [`write_particles_vtu`] writes a particle frame (one `VTK_VERTEX` cell per particle) with
//! the point arrays `velocity` (3 components, the `Vectors` of the piece), `material` (Int32),
//! `id` (Int32, the particle index), `plastic`, `mass`, and when asked `J` and `stress`: the
//! Cauchy stress as a full 3x3 tensor of 9 components (ParaView's tensor convention, row-major
//! `XX XY XZ YX YY YZ ZX ZY ZZ`; the `Tensors` of the piece). [`write_unstructured`] is the
//! general writer (the surface meshes use it with triangles).
//!
//! [`read_appended_vtu`] reads such files (compressed or not, `UInt32` or `UInt64` headers)
//! into [`VtuData`]; every size in the file is checked against the bytes present before
//! anything is allocated or decompressed.

use std::fs;
use std::io::{self, Read, Write};
use std::path::Path;

use rayon::prelude::*;

use super::atomic::write_atomic_with;
use super::bgeo::symmetric_to_full;
use super::vtu::{VtuData, VtuError};
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
    write: |path, f| write_particles_vtu(path, f.particles, &f.fields, f.compress),
    pvd: true,
    chunks: None,
};

/// Uncompressed bytes per compressed block (ParaView's default).
const BLOCK: usize = 32 * 1024;

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

/// The appended block of one array: `UInt64` header and data, zlib-compressed in blocks when
/// `compress`.
fn encode(bytes: &[u8], compress: bool) -> io::Result<Vec<u8>> {
    if !compress {
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

/// Write an UnstructuredGrid of `points` with cells `kind` (`cells`: the point indices of
/// each triangle; ignored for vertices) and the point arrays, atomically at `path`.
/// `scalars`/`vectors`/`tensors` name the piece's active arrays.
pub fn write_unstructured(
    path: &Path,
    points: &[[f32; 3]],
    kind: CellKind,
    cells: &[[u32; 3]],
    arrays: &[OutArray],
    active: &[(&str, &str)],
    compress: bool,
) -> io::Result<()> {
    let n = points.len();
    let (n_cells, conn, offsets, ty): (usize, Vec<u8>, Vec<u8>, u8) = match kind {
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
    let pts: Vec<u8> = points
        .iter()
        .flatten()
        .flat_map(|c| c.to_le_bytes())
        .collect();
    let types = vec![ty; n_cells];
    // (section, type, name, components, bytes) in file order.
    let mut list: Vec<(&str, &str, &str, usize, &[u8])> = vec![
        ("Points", "Float32", "Points", 3, &pts),
        ("Cells", "Int64", "connectivity", 1, &conn),
        ("Cells", "Int64", "offsets", 1, &offsets),
        ("Cells", "UInt8", "types", 1, &types),
    ];
    for a in arrays {
        list.push(("PointData", a.ty, &a.name, a.ncomp, &a.bytes));
    }
    let encoded: Vec<Vec<u8>> = list
        .iter()
        .map(|(_, _, _, _, b)| encode(b, compress))
        .collect::<io::Result<_>>()?;

    let mut xml = String::new();
    xml.push_str("<?xml version=\"1.0\"?>\n");
    xml.push_str(super::signature::XML_COMMENT);
    xml.push('\n');
    xml.push_str("<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\"");
    if compress {
        xml.push_str(" compressor=\"vtkZLibDataCompressor\"");
    }
    xml.push_str(">\n  <UnstructuredGrid>\n");
    xml.push_str(&format!(
        "    <Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{n_cells}\">\n"
    ));
    let mut offset = 0usize;
    let mut section = "";
    for ((sec, ty, name, ncomp, _), enc) in list.iter().zip(&encoded) {
        if *sec != section {
            if !section.is_empty() {
                xml.push_str(&format!("      </{section}>\n"));
            }
            if *sec == "PointData" {
                let attrs: String = active
                    .iter()
                    .map(|(k, v)| format!(" {k}=\"{v}\""))
                    .collect();
                xml.push_str(&format!("      <PointData{attrs}>\n"));
            } else {
                xml.push_str(&format!("      <{sec}>\n"));
            }
            section = sec;
        }
        let comps = if *ncomp != 1 {
            format!(" NumberOfComponents=\"{ncomp}\"")
        } else {
            String::new()
        };
        xml.push_str(&format!(
            "        <DataArray type=\"{ty}\" Name=\"{name}\"{comps} format=\"appended\" offset=\"{offset}\"/>\n"
        ));
        offset += enc.len();
    }
    xml.push_str(&format!("      </{section}>\n"));
    xml.push_str("    </Piece>\n  </UnstructuredGrid>\n  <AppendedData encoding=\"raw\">\n   _");
    write_atomic_with(path, |w| {
        w.write_all(xml.as_bytes())?;
        for e in &encoded {
            w.write_all(e)?;
        }
        w.write_all(b"\n  </AppendedData>\n</VTKFile>\n")
    })
}

/// Write a particle frame (see the module documentation), zlib-compressed when `compress`.
pub fn write_particles_vtu(
    path: &Path,
    p: &Particles,
    fields: &FrameFields,
    compress: bool,
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
        compress,
    )
}

mod read;
pub use read::read_appended_vtu;

#[cfg(test)]
mod tests;

/// Read a `.vtu` file whether its arrays are appended (this module's format, ParaView's
/// default) or inline (`format="binary"`, read by [`super::vtu::read_vtu`]).
pub fn read_any_vtu(path: &Path) -> Result<VtuData, VtuError> {
    // A folder, a device or a pipe (which would block this peek) is refused by the bounded
    // read of the inline reader, with its message.
    if !fs::metadata(path)?.is_file() {
        return super::vtu::read_vtu(path);
    }
    let mut head = Vec::new();
    fs::File::open(path)?.take(1 << 20).read_to_end(&mut head)?;
    if head.windows(13).any(|w| w == b"<AppendedData")
        || head.windows(17).any(|w| w == b"format=\"appended\"")
    {
        read_appended_vtu(path)
    } else {
        super::vtu::read_vtu(path)
    }
}
