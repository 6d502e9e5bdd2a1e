//! Bodies whose particle positions are drawn where they are used (issue 19, "start fast"): for a
//! GPU backend the host only counts a body's particles, keeps none of them, and hands the GPU
//! the recipe of the walk (the lattice, the shape and the random stream), from which the GPU
//! draws the very positions the host's walk finds, in the same order, bit for bit
//! (`rtmpm-cuda/src/sample.rs`). Any other consumer walks the body on the host
//! ([`DeferredBody::positions`]), so a deferred body is the same particles everywhere.
//!
//! Deferred: boxes, spheres and cylinders sampled `regular` or `jittered`, whose particles all
//! start with the same velocity (a spin needs the centroid of the positions, summed in walk
//! order on the host). Meshes, `random` sampling and points files are sampled on the host.

use super::fill::{BodyPositions, SampledBody, velocity_is_uniform};
use super::pcg::PcgStream;
use super::sampling::{self, BodyShape, SampleProgress, Sampling};
use super::walk::{Counter, Lattice, Mode};
use super::{Scene, SceneError};
use crate::math::Vec3;
use rand::SeedableRng;
use rand_pcg::Pcg64;

/// A body counted on the host, its positions left to be drawn.
#[derive(Clone, Debug)]
pub struct DeferredBody {
    /// What every particle shares (`chunks` empty, `count` the body's particles, `centre` zero:
    /// the velocity is uniform).
    pub shared: BodyPositions,
    /// The sub-cell lattice the walk visits, row by row (x fastest, then y, then z).
    pub lattice: Lattice,
    /// The shape whose inside keeps a point: a box, sphere or cylinder.
    pub shape: BodyShape,
    /// The seed of the walk's random stream (`Pcg64::seed_from_u64`).
    pub seed: u64,
}

impl DeferredBody {
    /// The walk's random stream as numbers (its state at the first point).
    pub fn stream(&self) -> PcgStream {
        PcgStream::seed_from_u64(self.seed)
    }

    /// The positions of the host's walk, as [`sampling::sample_positions`] finds them.
    pub fn positions(&self) -> BodyPositions {
        let rng = Pcg64::seed_from_u64(self.seed);
        let walked = self
            .lattice
            .walk(&self.shape, &rng, Mode::Keep, &Counter::new(&|_, _| {}));
        BodyPositions {
            chunks: walked.chunks,
            count: walked.count as usize,
            ..self.shared.clone()
        }
    }

    /// `f` of every chunk of the walk's positions, in walk order, each chunk walked and dropped
    /// in turn (in parallel): what the positions give without the host holding them all.
    pub fn map_chunks<T: Send>(&self, f: impl Fn(&[Vec3]) -> T + Sync + Send) -> Vec<T> {
        let rng = Pcg64::seed_from_u64(self.seed);
        self.lattice.map_chunks(&self.shape, &rng, f)
    }
}

/// True when body `index` can be deferred: a box, sphere or cylinder, sampled `regular` or
/// `jittered`, with a uniform initial velocity.
pub fn can_defer(scene: &Scene, index: usize) -> bool {
    let Some(body) = scene.bodies.get(index) else {
        return false;
    };
    matches!(
        body.shape,
        BodyShape::Box { .. } | BodyShape::Sphere { .. } | BodyShape::Cylinder { .. }
    ) && matches!(body.sampling, Sampling::Regular | Sampling::Jittered)
        && velocity_is_uniform(body.velocity, body.angular_velocity)
}

/// Every body of the scene, in order: those [`can_defer`] allows counted and deferred (the host
/// keeps no position), the others sampled by [`sampling::sample_positions`].
pub fn sample_bodies_deferred(
    scene: &Scene,
    progress: &(dyn Fn(SampleProgress) + Sync),
) -> Result<Vec<SampledBody>, SceneError> {
    let bodies = scene.bodies.len();
    (0..bodies)
        .map(|index| {
            if !can_defer(scene, index) {
                return sampling::sample_positions(scene, index, progress);
            }
            let report = |done, total| {
                progress(SampleProgress {
                    body: index,
                    bodies,
                    done,
                    total,
                })
            };
            let (walked, vol0) =
                sampling::walk_body(scene, index, Mode::Count, &Counter::new(&report))?;
            let shared =
                sampling::shared_of(scene, index, Vec::new(), walked.count as usize, vol0)?;
            Ok(SampledBody::Deferred(DeferredBody {
                shared,
                lattice: sampling::body_lattice(scene, index)?,
                shape: scene.bodies[index].shape.clone(),
                seed: sampling::body_seed(scene, index),
            }))
        })
        .collect()
}
