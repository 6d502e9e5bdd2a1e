//! The particles of one frame as the render thread receives them: from memory or from a PLY
//! frame, with the surface materials taken out of the splats.

use anyhow::{Context, Result, anyhow, bail};
use rtmpm_geometry::surface::{SurfaceParams, TriMesh};
use rtmpm_io::ply::PlyData;
use rtmpm_physics::Particles;
use rtmpm_physics::math::Vec3;
use rtmpm_render::von_mises;
use rtmpm_scene::{ColorBy, Scene, SurfaceSettings};
use std::path::Path;

/// The surface of a frame: none, ready, or to be reconstructed on the render thread from
/// these positions.
pub enum SurfaceJob {
    None,
    Ready(TriMesh, u32),
    Build(Vec<Vec3>, SurfaceParams, u32),
}

/// The particles of one frame, owned (sent to the render thread).
pub struct FrameJob {
    pub(super) frame: u64,
    pub(super) time: Option<f64>,
    pub(super) positions: Vec<Vec3>,
    pub(super) material: Vec<u32>,
    pub(super) field: Option<Vec<f32>>,
    pub(super) surface: SurfaceJob,
    /// The rigid bodies at this frame, as motionless colliders (drawn with the colliders).
    pub(super) bodies: Vec<rtmpm_geometry::Collider>,
}

impl FrameJob {
    /// Take the particles of the surface materials out of the splats and arrange their
    /// surface: `mesh` when given, else reconstructed on the render thread from them with
    /// particles of mean volume `volume`.
    pub(super) fn with_surface(
        mut self,
        settings: &SurfaceSettings,
        volume: f32,
        mesh: Option<TriMesh>,
    ) -> FrameJob {
        let Some(&first) = settings.materials.first() else {
            return self;
        };
        let keep: Vec<bool> = self
            .material
            .iter()
            .map(|m| !settings.materials.contains(m))
            .collect();
        let pick = |v: &[Vec3]| -> Vec<Vec3> {
            v.iter()
                .zip(&keep)
                .filter(|(_, k)| !**k)
                .map(|(x, _)| *x)
                .collect()
        };
        self.surface = match mesh {
            Some(m) => SurfaceJob::Ready(m, first),
            None => SurfaceJob::Build(pick(&self.positions), settings.params(volume), first),
        };
        let mut k = keep.iter();
        self.positions.retain(|_| *k.next().unwrap_or(&true));
        let mut k = keep.iter();
        self.material.retain(|_| *k.next().unwrap_or(&true));
        if let Some(f) = self.field.as_mut() {
            let mut k = keep.iter();
            f.retain(|_| *k.next().unwrap_or(&true));
        }
        self
    }
}

impl FrameJob {
    /// From particles in memory; the field is computed here (stress needs the scene).
    pub fn from_particles(
        frame: u64,
        time: f64,
        p: &Particles,
        scene: &Scene,
        color_by: ColorBy,
    ) -> FrameJob {
        let field = rtmpm_render::particle_field(p, scene, color_by);
        FrameJob {
            frame,
            time: Some(time),
            positions: p.x.clone(),
            material: p.material.clone(),
            field,
            surface: SurfaceJob::None,
            bodies: Vec::new(),
        }
    }

    /// Draw the rigid bodies `bodies` (their states at this frame) too.
    pub fn with_bodies(mut self, bodies: &[rtmpm_rigid::BodyState]) -> FrameJob {
        self.bodies = bodies.iter().map(|b| b.collider()).collect();
        self
    }

    /// From a PLY frame written by `rtmpm run`; a missing column is an error with a hint.
    pub(super) fn from_ply(
        frame: u64,
        d: &PlyData,
        color_by: ColorBy,
        path: &Path,
    ) -> Result<FrameJob> {
        let col = |name: &str| -> Result<&[f32]> {
            d.f32(name).ok_or_else(|| {
                let hint = match name {
                    "J" => " (add fields = [\"J\"] to the scene's [output] table and run again)",
                    s if s.starts_with('s') => {
                        " (add fields = [\"stress\"] to the scene's [output] table and run again)"
                    }
                    _ => "",
                };
                anyhow!("{} has no float column `{name}`{hint}", path.display())
            })
        };
        let (x, y, z) = (col("x")?, col("y")?, col("z")?);
        let positions: Vec<Vec3> = (0..d.count).map(|i| Vec3::new(x[i], y[i], z[i])).collect();
        let material: Vec<u32> = match d.int("material") {
            Some(m) => m
                .iter()
                .map(|&m| m.clamp(0, u32::MAX as i64) as u32)
                .collect(),
            None => vec![0; d.count],
        };
        let field = match color_by {
            ColorBy::Material => None,
            ColorBy::Speed => {
                let (vx, vy, vz) = (col("vx")?, col("vy")?, col("vz")?);
                Some(
                    (0..d.count)
                        .map(|i| Vec3::new(vx[i], vy[i], vz[i]).length())
                        .collect(),
                )
            }
            ColorBy::J => Some(col("J")?.to_vec()),
            ColorBy::Plastic => Some(col("plastic")?.to_vec()),
            ColorBy::Stress => {
                let c: Vec<&[f32]> = ["sxx", "syy", "szz", "sxy", "syz", "sxz"]
                    .into_iter()
                    .map(col)
                    .collect::<Result<_>>()?;
                Some(
                    (0..d.count)
                        .map(|i| von_mises([c[0][i], c[1][i], c[2][i], c[3][i], c[4][i], c[5][i]]))
                        .collect(),
                )
            }
        };
        Ok(FrameJob {
            frame,
            time: None,
            positions,
            material,
            field,
            surface: SurfaceJob::None,
            bodies: Vec::new(),
        })
    }
}

/// The rigid bodies of every frame from a run's `bodies.csv` (written by `rtmpm run`: `frame,
/// time, body, x, y, z, qx, qy, qz, qw, ...`, one row per body and frame, bodies in the scene's
/// order), their shapes from `scene`. A bad row is an error naming the file and line.
pub(super) fn read_bodies_csv(
    path: &Path,
    scene: &Scene,
) -> Result<std::collections::HashMap<u64, Vec<rtmpm_rigid::BodyState>>> {
    use rtmpm_rigid::{BodyState, RigidKind};
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let mut frames: std::collections::HashMap<u64, Vec<BodyState>> = Default::default();
    for (i, line) in text.lines().enumerate().skip(1) {
        let at = || format!("{}:{}", path.display(), i + 1);
        if line.trim().is_empty() {
            continue;
        }
        let cols: Vec<&str> = line.split(',').collect();
        let num = |k: usize| -> Result<f32> {
            cols.get(k)
                .and_then(|c| c.trim().parse::<f32>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| anyhow!("{}: column {} is not a number: {line}", at(), k + 1))
        };
        let frame: u64 = cols
            .first()
            .and_then(|c| c.trim().parse().ok())
            .ok_or_else(|| anyhow!("{}: no frame number: {line}", at()))?;
        let list = frames.entry(frame).or_default();
        let Some(spec) = scene.rigid_bodies.get(list.len()) else {
            bail!(
                "{}: more bodies in frame {frame} than the scene's {} [[rigid_body]] tables\n  \
                 fix: give the scene the run was made with (--scene)",
                at(),
                scene.rigid_bodies.len()
            );
        };
        let q = glam::Quat::from_xyzw(num(6)?, num(7)?, num(8)?, num(9)?);
        list.push(BodyState {
            shape: spec.shape.clone(),
            rotation: glam::Mat3::from_quat(q.normalize()),
            center: Vec3::new(num(3)?, num(4)?, num(5)?),
            velocity: Vec3::ZERO,
            angular_velocity: Vec3::ZERO,
            dynamic: spec.kind == RigidKind::Dynamic,
            condition: spec.condition,
            friction: spec.friction,
        });
    }
    Ok(frames)
}

#[cfg(test)]
mod tests {
    use super::*;

    const SCENE: &str = "[domain]\nmin = [0,0,0]\nmax = [1,1,1]\ndx = 0.05\n[time]\nduration = 0.1\n\
        [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000.0\nbulk_modulus = 1e4\n\
        [[body]]\nmaterial = \"w\"\nshape = \"box\"\nmin = [0.2, 0.2, 0.2]\nmax = [0.4, 0.4, 0.4]\n\
        [[rigid_body]]\nshape = \"sphere\"\ncenter = [0.7, 0.5, 0.5]\nradius = 0.1\ndensity = 500.0\n";

    #[test]
    fn bodies_csv_gives_each_frame_its_poses_and_bad_rows_name_the_line() {
        let scene = Scene::from_toml(SCENE, "s").expect("scene");
        let dir = std::env::temp_dir().join(format!("rtmpm-bodies-csv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let path = dir.join("bodies.csv");
        std::fs::write(
            &path,
            "frame,time,body,x,y,z,qx,qy,qz,qw,vx,vy,vz,wx,wy,wz\n\
             0,0,\"b\",0.7,0.5,0.5,0,0,0,1,0,0,0,0,0,0\n\
             1,0.1,\"b\",0.7,0.4,0.5,0,0,0.7071068,0.7071068,0,-1,0,0,0,0\n",
        )
        .expect("write");
        let f = read_bodies_csv(&path, &scene).expect("read");
        assert_eq!(f.len(), 2);
        assert_eq!(f[&1][0].center, Vec3::new(0.7, 0.4, 0.5));
        let turned = f[&1][0].rotation * Vec3::X;
        assert!((turned - Vec3::Y).length() < 1e-5, "{turned}");
        std::fs::write(&path, "frame,time,body,x\n3,0.3,\"b\",oops\n").expect("write");
        let e = read_bodies_csv(&path, &scene)
            .expect_err("bad row")
            .to_string();
        assert!(e.contains("bodies.csv:2"), "{e}");
        std::fs::write(&path, "h\n0,0,b,0,0,0,0,0,0,1\n0,0,c,0,0,0,0,0,0,1\n").expect("write");
        let e = read_bodies_csv(&path, &scene)
            .expect_err("two bodies")
            .to_string();
        assert!(e.contains("more bodies") && e.contains(":3"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
