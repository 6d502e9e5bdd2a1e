//! A sampled body before its particles are written: the positions of a shape
//! ([`BodyPositions`]), the particles of a points file, or a body counted and left to be
//! drawn where it is used ([`DeferredBody`]).

use crate::walk::{Lattice, RandomTries};
use rtmpm_geometry::Shape;
use rtmpm_physics::Particles;
use rtmpm_physics::math::{Mat3, Vec3};

/// The particles of a body of a shape before they are written: positions in walk order (the
/// chunks concatenated) and what every particle of the body shares.
#[derive(Clone, Debug)]
pub struct BodyPositions {
    /// The positions, in chunks (concatenated: the walk's order).
    pub chunks: Vec<Vec<Vec3>>,
    /// Their number.
    pub count: usize,
    /// Initial volume of each particle (m^3).
    pub vol0: f32,
    /// Mass of each particle (kg): density x `vol0`.
    pub mass: f32,
    /// Initial plastic state of the material.
    pub plastic: f32,
    /// Material index.
    pub material: u32,
    /// The body's `velocity`, `angular_velocity` and the centroid of its particles (summed in
    /// order, in f32, as the one-thread sampler always did; zero where it cannot matter).
    pub velocity: Vec3,
    pub angular_velocity: Vec3,
    pub centre: Vec3,
    /// APIC `C` of every particle: the spin matrix of `angular_velocity`.
    pub c: Mat3,
}

impl BodyPositions {
    /// The initial velocity of the particle at `x`: `v0 + w x (x - c)`.
    #[inline]
    pub fn velocity_at(&self, x: Vec3) -> Vec3 {
        self.velocity + self.angular_velocity.cross(x - self.centre)
    }

    /// The centroid for `velocity_at`: the f32 sum of the positions in order over their count,
    /// or zero when the velocity is the same for every `x` (see [`velocity_is_uniform`]).
    pub(crate) fn centroid(chunks: &[Vec<Vec3>], count: usize, v0: Vec3, w: Vec3) -> Vec3 {
        if velocity_is_uniform(v0, w) {
            Vec3::ZERO
        } else {
            chunks.iter().flatten().fold(Vec3::ZERO, |a, b| a + *b) / count.max(1) as f32
        }
    }
}

/// One body's sampling: the positions of a shape, or the particles of a points file.
#[derive(Debug)]
pub enum SampledBody {
    Shape(BodyPositions),
    Points(Particles),
    /// Counted, its positions left to the backend ([`crate::deferred`]).
    Deferred(DeferredBody),
}

impl SampledBody {
    /// Particles of the body.
    pub fn len(&self) -> usize {
        match self {
            SampledBody::Shape(b) => b.count,
            SampledBody::Points(p) => p.len(),
            SampledBody::Deferred(d) => d.shared.count,
        }
    }

    /// True when the body has no particle.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The walk a deferred body's positions come from.
#[derive(Clone, Debug)]
pub enum DeferredWalk {
    /// The sub-cell lattice, row by row (x fastest, then y, then z).
    Lattice(Lattice),
    /// Uniform tries in the bounding box, in order, the first `count` accepted kept.
    Random(RandomTries),
}

/// A body counted on the host, its positions left to be drawn.
#[derive(Clone, Debug)]
pub struct DeferredBody {
    /// What every particle shares (`chunks` empty, `count` the body's particles).
    pub shared: BodyPositions,
    /// The walk.
    pub walk: DeferredWalk,
    /// The shape whose inside keeps a point.
    pub shape: Shape,
    /// The seed of the walk's random stream (`Pcg64::seed_from_u64`).
    pub seed: u64,
    /// The points the walk accepts in all: the count, or for random tries every point accepted
    /// in the tries made (the last batch of the host's walk may accept more than it keeps).
    pub accepted: u64,
}

/// True when `v0 + w x (x - c)` equals `v0` bit for bit for every finite `x` and `c`: `w` is
/// zero (so the cross product is a signed zero) and no component of `v0` is -0 (which +0 would
/// turn into +0).
pub fn velocity_is_uniform(v0: Vec3, w: Vec3) -> bool {
    w == Vec3::ZERO
        && !v0
            .to_array()
            .iter()
            .any(|c| *c == 0.0 && c.is_sign_negative())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_uniform_velocity_needs_no_centroid() {
        let any = [Vec3::new(0.3, -2.0, 1e3), Vec3::new(-5.0, 0.0, -0.0)];
        for v0 in [
            Vec3::ZERO,
            Vec3::new(1.0, -2.0, 0.0),
            Vec3::new(-3.5, 0.0, 7.0),
        ] {
            assert!(velocity_is_uniform(v0, Vec3::ZERO));
            for d in any {
                let v = v0 + Vec3::ZERO.cross(d);
                assert_eq!(
                    v.to_array().map(f32::to_bits),
                    v0.to_array().map(f32::to_bits)
                );
                let v = v0 + Vec3::new(-0.0, 0.0, -0.0).cross(d);
                assert_eq!(
                    v.to_array().map(f32::to_bits),
                    v0.to_array().map(f32::to_bits)
                );
            }
        }
        // -0 in the velocity: +0 + -0 is +0, so the centroid's sign may matter.
        assert!(!velocity_is_uniform(Vec3::new(-0.0, 1.0, 0.0), Vec3::ZERO));
        assert!(!velocity_is_uniform(Vec3::ONE, Vec3::new(0.0, 1.0, 0.0)));
    }
}
