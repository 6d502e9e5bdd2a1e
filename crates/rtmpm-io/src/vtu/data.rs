//! What the readers give ([`VtuData`]: the arrays of a piece), their error, and the XML and
//! value decoding they share.

use std::io;

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

pub(super) fn format_err(msg: impl Into<String>) -> VtuError {
    VtuError::Format(msg.into())
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

/// The content of a `.vtu` file (single piece).
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

pub(super) fn xml_escape(s: &str) -> String {
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
