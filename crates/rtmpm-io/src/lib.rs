//! Output and checkpoint files. Every file is written to a temporary name and renamed
//! (see [`atomic`]).
//!
//! * [`ply`]: binary little-endian PLY point clouds (one vertex per particle).
//! * [`bgeo`]: Houdini's classic binary geometry (`.bgeo`, `.bgeo.gz`) with point attributes.
//! * [`vtu`]: VTK XML UnstructuredGrid (`.vtu`, base64 binary) and `.pvd` collections.
//! * [`vtk_appended`]: ParaView-grade `.vtu` (zlib-compressed appended arrays, 3x3 stress
//!   tensors), also for surface meshes.
//! * [`trimesh`]: surface meshes as OBJ, PLY and VTU.
//! * [`points`]: particles in: the points of a PLY, VTU or BGEO file for a body.
//! * [`obj`]: triangle meshes in: OBJ files.
//! * [`usd`]: USD text files (`.usda`): particles as `Points`, surfaces as `Mesh`.
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
#[cfg(all(test, feature = "interop"))]
mod interop_tests;
pub mod limits;
pub mod obj;
pub mod ply;
pub mod points;
pub mod stream;
#[cfg(any(test, feature = "testing"))]
pub mod testing;
pub mod trimesh;
pub mod usd;
pub mod vtk_appended;
pub mod vtu;

pub use atomic::{write_atomic, write_atomic_with};
pub use bgeo::{BgeoData, BgeoError, read_bgeo, write_bgeo};
pub use checkpoint::{Checkpoint, CheckpointError};
pub use contents::{BadValue, check_particle_values, check_particles_in_domain};
pub use limits::{read_bounded, read_text_bounded};
pub use ply::{PlyColumn, PlyData, PlyError, read_ply, write_ply, write_ply_with_comments};
pub use vtu::{PvdWriter, VtuArray, VtuData, VtuError, VtuValues, read_vtu, write_vtu};

/// Optional per-particle fields written next to the particle state in output frames. They are
/// computed by the caller (e.g. from the material model); each slice, when present, must have
/// one entry per particle.
#[derive(Clone, Copy, Debug, Default)]
pub struct FrameFields<'a> {
    /// Cauchy stress per particle, symmetric, stored as `[xx, yy, zz, xy, yz, xz]` (Pa).
    pub stress: Option<&'a [[f32; 6]]>,
    /// Volume ratio `J = det F` per particle.
    pub jacobian: Option<&'a [f32]>,
}

impl FrameFields<'_> {
    /// Check that every present field has `n` entries.
    pub(crate) fn check_len(&self, n: usize) -> std::io::Result<()> {
        let bad = |what: &str, len: usize| {
            Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!("{what} has {len} entries, expected {n} (one per particle)"),
            ))
        };
        match self.stress {
            Some(s) if s.len() != n => return bad("stress", s.len()),
            _ => {}
        }
        match self.jacobian {
            Some(j) if j.len() != n => return bad("jacobian", j.len()),
            _ => {}
        }
        Ok(())
    }
}

/// Check that every array of `p` has `p.len()` entries (a malformed particle set would otherwise
/// produce a file that lies about its size).
pub fn check_particles(p: &rtmpm_physics::Particles) -> std::io::Result<()> {
    let n = p.len();
    let lens = [
        ("v", p.v.len()),
        ("c", p.c.len()),
        ("f", p.f.len()),
        ("plastic", p.plastic.len()),
        ("mass", p.mass.len()),
        ("vol0", p.vol0.len()),
        ("material", p.material.len()),
    ];
    for (name, len) in lens {
        if len != n {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!("particle array {name} has {len} entries, x has {n}"),
            ));
        }
    }
    Ok(())
}
