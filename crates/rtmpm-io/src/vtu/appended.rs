//! Reading VTK XML UnstructuredGrid files with appended raw data, compressed or not.

use std::io::Read;
use std::path::Path;

use super::data::{VtuArray, VtuData, VtuError, VtuValues, attr, parse_values, xml_unescape};
use crate::limits::{DATA_MAX_BYTES, decompressed_limit, read_bounded};

fn bad(msg: impl Into<String>) -> VtuError {
    VtuError::Format(msg.into())
}

/// How the appended arrays are framed.
#[derive(Clone, Copy)]
struct Framing {
    /// Bytes of a header integer: 4 (`UInt32`) or 8 (`UInt64`).
    word: usize,
    compressed: bool,
}

impl Framing {
    fn int(&self, data: &[u8], at: usize, what: &str) -> Result<u64, VtuError> {
        let b = at
            .checked_add(self.word)
            .and_then(|e| data.get(at..e))
            .ok_or_else(|| {
                bad(format!(
                    "{what}: the appended data ends inside a header (truncated file?)"
                ))
            })?;
        Ok(if self.word == 4 {
            u32::from_le_bytes(b.try_into().unwrap()) as u64
        } else {
            u64::from_le_bytes(b.try_into().unwrap())
        })
    }

    /// The decoded bytes of the array at `offset` of the appended `data`.
    fn decode(&self, data: &[u8], offset: usize, what: &str) -> Result<Vec<u8>, VtuError> {
        let too_long = || {
            bad(format!(
                "{what}: its sizes run past the end of the file (truncated file?)"
            ))
        };
        if !self.compressed {
            let n = self.int(data, offset, what)?;
            let start = offset + self.word;
            let end = usize::try_from(n)
                .ok()
                .and_then(|n| start.checked_add(n))
                .filter(|&e| e <= data.len())
                .ok_or_else(too_long)?;
            return Ok(data[start..end].to_vec());
        }
        let nblocks = self.int(data, offset, what)?;
        let block = self.int(data, offset + self.word, what)?;
        let last = self.int(data, offset + 2 * self.word, what)?;
        // Each block needs a size word; more blocks than bytes left cannot be true.
        let nblocks = usize::try_from(nblocks)
            .ok()
            .filter(|&k| k <= (data.len() - offset) / self.word)
            .ok_or_else(too_long)?;
        let mut sizes = Vec::with_capacity(nblocks);
        for k in 0..nblocks {
            sizes.push(self.int(data, offset + (3 + k) * self.word, what)?);
        }
        let mut pos = offset + (3 + nblocks) * self.word;
        let total_in = sizes
            .iter()
            .try_fold(pos as u64, |a, &s| a.checked_add(s))
            .filter(|&end| end <= data.len() as u64)
            .ok_or_else(too_long)?
            - pos as u64;
        let total_out = match nblocks {
            0 => 0,
            k => (k as u64 - 1)
                .checked_mul(block)
                .and_then(|s| s.checked_add(last))
                .ok_or_else(|| bad(format!("{what}: block sizes overflow")))?,
        };
        if last > block || total_out > decompressed_limit(total_in) {
            return Err(bad(format!(
                "{what}: the header claims {total_out} bytes from {total_in} compressed bytes \
                 (corrupt header, or more than the memory available)"
            )));
        }
        let mut out = Vec::with_capacity(total_out as usize);
        for (k, &size) in sizes.iter().enumerate() {
            let want = if k + 1 == nblocks { last } else { block };
            let src = &data[pos..pos + size as usize];
            pos += size as usize;
            let before = out.len();
            flate2::read::ZlibDecoder::new(src)
                .take(want + 1)
                .read_to_end(&mut out)
                .map_err(|e| bad(format!("{what}: block {k} is not valid zlib data: {e}")))?;
            if (out.len() - before) as u64 != want {
                return Err(bad(format!(
                    "{what}: block {k} holds {} bytes, the header says {want}",
                    out.len() - before
                )));
            }
        }
        Ok(out)
    }
}

/// Read a `.vtu` file whose arrays are in an `AppendedData` section with raw encoding
/// (ParaView's default, and [`super::write_particles_vtu`]'s), compressed with zlib or not.
/// Only the first piece is read; `Points`, `Cells` and `PointData` arrays are returned.
pub fn read_appended_vtu(path: &Path) -> Result<VtuData, VtuError> {
    let bytes = read_bounded(path, DATA_MAX_BYTES, "VTU file")?;
    parse_appended(&bytes)
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// Parse a VTU file of appended arrays: the XML header, the framing of the appended data, then
/// the first piece's arrays read one by one and placed ([`read_array`], [`place`]).
pub(super) fn parse_appended(bytes: &[u8]) -> Result<VtuData, VtuError> {
    let (text, data) = split_appended(bytes)?;
    let framing = framing_of(text)?;
    let piece = text
        .find("<Piece")
        .ok_or_else(|| bad("no <Piece> element"))?;
    let piece_tag = &text[piece..piece + text[piece..].find('>').unwrap_or(0)];
    let count = |name: &str| -> Result<usize, VtuError> {
        attr(piece_tag, name)
            .and_then(|v| v.trim().parse().ok())
            .ok_or_else(|| bad(format!("<Piece> has no valid {name}")))
    };
    let mut out = VtuData {
        num_points: count("NumberOfPoints")?,
        num_cells: count("NumberOfCells")?,
        ..Default::default()
    };
    let mut section = "";
    let mut have_points = false;
    let mut pos = piece;
    while let Some(off) = text[pos..].find('<') {
        let start = pos + off;
        let end = start
            + text[start..]
                .find('>')
                .ok_or_else(|| bad("unterminated tag"))?;
        let tag = &text[start + 1..end];
        pos = end + 1;
        let name = tag.split_whitespace().next().unwrap_or("");
        match name {
            "Points" | "Cells" | "PointData" => section = name,
            "/Points" | "/Cells" | "/PointData" | "CellData" | "/CellData" | "FieldData"
            | "/FieldData" => section = "",
            "/Piece" => break,
            "DataArray" if !section.is_empty() => {
                let array = read_array(tag, data, &framing)?;
                have_points |= place(array, section, &mut out)?;
            }
            _ => {}
        }
    }
    if !have_points && out.num_points > 0 {
        return Err(bad("missing <Points> array"));
    }
    Ok(out)
}

/// The XML before `<AppendedData>` and the appended bytes after its `_` marker (raw encoding
/// only).
fn split_appended(bytes: &[u8]) -> Result<(&str, &[u8]), VtuError> {
    let app = find(bytes, b"<AppendedData")
        .ok_or_else(|| bad("no <AppendedData> section (arrays are not appended)"))?;
    let text = std::str::from_utf8(&bytes[..app])
        .map_err(|_| bad("the XML before <AppendedData> is not UTF-8"))?;
    let tag_end =
        find(&bytes[app..], b">").ok_or_else(|| bad("unterminated <AppendedData> tag"))?;
    let app_tag = std::str::from_utf8(&bytes[app..app + tag_end]).unwrap_or("");
    match attr(app_tag, "encoding") {
        Some("raw") => {}
        other => {
            return Err(bad(format!(
                "AppendedData encoding {other:?} is not supported (only \"raw\")"
            )));
        }
    }
    let underscore = find(&bytes[app + tag_end..], b"_")
        .ok_or_else(|| bad("no `_` marking the start of the appended data"))?;
    Ok((text, &bytes[app + tag_end + underscore + 1..]))
}

/// The framing of the appended arrays from the `<VTKFile>` element: header word size and
/// compression (an UnstructuredGrid, little-endian, zlib or uncompressed).
fn framing_of(text: &str) -> Result<Framing, VtuError> {
    let root = text
        .find("<VTKFile")
        .ok_or_else(|| bad("no <VTKFile> element"))?;
    let root_tag = &text[root..root + text[root..].find('>').unwrap_or(0)];
    if attr(root_tag, "type") != Some("UnstructuredGrid") {
        return Err(bad("not an UnstructuredGrid file"));
    }
    if attr(root_tag, "byte_order") != Some("LittleEndian") {
        return Err(bad("only byte_order=\"LittleEndian\" is supported"));
    }
    let word = match attr(root_tag, "header_type").unwrap_or("UInt32") {
        "UInt32" => 4,
        "UInt64" => 8,
        other => return Err(bad(format!("header_type {other} is not supported"))),
    };
    let compressed = match attr(root_tag, "compressor") {
        None => false,
        Some("vtkZLibDataCompressor") => true,
        Some(other) => {
            return Err(bad(format!(
                "compressor {other} is not supported (only vtkZLibDataCompressor)"
            )));
        }
    };
    Ok(Framing { word, compressed })
}

/// The array of a `<DataArray>` tag, its values decoded from the appended `data`.
fn read_array(tag: &str, data: &[u8], framing: &Framing) -> Result<VtuArray, VtuError> {
    let aname = attr(tag, "Name").map(xml_unescape).unwrap_or_default();
    let what = format!("array `{aname}`");
    if attr(tag, "format") != Some("appended") {
        return Err(bad(format!(
            "{what}: only format=\"appended\" arrays are read here"
        )));
    }
    let offset: usize = attr(tag, "offset")
        .and_then(|o| o.trim().parse().ok())
        .ok_or_else(|| bad(format!("{what}: no valid offset")))?;
    let ty = attr(tag, "type").ok_or_else(|| bad(format!("{what}: no type")))?;
    let ncomp: usize = match attr(tag, "NumberOfComponents") {
        Some(c) => c
            .trim()
            .parse()
            .ok()
            .filter(|&c| (1..=64).contains(&c))
            .ok_or_else(|| bad(format!("{what}: bad NumberOfComponents {c}")))?,
        None => 1,
    };
    let raw = framing.decode(data, offset, &what)?;
    let values = parse_values(ty, &raw).map_err(|e| bad(format!("{what}: {e}")))?;
    Ok(VtuArray {
        name: aname,
        num_components: ncomp,
        values,
    })
}

/// Put `array` of `section` (`Points`, `Cells` or `PointData`) into `out`, its size checked
/// against the piece's; true when it was the points.
fn place(array: VtuArray, section: &str, out: &mut VtuData) -> Result<bool, VtuError> {
    let ncomp = array.num_components;
    match section {
        "Points" => {
            let flat: Vec<f32> = match &array.values {
                VtuValues::Float32(v) => v.clone(),
                VtuValues::Float64(v) => v.iter().map(|&x| x as f32).collect(),
                _ => return Err(bad("Points must be Float32 or Float64")),
            };
            if ncomp != 3 || flat.len() != 3 * out.num_points {
                return Err(bad(format!(
                    "Points has {} values, expected 3 x {}",
                    flat.len(),
                    out.num_points
                )));
            }
            out.points = flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
            return Ok(true);
        }
        "Cells" => out.cells.push(array),
        _ => {
            if array.values.len() != ncomp * out.num_points {
                return Err(bad(format!(
                    "point array {} has {} values, expected {ncomp} x {}",
                    array.name,
                    array.values.len(),
                    out.num_points
                )));
            }
            out.point_data.push(array);
        }
    }
    Ok(false)
}
