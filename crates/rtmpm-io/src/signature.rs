//! rtmpm's signature in the files it writes, so that a command that removes files (`rtmpm run
//! --overwrite`) removes only files it can prove rtmpm wrote: a comment or metadata field in
//! the header of every text or self-describing format, the magic bytes of a checkpoint, the
//! exact header of `bodies.csv`. Houdini's classic BGEO and an MP4 from ffmpeg carry none
//! ([`signature_of`] says so); the caller decides about them (an output folder's run marker).

use std::io::Read;
use std::path::Path;

/// The XML comment after `<?xml ...?>` of every `.vtu` and `.pvd` rtmpm writes.
pub const XML_COMMENT: &str = "<!-- written by rtmpm -->";
/// The `doc` layer metadata of every `.usda` rtmpm writes.
pub const USD_DOC: &str = "written by rtmpm";
/// The PNG `tEXt` chunk (keyword, text) of every picture rtmpm writes.
pub const PNG_TEXT: (&str, &str) = ("Software", "rtmpm");
/// The GIF comment extension of every movie rtmpm writes.
pub const GIF_COMMENT: &[u8] = b"written by rtmpm";
/// The header line of `bodies.csv`.
pub const BODIES_CSV_HEADER: &str = "frame,time,body,x,y,z,qx,qy,qz,qw,vx,vy,vz,wx,wy,wz";
/// The prefix of the PLY comments rtmpm writes (`rtmpm particles`, `rtmpm fluid surface`,
/// `rtmpm-run ...`).
pub const PLY_COMMENT: &[u8] = b"\ncomment rtmpm";
/// The first line of every surface `.obj` rtmpm writes starts with this.
pub const OBJ_COMMENT: &[u8] = b"# rtmpm";
/// Bytes read from the start of a file to find its signature: the signatures are all in the
/// first lines (headers), the PNG and GIF ones before the image data.
pub const HEAD_BYTES: usize = 64 * 1024;

/// What the start of a file says about who wrote it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Signature {
    /// It carries rtmpm's signature.
    Rtmpm,
    /// Its format carries one when rtmpm writes it, and this file has none.
    Absent,
    /// Its format carries none (BGEO, MP4): the start of the file cannot tell.
    Unsigned,
}

fn contains(hay: &[u8], needle: &[u8]) -> bool {
    hay.windows(needle.len()).any(|w| w == needle)
}

/// The signature of a file named `name` whose first bytes are `head` (at most
/// [`HEAD_BYTES`] of them).
pub fn signature_of(name: &str, head: &[u8]) -> Signature {
    let ext = name.split_once('.').map_or("", |(_, e)| e);
    let signed = match ext {
        "ply" => head.starts_with(b"ply") && contains(head, PLY_COMMENT),
        "obj" => head.starts_with(OBJ_COMMENT),
        "vtu" | "pvd" => contains(head, XML_COMMENT.as_bytes()),
        "usda" => {
            head.starts_with(b"#usda") && contains(head, format!("doc = \"{USD_DOC}").as_bytes())
        }
        "png" => {
            let text = [PNG_TEXT.0.as_bytes(), b"\0", PNG_TEXT.1.as_bytes()].concat();
            head.starts_with(b"\x89PNG") && contains(head, &text)
        }
        "gif" => head.starts_with(b"GIF8") && contains(head, GIF_COMMENT),
        "ckpt" => head.starts_with(&super::checkpoint::MAGIC),
        "csv" => head.starts_with(BODIES_CSV_HEADER.as_bytes()),
        _ => return Signature::Unsigned,
    };
    if signed {
        Signature::Rtmpm
    } else {
        Signature::Absent
    }
}

/// [`signature_of`] the file at `path` (its first [`HEAD_BYTES`]).
pub fn signature_of_file(path: &Path) -> std::io::Result<Signature> {
    let mut head = Vec::with_capacity(HEAD_BYTES);
    std::fs::File::open(path)?
        .take(HEAD_BYTES as u64)
        .read_to_end(&mut head)?;
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    Ok(signature_of(name, &head))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signatures_by_format() {
        let ply = b"ply\nformat binary_little_endian 1.0\ncomment rtmpm particles\nend_header\n";
        assert_eq!(signature_of("frame_00001.ply", ply), Signature::Rtmpm);
        let foreign = b"ply\nformat binary_little_endian 1.0\ncomment Blender\nend_header\n";
        assert_eq!(signature_of("frame_00001.ply", foreign), Signature::Absent);
        assert_eq!(
            signature_of("frame_00001.vtu", b"<?xml version=\"1.0\"?>\n<VTKFile>"),
            Signature::Absent
        );
        let vtu = format!("<?xml version=\"1.0\"?>\n{XML_COMMENT}\n<VTKFile>");
        assert_eq!(
            signature_of("surface.pvd", vtu.as_bytes()),
            Signature::Rtmpm
        );
        assert_eq!(
            signature_of("frame_00001.bgeo.gz", b"\x1f\x8b"),
            Signature::Unsigned
        );
        assert_eq!(signature_of("movie.mp4", b""), Signature::Unsigned);
        assert_eq!(
            signature_of("bodies.csv", format!("{BODIES_CSV_HEADER}\n0,0").as_bytes()),
            Signature::Rtmpm
        );
        assert_eq!(signature_of("bodies.csv", b"a,b\n"), Signature::Absent);
        assert_eq!(
            signature_of("checkpoint_00001.ckpt", b"RTMPMCKP\x02"),
            Signature::Rtmpm
        );
    }
}
