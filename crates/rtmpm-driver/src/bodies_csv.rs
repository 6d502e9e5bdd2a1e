//! `bodies.csv`: the rigid bodies' poses and velocities at every frame of a run.

use crate::simulation::Simulation;
use anyhow::{Context, Result};

/// `bodies.csv` in the output folder: the pose and velocities of every rigid body at every
/// frame (`[[rigid_body]]`; nothing when the scene has none).
pub struct BodiesCsv {
    file: Option<std::io::BufWriter<std::fs::File>>,
    names: Vec<String>,
}

impl BodiesCsv {
    /// The file, new (none when `writes` is false or the scene has no rigid bodies); or,
    /// resuming at frame `resumed_at`, the rows of a previous run's file up to that frame kept
    /// (the rows of later frames are written again).
    pub fn new(
        writes: bool,
        dir: &std::path::Path,
        sim: &Simulation,
        resumed_at: Option<u64>,
    ) -> Result<BodiesCsv> {
        let names: Vec<String> = sim
            .scene
            .rigid_bodies
            .iter()
            .map(|b| b.name.clone())
            .collect();
        if !writes || names.is_empty() {
            return Ok(BodiesCsv { file: None, names });
        }
        use std::io::Write;
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create output folder {}", dir.display()))?;
        let path = dir.join("bodies.csv");
        let kept: Vec<String> = match resumed_at {
            Some(at) => std::fs::read_to_string(&path)
                .unwrap_or_default()
                .lines()
                .skip(1)
                .filter(|l| {
                    l.split(',')
                        .next()
                        .and_then(|f| f.parse::<u64>().ok())
                        .is_some_and(|f| f <= at)
                })
                .map(str::to_string)
                .collect(),
            None => Vec::new(),
        };
        let mut f = std::io::BufWriter::new(
            std::fs::File::create(&path)
                .with_context(|| format!("cannot write {}", path.display()))?,
        );
        writeln!(f, "frame,time,body,x,y,z,qx,qy,qz,qw,vx,vy,vz,wx,wy,wz")?;
        for l in kept {
            writeln!(f, "{l}")?;
        }
        Ok(BodiesCsv {
            file: Some(f),
            names,
        })
    }

    /// The rows of frame `frame` at `time`.
    pub fn write(&mut self, frame: u64, time: f64, sim: &Simulation) -> Result<()> {
        let Some(f) = self.file.as_mut() else {
            return Ok(());
        };
        use std::io::Write;
        for (b, name) in sim.backend.rigid_bodies().iter().zip(&self.names) {
            let q = glam::Quat::from_mat3(&b.rotation);
            let (c, v, w) = (b.center, b.velocity, b.angular_velocity);
            writeln!(
                f,
                "{frame},{time},{name:?},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                c.x, c.y, c.z, q.x, q.y, q.z, q.w, v.x, v.y, v.z, w.x, w.y, w.z
            )?;
        }
        f.flush()?;
        Ok(())
    }
}
