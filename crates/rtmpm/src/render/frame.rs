//! The particles of one frame as the render thread receives them: from memory or from a PLY
//! frame, with the surface materials taken out of the splats.

use super::*;

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
        let field = match color_by {
            ColorBy::Material => None,
            ColorBy::Speed => Some(p.v.iter().map(|v| v.length()).collect()),
            ColorBy::J => Some(p.f.iter().map(|f| f.determinant()).collect()),
            ColorBy::Plastic => Some(p.plastic.clone()),
            ColorBy::Stress => Some(
                crate::output::cauchy_stress(p, scene)
                    .into_iter()
                    .map(von_mises)
                    .collect(),
            ),
        };
        FrameJob {
            frame,
            time: Some(time),
            positions: p.x.clone(),
            material: p.material.clone(),
            field,
            surface: SurfaceJob::None,
        }
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
        })
    }
}
