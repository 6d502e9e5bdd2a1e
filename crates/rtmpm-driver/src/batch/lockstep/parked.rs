//! A frozen world as a lockstep batch leaves it in the backend (parked): its particles where
//! they were at its last frame, at rest and unstressed, its rigid bodies at rest, so that it
//! bounds no time step and cannot blow up again.

use rtmpm_physics::Particles;
use rtmpm_physics::math::{Mat3, Vec3};
use rtmpm_rigid::BodyPose;

/// A frozen world's particles as it is left in the backend: where they were at its last frame,
/// at rest (`v = 0`, `C = 0`) and unstressed (`F = I`), so that it bounds no time step and
/// cannot blow up again; its files keep the state it froze at.
pub(super) fn parked(kept: &Particles) -> Particles {
    let mut p = kept.clone();
    p.v.iter_mut().for_each(|v| *v = Default::default());
    p.c.iter_mut().for_each(|c| *c = Mat3::ZERO);
    p.f.iter_mut().for_each(|f| *f = Mat3::IDENTITY);
    p
}

/// A frozen world's rigid bodies as it is left in the backend: where they were, at rest.
pub(super) fn parked_bodies(kept: &[BodyPose]) -> Vec<BodyPose> {
    kept.iter()
        .map(|b| BodyPose {
            velocity: Vec3::ZERO,
            angular_velocity: Vec3::ZERO,
            ..*b
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_parked_world_keeps_its_places_at_rest_and_unstressed() {
        let mut p = Particles::default();
        p.x.push(Vec3::new(0.1, 0.2, 0.3));
        p.v.push(Vec3::new(5.0, -1.0, 2.0));
        p.c.push(Mat3::from_diagonal(Vec3::splat(3.0)));
        p.f.push(Mat3::from_diagonal(Vec3::splat(1.5)));
        p.plastic.push(0.9);
        p.mass.push(1.0);
        p.vol0.push(1.0);
        p.material.push(0);
        let q = parked(&p);
        assert_eq!(q.x, p.x);
        assert_eq!(q.v[0], Vec3::ZERO);
        assert_eq!(q.c[0], Mat3::ZERO);
        assert_eq!(q.f[0], Mat3::IDENTITY);
        assert_eq!((q.mass.clone(), q.material.clone()), (p.mass, p.material));
    }
}
