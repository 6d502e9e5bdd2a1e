//! The scene's and the interface's values (f32, the f32 package's types) in the precision of
//! [`crate::real`]: particles, materials and walls. In f32 each is the identity (or a copy).

#[cfg(not(feature = "f64"))]
use crate as single;
use crate::boundary::{BoundaryRule, Walls};
use crate::material::registry::Material;
use crate::real::real;
#[cfg(feature = "f64")]
use crate::real::{mat3, vec3};
#[cfg(feature = "f64")]
use rtmpm_physics as single;

/// The interface's particles (f32) in this precision.
pub fn particles(p: single::particles::Particles) -> crate::particles::Particles {
    #[cfg(not(feature = "f64"))]
    return p;
    #[cfg(feature = "f64")]
    return crate::particles::Particles {
        x: p.x.iter().map(|&v| vec3(v)).collect(),
        v: p.v.iter().map(|&v| vec3(v)).collect(),
        c: p.c.iter().map(|&m| mat3(m)).collect(),
        f: p.f.iter().map(|&m| mat3(m)).collect(),
        plastic: p.plastic.iter().map(|&x| real(x)).collect(),
        mass: p.mass.iter().map(|&x| real(x)).collect(),
        vol0: p.vol0.iter().map(|&x| real(x)).collect(),
        material: p.material,
    };
}

/// The scene's materials in this precision: in f64 each model is built again from the
/// parameters as written (`Material::params`) by the model files, so the f64 models are those
/// of the scene text, not widened f32 models. The error names the material.
pub fn materials(m: &[single::material::registry::Material]) -> Result<Vec<Material>, String> {
    #[cfg(not(feature = "f64"))]
    return Ok(m.to_vec());
    #[cfg(feature = "f64")]
    return m
        .iter()
        .map(|m| {
            Material::new(&m.name, real(m.density), m.params.clone())
                .map_err(|e| format!("material `{}` in f64: {e}", m.name))
        })
        .collect();
}

/// A boundary rule of the scene in this precision.
pub fn rule(r: &single::boundary::BoundaryRule) -> BoundaryRule {
    BoundaryRule {
        condition: r.condition,
        friction: real(r.friction),
    }
}

/// The scene's walls in this precision.
pub fn walls(w: &single::boundary::Walls) -> Walls {
    Walls {
        thickness: w.thickness,
        faces: w.faces.each_ref().map(rule),
    }
}
