//! Output and checkpoint files. Every file is written to a temporary name and renamed
//! (see [`atomic`]).
//!
//! * [`ply`]: binary little-endian PLY point clouds (one vertex per particle).
//! * [`bgeo`]: Houdini's classic binary geometry (`.bgeo`, `.bgeo.gz`) with point attributes.
//! * [`vtu`]: VTK XML UnstructuredGrid (`.vtu`) for ParaView: one writer (appended arrays,
//!   zlib-compressed or raw, or inline base64; 3x3 stress tensors), used for particle frames and
//!   surface meshes, its readers, and `.pvd` collections.
//! * [`trimesh`]: surface meshes as OBJ, PLY and VTU.
//! * [`points`]: particles in: the points of a PLY, VTU or BGEO file for a body.
//! * [`obj`]: triangle meshes in: OBJ files.
//! * [`usd`]: USD text files (`.usda`): particles as `Points`, surfaces as `Mesh`.
//! * [`frame`], [`FRAME_FORMATS`]: the particle frame formats, each a module with its writer
//!   and one line of the registry.
//! * [`chunks`], [`stream`]: frames in chunks of particles (the layout a backend fills through
//!   `rtmpm_sim::ChunkSink`), streamed to PLY and BGEO files while the simulation goes on.
//! * [`checkpoint`]: bit-exact binary checkpoints with a checksum.
//! * [`limits`]: bounded reads (sizes checked before allocating) shared by every reader.
//! * [`contents`]: checks of the values read (finite, positive, in range, inside the domain).

pub mod atomic;
pub mod bgeo;
pub mod checkpoint;
pub mod chunks;
pub mod contents;
pub mod fields;
pub mod frame;
#[cfg(all(test, feature = "interop"))]
mod interop_tests;
pub mod limits;
pub mod obj;
pub mod ply;
pub mod points;
pub mod signature;
pub mod stream;
#[cfg(any(test, feature = "testing"))]
pub mod testing;
pub mod trimesh;
pub mod usd;
pub mod vtu;

pub use atomic::{write_atomic, write_atomic_with};
pub use bgeo::{BgeoData, BgeoError, read_bgeo, write_bgeo};
pub use checkpoint::{Checkpoint, CheckpointError};
pub use contents::{BadValue, check_particle_values, check_particles, check_particles_in_domain};
pub use fields::FrameFields;
pub use limits::{read_bounded, read_text_bounded};
pub use ply::{PlyColumn, PlyData, PlyError, read_ply, write_ply, write_ply_with_comments};
pub use vtu::{
    Encoding, PvdWriter, VtuArray, VtuData, VtuError, VtuValues, read_any_vtu, read_vtu,
    write_particles_vtu,
};

use frame::FrameFormat;

/// Every particle frame format, in the order a frame's files are written. A format is a module
/// with its writer and a `FORMAT` ([`FrameFormat`]), and one line here.
pub static FRAME_FORMATS: &[&FrameFormat] = &[
    &ply::FORMAT,
    &bgeo::FORMAT,
    &bgeo::FORMAT_GZ,
    &usd::FORMAT,
    &vtu::FORMAT,
];

/// The frame format named `name` (`[output] formats`).
pub fn frame_format(name: &str) -> Option<&'static FrameFormat> {
    FRAME_FORMATS.iter().copied().find(|f| f.name == name)
}

/// The frame format of a file name, by its extension (the longest that matches:
/// `x.bgeo.gz` is `bgeo.gz`).
pub fn frame_format_of(file_name: &str) -> Option<&'static FrameFormat> {
    FRAME_FORMATS
        .iter()
        .copied()
        .filter(|f| {
            file_name
                .strip_suffix(f.extension)
                .is_some_and(|stem| stem.ends_with('.'))
        })
        .max_by_key(|f| f.extension.len())
}

/// The names of the frame formats, quoted and comma-separated (for messages).
pub fn frame_format_names() -> String {
    let names: Vec<String> = FRAME_FORMATS
        .iter()
        .map(|f| format!("\"{}\"", f.name))
        .collect();
    names.join(", ")
}
