//! Validation of the file-related parts of a scene: `[output]` and `[surface]`.

use super::core::{R, V};
use crate::schema::*;
use crate::settings::{MeshFormats, OutputSettings, SurfaceSettings};
use rtmpm_io::frame::FrameFormat;
use rtmpm_physics::material::{Material, Model};
use std::path::PathBuf;

impl V<'_> {
    /// `[output]` and `[surface]`.
    pub(super) fn output(
        &self,
        out: Option<&RawOutput>,
        surface: Option<&RawSurface>,
        materials: &[Material],
        default_dir: PathBuf,
    ) -> R<OutputSettings> {
        let dir = out
            .and_then(|o| o.dir.clone())
            .map(PathBuf::from)
            .unwrap_or(default_dir);
        if dir.as_os_str().is_empty()
            || dir
                .components()
                .any(|c| matches!(c, std::path::Component::ParentDir))
        {
            return Err(self.err(
                "output.dir",
                format!("output folder {:?} is empty or climbs out with `..`", dir),
                "give a folder below the current one (e.g. \"out/my_run\") or an absolute path without `..`",
            ));
        }
        let names = out
            .and_then(|o| o.formats.clone())
            .unwrap_or_else(|| vec!["ply".to_string()]);
        let formats = self.frame_formats(&names)?;
        let fields = out.and_then(|o| o.fields.clone()).unwrap_or_default();
        let mesh = out.and_then(|o| o.surface.clone()).unwrap_or_default();
        let surface_formats = MeshFormats {
            obj: mesh.contains(&RawMeshFormat::Obj),
            ply: mesh.contains(&RawMeshFormat::Ply),
            vtu: mesh.contains(&RawMeshFormat::Vtu),
            usda: mesh.contains(&RawMeshFormat::Usda),
        };
        let surface = self.surface(surface, materials)?;
        if surface_formats.any() && surface.materials.is_empty() {
            return Err(self.err(
                "output.surface",
                "surfaces are asked for, but no material forms one (no fluid material, and no [surface] materials)",
                "name the materials to mesh in [surface] materials = [\"...\"], or remove output.surface",
            ));
        }
        Ok(OutputSettings {
            dir,
            formats,
            stress: fields.contains(&RawField::Stress),
            jacobian: fields.contains(&RawField::J),
            compress: out.and_then(|o| o.compress).unwrap_or(true),
            surface_formats,
            surface,
        })
    }

    /// The frame formats `names` (`[output] formats`), in the registry's order.
    fn frame_formats(&self, names: &[String]) -> R<Vec<&'static FrameFormat>> {
        if let Some(bad) = names.iter().find(|n| rtmpm_io::frame_format(n).is_none()) {
            return Err(self.err(
                "output.formats",
                format!("unknown frame format {bad:?}"),
                format!("use any of {}", rtmpm_io::frame_format_names()),
            ));
        }
        Ok(rtmpm_io::FRAME_FORMATS
            .iter()
            .copied()
            .filter(|f| names.iter().any(|n| n == f.name))
            .collect())
    }

    fn surface(&self, s: Option<&RawSurface>, materials: &[Material]) -> R<SurfaceSettings> {
        let d = SurfaceSettings::default();
        let fluids: Vec<u32> = (0..materials.len() as u32)
            .filter(|&i| matches!(materials[i as usize].model, Model::Fluid(_)))
            .collect();
        let Some(s) = s else {
            return Ok(SurfaceSettings {
                materials: fluids,
                ..d
            });
        };
        let materials = match &s.materials {
            None => fluids,
            Some(names) => {
                let mut ids = Vec::new();
                for (k, name) in names.iter().enumerate() {
                    let id = materials
                        .iter()
                        .position(|m| &m.name == name)
                        .ok_or_else(|| {
                            let known: Vec<String> =
                                materials.iter().map(|m| format!("{:?}", m.name)).collect();
                            self.err(
                                format!("surface.materials[{k}]"),
                                format!("unknown material {name:?}"),
                                format!("use one of: {}", known.join(", ")),
                            )
                        })?;
                    ids.push(id as u32);
                }
                ids
            }
        };
        let rel = |field: &str, v: Option<f32>, default: f32, what: &str| -> R<f32> {
            match v {
                Some(x) => self.positive(&format!("surface.{field}"), x, what),
                None => Ok(default),
            }
        };
        let threshold = match s.threshold {
            Some(t) => {
                self.finite("surface.threshold", t)?;
                if !(t > 0.0 && t < 1.0) {
                    return Err(self.err(
                        "surface.threshold",
                        format!("the threshold must be in (0, 1), got {t}"),
                        "use a fraction of the rest density such as 0.6",
                    ));
                }
                t
            }
            None => d.threshold,
        };
        Ok(SurfaceSettings {
            materials,
            smoothing_length: rel(
                "smoothing_length",
                s.smoothing_length,
                d.smoothing_length,
                "smoothing length (particle radii)",
            )?,
            cube_size: rel(
                "cube_size",
                s.cube_size,
                d.cube_size,
                "cube size (particle radii)",
            )?,
            threshold,
            smoothing_iters: s.smoothing_iters.unwrap_or(d.smoothing_iters),
            normal_smoothing_iters: s.normal_smoothing_iters.unwrap_or(d.normal_smoothing_iters),
        })
    }
}
