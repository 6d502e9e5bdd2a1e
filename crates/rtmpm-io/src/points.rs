//! Particles in: the points of a PLY, VTU or BGEO file (positions, and velocities, volumes and
//! masses when the file has them), to start a body from (`[[body]] shape = "particles"`).
//!
//! Columns looked for, by format (the names rtmpm writes come first):
//!
//! | | PLY | VTU | BGEO |
//! | --- | --- | --- | --- |
//! | position | `x y z` | the points | `P` |
//! | velocity | `vx vy vz` | `velocity`, `v` or `Velocity` (3 components) | `v` |
//! | volume | `volume` | `volume` | `volume` |
//! | mass | `mass` | `mass` | `mass` |
//!
//! Every reader checks the file's size before reading it and the sizes its header announces
//! against the file before it allocates ([`super::limits`]); errors name the file.

use std::path::Path;

use super::bgeo::read_bgeo;
use super::ply::{PlyColumn, read_ply};
use super::vtu::{VtuData, VtuValues, read_any_vtu};
use rtmpm_geometry::PointSet;
use rtmpm_physics::math::Vec3;

/// Why a particle file could not be used; the message names the file.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct PointsError {
    /// The file.
    pub path: String,
    /// What is wrong.
    pub message: String,
}

/// Read the points of `path`, by its extension: `.ply`, `.vtu`, `.bgeo` or `.bgeo.gz`.
pub fn read_points(path: &Path) -> Result<PointSet, PointsError> {
    let err = |m: String| PointsError {
        path: path.display().to_string(),
        message: m,
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    let mut set = if name.ends_with(".ply") {
        let d = read_ply(path).map_err(|e| err(e.to_string()))?;
        let col = |n: &str| -> Option<Vec<f32>> {
            Some(match d.column(n)? {
                PlyColumn::Float(v) => v.clone(),
                PlyColumn::Double(v) => v.iter().map(|&x| x as f32).collect(),
                PlyColumn::Int(v) => v.iter().map(|&x| x as f32).collect(),
            })
        };
        let vec3 = |a: &str, b: &str, c: &str| -> Option<Vec<Vec3>> {
            let (x, y, z) = (col(a)?, col(b)?, col(c)?);
            Some((0..x.len()).map(|i| Vec3::new(x[i], y[i], z[i])).collect())
        };
        PointSet {
            positions: vec3("x", "y", "z")
                .ok_or_else(|| err("the vertex element has no x, y, z properties".into()))?,
            velocities: vec3("vx", "vy", "vz"),
            volumes: col("volume"),
            masses: col("mass"),
            ..Default::default()
        }
    } else if name.ends_with(".vtu") {
        let d = read_any_vtu(path).map_err(|e| err(e.to_string()))?;
        from_vtu(&d)
    } else if name.ends_with(".bgeo") || name.ends_with(".bgeo.gz") {
        let d = read_bgeo(path).map_err(|e| err(e.to_string()))?;
        let v3 = |v: &[f32]| {
            v.chunks_exact(3)
                .map(|c| Vec3::new(c[0], c[1], c[2]))
                .collect()
        };
        PointSet {
            positions: d.positions.iter().map(|p| Vec3::from_array(*p)).collect(),
            velocities: d.floats("v", 3).map(v3),
            volumes: d.floats("volume", 1).map(<[f32]>::to_vec),
            masses: d.floats("mass", 1).map(<[f32]>::to_vec),
            ..Default::default()
        }
    } else {
        return Err(err(
            "unknown particle file type: use .ply, .vtu, .bgeo or .bgeo.gz".into(),
        ));
    };
    set.source = path.to_path_buf();
    check(&set).map_err(err)?;
    Ok(set)
}

fn from_vtu(d: &VtuData) -> PointSet {
    let floats = |names: &[&str], ncomp: usize| -> Option<Vec<f32>> {
        let a = d
            .point_data
            .iter()
            .find(|a| names.contains(&a.name.as_str()) && a.num_components == ncomp)?;
        Some(match &a.values {
            VtuValues::Float32(v) => v.clone(),
            VtuValues::Float64(v) => v.iter().map(|&x| x as f32).collect(),
            _ => return None,
        })
    };
    PointSet {
        positions: d.points.iter().map(|p| Vec3::from_array(*p)).collect(),
        velocities: floats(&["velocity", "v", "Velocity"], 3).map(|v| {
            v.chunks_exact(3)
                .map(|c| Vec3::new(c[0], c[1], c[2]))
                .collect()
        }),
        volumes: floats(&["volume"], 1),
        masses: floats(&["mass"], 1),
        ..Default::default()
    }
}

/// Finite values, one per point, positive volumes and masses.
fn check(s: &PointSet) -> Result<(), String> {
    let n = s.positions.len();
    if let Some(i) = s.positions.iter().position(|p| !p.is_finite()) {
        return Err(format!(
            "point {i} has a non-finite position {}",
            s.positions[i]
        ));
    }
    if let Some(v) = &s.velocities {
        if v.len() != n {
            return Err(format!("{} velocities for {n} points", v.len()));
        }
        if let Some(i) = v.iter().position(|v| !v.is_finite()) {
            return Err(format!("point {i} has a non-finite velocity"));
        }
    }
    for (what, col) in [("volume", &s.volumes), ("mass", &s.masses)] {
        if let Some(c) = col {
            if c.len() != n {
                return Err(format!("{} {what} values for {n} points", c.len()));
            }
            if let Some(i) = c.iter().position(|x| !(x.is_finite() && *x > 0.0)) {
                return Err(format!(
                    "point {i} has {what} {}, not a positive number",
                    c[i]
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bgeo::tests::sample;
    use crate::bgeo::write_bgeo;
    use crate::fields::FrameFields;
    use crate::ply::write_ply;
    use crate::testing::TestDir;
    use crate::vtu::{Encoding, write_particles_vtu};
    use rtmpm_physics::Particles;
    use std::fs;

    #[test]
    fn every_format_rtmpm_writes_seeds_a_body() {
        let d = TestDir::new("points");
        let p: Particles = sample(50);
        let f = FrameFields::default();
        write_ply(&d.path("a.ply"), &p, &f).unwrap();
        write_particles_vtu(&d.path("inline.vtu"), &p, &f, Encoding::Inline).unwrap();
        write_particles_vtu(&d.path("c.vtu"), &p, &f, Encoding::Zlib).unwrap();
        write_bgeo(&d.path("b.bgeo"), &p, &f, false).unwrap();
        write_bgeo(&d.path("b.bgeo.gz"), &p, &f, true).unwrap();
        for name in ["a.ply", "inline.vtu", "c.vtu", "b.bgeo", "b.bgeo.gz"] {
            let s = read_points(&d.path(name)).unwrap();
            assert_eq!(s.positions, p.x, "{name}");
            assert_eq!(s.velocities.as_ref(), Some(&p.v), "{name}");
            assert!(s.volumes.is_none());
            if name.ends_with("ply") {
                assert!(s.masses.is_none());
            } else {
                assert_eq!(s.masses.as_ref(), Some(&p.mass), "{name}");
            }
        }
    }

    #[test]
    fn bad_files_name_the_file() {
        let d = TestDir::new("points-bad");
        let e = read_points(&d.path("x.xyz")).unwrap_err().to_string();
        assert!(e.contains("x.xyz") && e.contains(".bgeo"), "{e}");
        let e = read_points(&d.path("missing.ply")).unwrap_err().to_string();
        assert!(e.contains("missing.ply"), "{e}");
        // A PLY header announcing a billion vertices in a few bytes.
        let path = d.path("huge.ply");
        fs::write(&path, b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n").unwrap();
        let e = read_points(&path).unwrap_err().to_string();
        assert!(e.contains("huge.ply") && e.contains("truncated"), "{e}");
        // No positions.
        let path = d.path("nox.ply");
        fs::write(&path, b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float a\nend_header\n\0\0\0\0").unwrap();
        assert!(
            read_points(&path)
                .unwrap_err()
                .to_string()
                .contains("x, y, z")
        );
        // Non-finite values.
        let mut p = sample(3);
        p.x[1].y = f32::NAN;
        write_bgeo(&d.path("nan.bgeo"), &p, &FrameFields::default(), false).unwrap();
        let e = read_points(&d.path("nan.bgeo")).unwrap_err().to_string();
        assert!(e.contains("nan.bgeo") && e.contains("point 1"), "{e}");
        // Garbage with a known extension.
        fs::write(d.path("g.vtu"), b"hello").unwrap();
        assert!(
            read_points(&d.path("g.vtu"))
                .unwrap_err()
                .to_string()
                .contains("g.vtu")
        );
    }

    /// A folder or a named pipe with a particle file's name is refused at once, by the bounded
    /// reads of `io::limits` (the VTU type sniffing must not open a pipe: that blocks).
    #[test]
    fn folders_and_pipes_are_refused_at_once() {
        let d = TestDir::new("points-special");
        let t = std::time::Instant::now();
        for name in ["dir.ply", "dir.vtu", "dir.bgeo", "dir.bgeo.gz"] {
            fs::create_dir(d.path(name)).unwrap();
            let e = read_points(&d.path(name)).unwrap_err().to_string();
            assert!(e.contains(name) && e.contains("is a folder"), "{e}");
        }
        for name in ["pipe.ply", "pipe.vtu", "pipe.bgeo"] {
            let fifo = d.path(name);
            if std::process::Command::new("mkfifo")
                .arg(&fifo)
                .status()
                .is_ok_and(|s| s.success())
            {
                let e = read_points(&fifo).unwrap_err().to_string();
                assert!(e.contains(name) && e.contains("a pipe"), "{e}");
            }
        }
        assert!(t.elapsed().as_secs_f64() < 5.0);
    }
}
