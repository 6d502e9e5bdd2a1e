//! Bodies whose particle positions are drawn where they are used, so that a large scene starts
//! fast: for a GPU backend the host only counts a body's particles, keeps none of them, and hands the GPU
//! the recipe of the walk (the lattice or the random tries, the shape and the random stream),
//! from which the GPU draws the very positions the host's walk finds, in the same order, bit for
//! bit (`rtmpm-cuda/src/setup/sample/mod.rs`). Any other consumer walks the body on the host
//! ([`DeferredBody::positions`]), so a deferred body is the same particles everywhere.
//!
//! Deferred: boxes, spheres, cylinders and meshes, sampled `regular`, `jittered` or `random`.
//! A spinning body's centroid (its velocity is `v0 + w x (x - c)`) is summed on the host in walk
//! order, a window of chunks at a time, as the eager sampler sums it. Points files are read on
//! the host.

use crate::body::{BodyPositions, SampledBody, velocity_is_uniform};
pub use crate::body::{DeferredBody, DeferredWalk};
use crate::error::SceneError;
use crate::pcg::PcgStream;
use crate::sampling::{self, SampleProgress, Sampling};
use crate::scene::Scene;
use crate::walk::{Counter, Mode, RandomTries};
use rand::SeedableRng;
use rand_pcg::Pcg64;
use rayon::prelude::*;
use rtmpm_physics::math::Vec3;

impl DeferredBody {
    /// The walk's random stream as numbers (its state at the first point).
    pub fn stream(&self) -> PcgStream {
        PcgStream::seed_from_u64(self.seed)
    }

    fn rng(&self) -> Pcg64 {
        Pcg64::seed_from_u64(self.seed)
    }

    /// The walk's chunks and, for random tries, the index of each chunk's first point.
    fn chunks(&self) -> (u64, Option<Vec<u64>>) {
        match &self.walk {
            DeferredWalk::Lattice(l) => (l.chunk_count(), None),
            DeferredWalk::Random(r) => (r.chunk_count(), Some(r.starts(&self.shape, &self.rng()))),
        }
    }

    fn chunk(&self, rng: &Pcg64, c: u64, starts: Option<&[u64]>) -> Vec<Vec3> {
        match (&self.walk, starts) {
            (DeferredWalk::Lattice(l), _) => l.chunk(&self.shape, rng, c),
            (DeferredWalk::Random(r), Some(s)) => r.chunk(&self.shape, rng, c, s[c as usize]),
            (DeferredWalk::Random(_), None) => Vec::new(),
        }
    }

    /// `f` of every chunk of the walk's positions, in walk order, each chunk walked and dropped
    /// in turn (in parallel): what the positions give without the host holding them all.
    pub fn map_chunks<T: Send>(&self, f: impl Fn(&[Vec3]) -> T + Sync + Send) -> Vec<T> {
        let rng = self.rng();
        let (n, starts) = self.chunks();
        (0..n)
            .into_par_iter()
            .map(|c| f(&self.chunk(&rng, c, starts.as_deref())))
            .collect()
    }

    /// The positions of the host's walk, as [`sampling::sample_positions`] finds them.
    pub fn positions(&self) -> BodyPositions {
        let chunks = self.map_chunks(|c| c.to_vec());
        BodyPositions {
            count: chunks.iter().map(|c| c.len()).sum(),
            chunks,
            ..self.shared.clone()
        }
    }

    /// The f32 sum of the positions in walk order (the eager centroid's sum), walking a window
    /// of chunks at a time in parallel.
    fn sum_in_order(&self) -> Vec3 {
        let rng = self.rng();
        let (n, starts) = self.chunks();
        let window = 4 * rayon::current_num_threads() as u64;
        let mut sum = Vec3::ZERO;
        let mut c0 = 0;
        while c0 < n {
            let c1 = (c0 + window).min(n);
            let chunks: Vec<Vec<Vec3>> = (c0..c1)
                .into_par_iter()
                .map(|c| self.chunk(&rng, c, starts.as_deref()))
                .collect();
            sum = chunks.iter().flatten().fold(sum, |a, b| a + *b);
            c0 = c1;
        }
        sum
    }
}

/// True when body `index` can be deferred: a shape the device samples (any but a points
/// file: `ShapeInfo::device`).
pub fn can_defer(scene: &Scene, index: usize) -> bool {
    scene
        .bodies
        .get(index)
        .is_some_and(|b| b.shape.info().device)
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
            let body = &scene.bodies[index];
            let count = walked.count;
            let (walk, accepted) = match body.sampling {
                Sampling::Regular | Sampling::Jittered => (
                    DeferredWalk::Lattice(sampling::body_lattice(scene, index)?),
                    count,
                ),
                Sampling::Random => {
                    let (lo, hi) = body.shape.bounds();
                    let tries = RandomTries {
                        lo,
                        hi,
                        tries: walked.tries,
                        count,
                    };
                    (DeferredWalk::Random(tries), walked.accepted)
                }
            };
            let shared = sampling::shared_of(scene, index, Vec::new(), count as usize, vol0)?;
            let mut d = DeferredBody {
                shared,
                walk,
                shape: body.shape.clone(),
                seed: sampling::body_seed(scene, index),
                accepted,
            };
            if !velocity_is_uniform(body.velocity, body.angular_velocity) {
                d.shared.centre = d.sum_in_order() / (count as usize).max(1) as f32;
            }
            Ok(SampledBody::Deferred(d))
        })
        .collect()
}
