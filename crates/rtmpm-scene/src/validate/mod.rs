//! Validation: raw serde structs -> [`Scene`], with field paths, positions and hints. The
//! validator and its checks of single values are in `core.rs`; each part of the scene has its
//! file.

mod core;
mod domain;
mod emitters;
mod io_fields;
mod joints;
mod motion;
mod rigid;
mod settings;
mod shapes;
mod time;

use self::core::{R, V, toml_error};
use crate::sampling;
use crate::scene::Scene;
use crate::schema::*;
use crate::settings::{ParticleState, Precision};
use rtmpm_physics::material::Material;
use rtmpm_physics::math::Vec3;
use std::path::{Path, PathBuf};

/// Parse and validate scene text.
pub(super) fn parse(text: &str, origin: &str, base: &Path, stem: Option<&str>) -> R<Scene> {
    parse_with(text, origin, base, stem, false)
}

/// Parse and validate a checkpoint's scene text (see [`Scene::from_checkpoint_text`]).
pub(super) fn parse_resumed(text: &str, origin: &str, base: &Path) -> R<Scene> {
    parse_with(text, origin, base, None, true)
}

fn parse_with(
    text: &str,
    origin: &str,
    base: &Path,
    stem: Option<&str>,
    resumed: bool,
) -> R<Scene> {
    let raw: RawScene = toml::from_str(text).map_err(|e| toml_error(text, origin, &e))?;
    let v = V {
        text,
        origin,
        doc: toml_edit::Document::parse(text).ok(),
        resumed,
        files: Default::default(),
    };
    v.resolve(raw, base, stem)
}

impl V<'_> {
    fn resolve(&self, raw: RawScene, base: &Path, stem: Option<&str>) -> R<Scene> {
        let name = raw
            .name
            .clone()
            .or_else(|| stem.map(str::to_string))
            .unwrap_or_else(|| "scene".into());
        self.file_name_ok(&name, raw.name.is_some())?;
        let (dmin, dmax, dx) = self.domain(&raw.domain)?;
        let cells = (dmax - dmin) / dx;
        let gravity = match raw.gravity {
            Some(g) => self.vec3("gravity", g)?,
            None => Vec3::new(0.0, -9.81, 0.0),
        };

        let time = self.time(&raw, dx)?;
        let duration = time.duration;

        // Walls.
        let walls = self.walls(raw.walls.as_ref(), cells)?;

        let materials = self.materials(&raw.material)?;

        // Bodies.
        let thick = walls.thickness as f32 * dx;
        let (imin, imax) = (dmin + thick, dmax - thick);
        let mut bodies = Vec::new();
        for (i, b) in raw.body.iter().enumerate() {
            bodies.push(self.body(i, b, &materials, base, dx, (imin, imax))?);
        }

        // Colliders.
        let mut colliders = Vec::new();
        for (i, c) in raw.collider.iter().enumerate() {
            colliders.push(self.collider(i, c, base, dx)?);
        }

        // Emitters (validate_emitter.rs).
        let seed = raw.seed.unwrap_or(0);
        let cx = emitters::EmitterContext {
            materials: &materials,
            base,
            dx,
            interior: (imin, imax),
            duration,
            seed,
        };
        let emitters = raw
            .emitter
            .iter()
            .enumerate()
            .map(|(i, e)| self.emitter(i, e, &cx))
            .collect::<R<Vec<_>>>()?;

        // Rigid bodies (validate_rigid.rs).
        let rigid_bodies = raw
            .rigid_body
            .iter()
            .enumerate()
            .map(|(i, b)| self.rigid_body(i, b, base, dx, (imin, imax)))
            .collect::<R<Vec<_>>>()?;
        self.rigid_names(&rigid_bodies)?;
        let joints = raw
            .joint
            .iter()
            .enumerate()
            .map(|(i, j)| self.joint(i, j, &rigid_bodies, (dmin, dmax)))
            .collect::<R<Vec<_>>>()?;
        self.rigid_overlaps(&rigid_bodies, &joints)?;

        // Output and surfaces (validate_io.rs).
        let output = self.output(
            raw.output.as_ref(),
            raw.surface.as_ref(),
            &materials,
            PathBuf::from("out").join(&name),
        )?;

        let render = self.render(raw.render.as_ref())?;
        let solver = self.solver(raw.solver.as_ref())?;
        self.solver_couples(&solver, &rigid_bodies)?;

        let scene = Scene {
            name,
            source: None,
            domain_min: dmin,
            domain_max: dmax,
            dx,
            gravity,
            time,
            materials,
            bodies,
            colliders,
            emitters,
            rigid_bodies,
            joints,
            walls,
            output,
            render,
            seed,
            solver,
            precision: raw
                .solver
                .as_ref()
                .and_then(|s| s.precision)
                .unwrap_or_default(),
            particle_state: raw
                .solver
                .as_ref()
                .and_then(|s| s.particle_state)
                .unwrap_or_default(),
            files: self.files.take(),
        };
        self.check_scene(&scene)?;
        Ok(scene)
    }

    /// The `[[material]]` tables, each name used once.
    fn materials(&self, raw: &[RawMaterial]) -> R<Vec<Material>> {
        let mut materials: Vec<Material> = Vec::new();
        for (i, m) in raw.iter().enumerate() {
            let mat = self.material(i, m)?;
            if materials.iter().any(|o| o.name == mat.name) {
                return Err(self.err(
                    format!("material[{i}].name"),
                    format!("material name {:?} is used twice", mat.name),
                    "give every material a unique name",
                ));
            }
            materials.push(mat);
        }

        Ok(materials)
    }

    /// What no single table shows: a compact particle state in f64, a body without particles.
    fn check_scene(&self, scene: &Scene) -> R<()> {
        if scene.particle_state == ParticleState::Compact && scene.precision == Precision::F64 {
            return Err(self.err(
                "solver.particle_state",
                "particle_state = \"compact\" is single precision only (it stores the velocity \
                 and C in 32-bit shared-exponent words)",
                "remove particle_state, or use precision = \"f32\"",
            ));
        }
        // Every body must produce particles (found without storing them: the first one is
        // enough; the size of the whole scene is checked by the budget, scene::budget).
        for i in 0..scene.bodies.len() {
            if self.resumed {
                // The particles are the checkpoint's; a body's file may be gone.
                break;
            }
            let empty = sampling::body_is_empty(scene, i).map_err(|e| {
                self.err(format!("body[{i}]"), e.message, e.hint.unwrap_or_default())
            })?;
            if empty {
                return Err(self.err(
                    format!("body[{i}]"),
                    "the body produces 0 particles",
                    "make it larger than a particle spacing (dx / round(cbrt(particles_per_cell))) or raise particles_per_cell/count",
                ));
            }
        }
        Ok(())
    }
}
