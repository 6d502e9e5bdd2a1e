//! The points of a particle file (read by `rtmpm_io::points`), a body's shape when it starts
//! from a file (`[[body]] shape = "particles"`).

use glam::Vec3;
use std::path::PathBuf;

/// The points of a particle file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointSet {
    /// The file read.
    pub source: PathBuf,
    /// Positions (m).
    pub positions: Vec<Vec3>,
    /// Velocities (m/s), when the file has them.
    pub velocities: Option<Vec<Vec3>>,
    /// Volume per particle (m^3), when the file has it.
    pub volumes: Option<Vec<f32>>,
    /// Mass per particle (kg), when the file has it.
    pub masses: Option<Vec<f32>>,
}
