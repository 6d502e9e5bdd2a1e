//! Checks of the *values* read from a file (a checksum only proves that the bytes are those
//! written): finite numbers, positive mass and volume, material indices in range, positions
//! inside the domain. Used for checkpoints, and meant for every reader of particle data.

use rtmpm_physics::Particles;
use rtmpm_physics::math::Vec3;

/// A value read from a file that cannot be simulated: which particle, which quantity, why.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("particle {index}: {message}")]
pub struct BadValue {
    /// Index of the particle in the file.
    pub index: usize,
    /// What is wrong, e.g. "mass is -1".
    pub message: String,
}

fn bad(index: usize, message: String) -> Result<(), BadValue> {
    Err(BadValue { index, message })
}

/// Values that make sense whatever the scene: every array as long as `x`; position, velocity,
/// `C`, `F` and the plastic state finite; mass and initial volume finite and positive.
pub fn check_particle_values(p: &Particles) -> Result<(), BadValue> {
    check_particles(p).map_err(|e| BadValue {
        index: 0,
        message: e.to_string(),
    })?;
    for i in 0..p.len() {
        if !p.x[i].is_finite() {
            return bad(i, format!("position {} is not finite", p.x[i]));
        }
        if !p.v[i].is_finite() {
            return bad(i, format!("velocity {} is not finite", p.v[i]));
        }
        if !p.c[i].is_finite() {
            return bad(i, "the affine velocity C is not finite".into());
        }
        if !p.f[i].is_finite() {
            return bad(i, "the deformation gradient F is not finite".into());
        }
        if !p.plastic[i].is_finite() {
            return bad(
                i,
                format!("the plastic state {} is not finite", p.plastic[i]),
            );
        }
        let (m, v) = (p.mass[i], p.vol0[i]);
        if !(m.is_finite() && m > 0.0) {
            return bad(i, format!("mass {m} is not a positive finite number"));
        }
        if !(v.is_finite() && v > 0.0) {
            return bad(
                i,
                format!("initial volume {v} is not a positive finite number"),
            );
        }
    }
    Ok(())
}

/// Values that depend on the scene: material indices below `materials`, positions inside the
/// domain `[min, max]` widened by `tolerance` (a running simulation keeps particles within about
/// one cell of it).
pub fn check_particles_in_domain(
    p: &Particles,
    min: Vec3,
    max: Vec3,
    tolerance: f32,
    materials: usize,
) -> Result<(), BadValue> {
    let (lo, hi) = (min - tolerance, max + tolerance);
    for i in 0..p.len() {
        let m = p.material[i] as usize;
        if m >= materials {
            return bad(
                i,
                format!("material index {m} is out of range (the scene has {materials} materials)"),
            );
        }
        let x = p.x[i];
        if x.cmplt(lo).any() || x.cmpgt(hi).any() {
            return bad(
                i,
                format!("position {x} is outside the domain {min} .. {max}"),
            );
        }
    }
    Ok(())
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

#[cfg(test)]
mod tests {
    use super::*;

    fn two() -> Particles {
        let mut p = Particles::default();
        p.push(Vec3::splat(0.5), Vec3::ZERO, 1.0, 1e-3, 0, 0.0);
        p.push(Vec3::splat(0.25), Vec3::X, 1.0, 1e-3, 1, 0.0);
        p
    }

    #[test]
    fn each_bad_value_is_named() {
        assert_eq!(check_particle_values(&two()), Ok(()));
        type Edit = fn(&mut Particles);
        let cases: Vec<(Edit, &str)> = vec![
            (|p| p.mass[1] = -1.0, "mass -1"),
            (|p| p.mass[1] = f32::NAN, "mass NaN"),
            (|p| p.vol0[1] = 0.0, "initial volume 0"),
            (|p| p.x[1].y = f32::INFINITY, "position"),
            (|p| p.v[1].z = f32::NAN, "velocity"),
            (|p| p.c[1].x_axis.x = f32::NAN, "affine"),
            (|p| p.f[1].z_axis.z = f32::INFINITY, "deformation gradient"),
            (|p| p.plastic[1] = f32::NEG_INFINITY, "plastic"),
            (
                |p| p.mass.pop().map(drop).unwrap_or(()),
                "mass has 1 entries",
            ),
        ];
        for (break_it, expect) in cases {
            let mut p = two();
            break_it(&mut p);
            let e = check_particle_values(&p).unwrap_err().to_string();
            assert!(e.contains(expect), "{e} (expected {expect})");
        }
    }

    #[test]
    fn domain_and_materials() {
        let p = two();
        let (lo, hi) = (Vec3::ZERO, Vec3::ONE);
        assert_eq!(check_particles_in_domain(&p, lo, hi, 0.0, 2), Ok(()));
        let e = check_particles_in_domain(&p, lo, hi, 0.0, 1).unwrap_err();
        assert_eq!(e.index, 1);
        assert!(e.message.contains("material index 1"), "{e}");
        let mut far = p.clone();
        far.x[0].x = 1e6;
        let e = check_particles_in_domain(&far, lo, hi, 0.1, 2).unwrap_err();
        assert!(e.message.contains("outside the domain"), "{e}");
        far.x[0].x = 1.05;
        assert_eq!(check_particles_in_domain(&far, lo, hi, 0.1, 2), Ok(()));
    }
}
