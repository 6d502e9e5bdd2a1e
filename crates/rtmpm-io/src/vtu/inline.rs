//! Reading `.vtu` files whose arrays are inline (`format="binary"`: base64 of a `UInt64` byte
//! count, then of the data).

use std::path::Path;

use base64::Engine;
use base64::engine::general_purpose::STANDARD;

use super::data::{
    VtuArray, VtuData, VtuError, VtuValues, attr, format_err, parse_values, xml_unescape,
};
use crate::limits::{DATA_MAX_BYTES, read_text_bounded};

/// Decode inline base64 binary data with a `UInt64` header. Accepts the header encoded
/// separately (as VTK and [`super::write_unstructured`] do) or together with the data.
pub(super) fn decode_binary(text: &str) -> Result<Vec<u8>, VtuError> {
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

/// Read a `.vtu` file with inline arrays ([`Encoding::Inline`](super::Encoding)): one piece, inline
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
