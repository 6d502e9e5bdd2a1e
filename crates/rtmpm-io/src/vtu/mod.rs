//! VTK XML UnstructuredGrid (`.vtu`) files, which ParaView, VTK and meshio read, and `.pvd`
//! time collections.
//!
//! One writer, [`write_unstructured`] (points, vertex or triangle cells, named point arrays),
//! with the particle frame on top of it ([`write_particles_vtu`]: one `VTK_VERTEX` cell per
//! particle, the point arrays `velocity` (3 components, the `Vectors` of the piece), `material`
//! (Int32), `id` (Int32, the particle index), `plastic`, `mass`, and when asked `J` and
//! `stress`: the Cauchy stress as a full 3x3 tensor of 9 components, ParaView's tensor
//! convention, row-major `XX XY XZ YX YY YZ ZX ZY ZZ`, the `Tensors` of the piece). Its
//! [`Encoding`]: the arrays in one `AppendedData` section (`encoding="raw"`), zlib-compressed in
//! 32 KiB blocks (`vtkZLibDataCompressor`) as ParaView itself writes them, or not; or inline
//! (`format="binary"`, base64), the simplest form for other tools.
//!
//! Readers: [`read_appended_vtu`] (appended arrays, compressed or not, `UInt32` or `UInt64`
//! headers), [`read_vtu`] / [`parse_vtu`] (inline base64 arrays), [`read_any_vtu`] (either);
//! every size in a file is checked against the bytes present before anything is allocated or
//! decompressed. [`PvdWriter`] and [`parse_pvd`]: the `.pvd` collection of a run's frames.

use std::fs;
use std::io::Read;
use std::path::Path;

mod appended;
mod data;
mod inline;
mod pvd;
#[cfg(test)]
mod tests;
mod write;

pub use appended::read_appended_vtu;
pub use data::{VtuArray, VtuData, VtuError, VtuValues};
pub use inline::{parse_vtu, read_vtu};
pub use pvd::{PvdWriter, parse_pvd};
pub use write::{CellKind, Encoding, FORMAT, OutArray, write_particles_vtu, write_unstructured};

/// Read a `.vtu` file whether its arrays are appended (this module's format, ParaView's
/// default) or inline (`format="binary"`, read by [`read_vtu`]).
pub fn read_any_vtu(path: &Path) -> Result<VtuData, VtuError> {
    // A folder, a device or a pipe (which would block this peek) is refused by the bounded
    // read of the inline reader, with its message.
    if !fs::metadata(path)?.is_file() {
        return read_vtu(path);
    }
    let mut head = Vec::new();
    fs::File::open(path)?.take(1 << 20).read_to_end(&mut head)?;
    if head.windows(13).any(|w| w == b"<AppendedData")
        || head.windows(17).any(|w| w == b"format=\"appended\"")
    {
        read_appended_vtu(path)
    } else {
        read_vtu(path)
    }
}
