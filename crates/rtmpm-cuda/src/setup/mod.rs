//! The set-up of a backend: what it starts from, the initial mapping's block counts, and where
//! the time of building it went.

pub mod buffers;
pub mod capacity;
pub mod fill;
pub mod sample;

use crate::options::{CudaOptions, P2gMode};
use capacity::Capacity;
use rtmpm_physics::Particles;
use rtmpm_physics::grid::BlockLayout;
use rtmpm_physics::math::IVec3;
use rtmpm_scene::Scene;
use rtmpm_scene::sampling::SampledBody;

/// What a backend starts from: particles, or sampled bodies packed straight from their positions.
#[derive(Clone, Copy)]
pub(crate) enum Initial<'a> {
    Particles(&'a Particles),
    Bodies(&'a [SampledBody]),
}

impl Initial<'_> {
    pub(crate) fn len(&self) -> usize {
        match self {
            Initial::Particles(p) => p.len(),
            Initial::Bodies(b) => b.iter().map(|b| b.len()).sum(),
        }
    }
}

/// The stencil bases of the initial particles (for `p2g=reverse_map` only; else empty) and the
/// initial mapping's (gblocks, pblocks): the reverse map needs every particle's stencil base (its
/// load per node); the other strategies only the counts, found without a per-particle array on
/// the host (the device builds the mapping), and none at all when the domain's grid fits
/// ([`Capacity::needs_block_counts`]).
pub(crate) fn initial_blocks(
    scene: &Scene,
    initial: Initial,
    options: &CudaOptions,
) -> (Vec<IVec3>, (usize, usize)) {
    if options.p2g == P2gMode::ReverseMap {
        let bases = match initial {
            Initial::Particles(p) => capacity::bases(scene, p),
            Initial::Bodies(b) => crate::state::map_positions(b, capacity::base_of(scene)),
        };
        let mut layout = BlockLayout::default();
        layout.rebuild(&bases);
        let blocks = (layout.gblock_count, layout.pblock_count());
        (bases, blocks)
    } else if !Capacity::needs_block_counts(scene, options) {
        // The domain's grid fits: the capacities are the domain's.
        (Vec::new(), (0, 0))
    } else {
        let blocks = match initial {
            Initial::Particles(p) => {
                let chunks: Vec<_> = p.x.chunks(1 << 16).collect();
                capacity::block_counts_of(scene, &chunks)
            }
            Initial::Bodies(b) => capacity::block_counts(scene, b),
        };
        (Vec::new(), blocks)
    }
}

/// Where the time of building a backend went (s): what bounds the set-up of a big scene.
#[derive(Clone, Copy, Debug, Default)]
pub struct SetupPhases {
    /// Probing the device.
    pub probe: f64,
    /// The initial mapping on the host (stencil bases, block layout) and the capacities.
    pub layout: f64,
    /// Compiling the kernels (or reading the cache), the context, loading the module.
    pub kernels: f64,
    /// Packing the state image on the host (0 with the device fill).
    pub pack: f64,
    /// Allocating the buffers, uploading the packed state (if any) and the tables.
    pub allocate: f64,
    /// The device fill ([`crate::setup::fill::FillTimes::total`]; 0 when the host packed).
    pub fill: f64,
    /// Of which gathering positions into page-locked memory.
    pub fill_gather: f64,
    /// Of which counting the rows of the bodies drawn on the device.
    pub fill_count: f64,
    /// The whole build.
    pub total: f64,
}

impl std::fmt::Display for SetupPhases {
    /// "layout 1.20 s, kernels 0.41 s, pack 0.00 s, allocate+upload 0.30 s, device fill 0.80 s
    /// (gather 0.50 s, rows counted 0.01 s), other 0.05 s".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let known = self.probe + self.layout + self.kernels + self.pack + self.allocate + self.fill;
        write!(
            f,
            "probe {:.2} s, layout {:.2} s, kernels {:.2} s, pack {:.2} s, allocate+upload {:.2} s, \
             device fill {:.2} s (gather {:.2} s, rows counted {:.2} s), other {:.2} s",
            self.probe,
            self.layout,
            self.kernels,
            self.pack,
            self.allocate,
            self.fill,
            self.fill_gather,
            self.fill_count,
            (self.total - known).max(0.0)
        )
    }
}
