//! `.pvd` collections: the frames of a run with their times, for ParaView's time series.

use std::io;
use std::path::{Path, PathBuf};

use super::data::{VtuError, attr, format_err, xml_escape, xml_unescape};
use crate::atomic::write_atomic;
use crate::limits::{PVD_MAX_BYTES, read_text_bounded};

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
        s.push_str(crate::signature::XML_COMMENT);
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
