//! Validation of the file-related parts of a scene: `[output]`, `[surface]` and bodies made of
//! the particles of a file (`shape = "particles"`).

use super::core::{R, V};
use crate::schema::*;
use crate::settings::{MeshFormats, OutputSettings, SurfaceSettings};
use rtmpm_geometry::BodyShape;
use rtmpm_io::frame::FrameFormat;
use rtmpm_io::points::read_points;
use rtmpm_physics::material::{Material, Model};
use rtmpm_physics::math::Vec3;
use std::path::{Path, PathBuf};
use std::sync::Arc;

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

    /// A body made of the points of a file (`shape = "particles"`).
    pub(super) fn particles_shape(&self, prefix: &str, b: &RawBody, base: &Path) -> R<BodyShape> {
        let f = |n: &str| format!("{prefix}.{n}");
        let g = b.geometry();
        self.shape_fields(prefix, RawShape::Particles, &g)?;
        for (field, given) in [
            ("sampling", b.sampling.is_some()),
            ("count", b.count.is_some()),
        ] {
            if given {
                return Err(self.err(
                    f(field),
                    format!("`{field}` does not apply to a body made of a file's particles"),
                    "remove it: the particles are the file's points",
                ));
            }
        }
        let file = g.file.as_ref().ok_or_else(|| {
            self.err(
                f("file"),
                "a particles body needs a file",
                "add file = \"x.ply\" (or .vtu, .bgeo, .bgeo.gz), relative to the scene file",
            )
        })?;
        let mut points = read_points(&base.join(file)).map_err(|e| {
            self.err(
                f("file"),
                e.to_string(),
                "give a readable PLY, VTU or BGEO file of points (e.g. a frame of an earlier run)",
            )
        })?;
        if points.positions.is_empty() {
            return Err(self.err(
                f("file"),
                format!("{} holds no points", points.source.display()),
                "use a file with at least one point",
            ));
        }
        let scale = match g.scale {
            None => Vec3::ONE,
            Some(RawScale::Uniform(s)) => Vec3::splat(s),
            Some(RawScale::PerAxis(s)) => Vec3::from_array(s),
        };
        if !scale.is_finite() || scale.min_element() <= 0.0 {
            return Err(self.err(
                f("scale"),
                "scale factors must be positive",
                "use positive scale factors",
            ));
        }
        let translate = match g.translate {
            Some(t) => self.vec3(&f("translate"), t)?,
            None => Vec3::ZERO,
        };
        if scale != Vec3::ONE || translate != Vec3::ZERO {
            for p in &mut points.positions {
                *p = *p * scale + translate;
            }
            // Volumes scale with the product of the factors; masses stay.
            if let Some(v) = &mut points.volumes {
                let k = scale.element_product();
                v.iter_mut().for_each(|x| *x *= k);
            }
        }
        Ok(BodyShape::Particles {
            points: Arc::new(points),
            file_velocity: b.velocity.is_none() && b.angular_velocity.is_none(),
        })
    }
}
