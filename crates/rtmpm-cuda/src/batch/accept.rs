//! What a GPU batch accepts: the worlds' scenes and options it runs ([`unsupported`], a pure
//! function also behind `--backend auto`'s choice), their initial particles, whether the worlds fit
//! the 64-bit block codes side by side, and the block capacities of all worlds summed.

use super::colliders;
use super::layout::{MAX_GRID_CELLS_X, WORLD_ORIGIN_CELLS, world_stride};
use crate::options::{CudaOptions, P2gMode};
use crate::setup::Initial;
use crate::setup::capacity::Capacity;
use rtmpm_physics::Particles;
use rtmpm_physics::transfer::{Transfer, Update};
use rtmpm_scene::Scene;
use rtmpm_sim::SimError;

/// Why the worlds `worlds` cannot run together on the GPU with `options` (what the batch does
/// not support, in words, without the fix), or `None`: a pure function of the scenes and
/// options, checked before any GPU work (and by `--backend auto` to choose a batch's backend).
pub fn unsupported(worlds: &[Scene], options: &CudaOptions) -> Option<String> {
    let Some(base) = worlds.first() else {
        return Some("no worlds (a batch needs at least one)".into());
    };
    if matches!(options.p2g, P2gMode::ReverseMap | P2gMode::Sort) {
        return Some(format!(
            "p2g={} is planned from one world's grid; a batch runs p2g=warp (the default) or \
             p2g=shared",
            options.p2g.name()
        ));
    }
    let shared = |s: &Scene| {
        format!(
            "{:?}",
            (
                s.domain_min,
                s.domain_max,
                s.dx,
                &s.walls,
                &s.solver,
                s.precision,
                s.particle_state,
                s.materials.len(),
            )
        )
    };
    let want = shared(base);
    if let Some(why) = rigid_refusal(worlds).or_else(|| colliders::refusal(worlds)) {
        return Some(why);
    }
    for (w, s) in worlds.iter().enumerate() {
        if !s.emitters.is_empty() {
            return Some(format!(
                "world {w} has emitters: the GPU batch runs worlds of material, colliders, \
                 walls and rigid bodies only so far"
            ));
        }
        if shared(s) != want {
            return Some(format!(
                "world {w} differs from world 0 in its domain, grid spacing, walls, solver or \
                 number of materials: on the GPU the worlds share those (they may differ in \
                 material values, gravity, colliders and rigid bodies)"
            ));
        }
    }
    let n_cells_x = base.n_cells()[0] as usize;
    grid_reach_refusal(worlds.len(), world_stride(n_cells_x), n_cells_x)
}

/// Why the worlds' rigid bodies cannot run in a GPU batch, or `None`: every world has as many
/// (they may differ in anything else: kind, pose, velocity, shape, boundary rule), a mesh body
/// has world 0's mesh (the mesh table is shared), at most `MAX_BODIES` a world, a USL step of
/// the MLS or classic transfers (as a single run), and a build with the rigid-body engine.
fn rigid_refusal(worlds: &[Scene]) -> Option<String> {
    let base = worlds.first()?;
    let n = base.rigid_bodies.len();
    for (w, s) in worlds.iter().enumerate() {
        if s.rigid_bodies.len() != n {
            return Some(format!(
                "world {w} has {} rigid bodies and world 0 has {n}: on the GPU every world has \
                 the same number (they may differ in kind, pose, velocity, shape and boundary \
                 rule)",
                s.rigid_bodies.len()
            ));
        }
        for (i, (b, b0)) in s.rigid_bodies.iter().zip(&base.rigid_bodies).enumerate() {
            let mesh =
                |b: &rtmpm_rigid::RigidBodySpec| matches!(b.shape, rtmpm_geometry::Shape::Mesh(_));
            if (mesh(b) || mesh(b0)) && b.shape != b0.shape {
                return Some(format!(
                    "rigid body {i} of world {w} is a mesh other than world 0's: on the GPU \
                     every world's mesh bodies share world 0's meshes"
                ));
            }
        }
    }
    if n == 0 {
        return None;
    }
    if !cfg!(feature = "rigid") {
        return Some(
            "the worlds have rigid bodies and this build has no rigid-body engine (the cargo \
             feature `rigid`)"
                .into(),
        );
    }
    if n > crate::contract::MAX_BODIES {
        return Some(format!(
            "the worlds have {n} rigid bodies each; at most {} a world",
            crate::contract::MAX_BODIES
        ));
    }
    if base.solver.update == Update::Musl || base.solver.transfer == Transfer::CkMpm {
        return Some(
            "rigid bodies are coupled in the grid update of USL steps of the MLS or classic \
             transfers ([solver] update = \"usl\", transfer other than \"ck-mpm\")"
                .into(),
        );
    }
    None
}

/// The worlds' initial particles against their scenes (one set per world, none empty, their
/// materials the world's).
pub(super) fn check_particles(worlds: &[Scene], particles: &[Particles]) -> Result<(), SimError> {
    let refuse = |why: String| Err(SimError::Backend(format!("CUDA batch: {why}")));
    if particles.len() != worlds.len() {
        return refuse(format!(
            "{} worlds but {} particle sets",
            worlds.len(),
            particles.len()
        ));
    }
    for (w, (s, p)) in worlds.iter().zip(particles).enumerate() {
        if p.is_empty() {
            return refuse(format!("world {w} has no particles"));
        }
        if let Some(k) = p
            .material
            .iter()
            .find(|&&k| k as usize >= s.materials.len())
        {
            return refuse(format!(
                "world {w}: a particle of material {k}, the scene has {}",
                s.materials.len()
            ));
        }
    }
    Ok(())
}

/// The worlds lie side by side along x in the block coordinates: refused when the last one's
/// nodes lie past what the 64-bit block code addresses.
fn grid_reach_refusal(worlds: usize, stride: usize, n_cells_x: usize) -> Option<String> {
    let reach = worlds
        .saturating_sub(1)
        .saturating_mul(stride)
        .saturating_add(WORLD_ORIGIN_CELLS + n_cells_x + 12);
    if reach > MAX_GRID_CELLS_X {
        let fit = MAX_GRID_CELLS_X.saturating_sub(WORLD_ORIGIN_CELLS + n_cells_x + 12) / stride + 1;
        return Some(format!(
            "{worlds} worlds of {n_cells_x} cells along x take {stride} cells each side by side, \
             {reach} cells; the 64-bit block codes address {MAX_GRID_CELLS_X}: at most {fit} \
             worlds of this domain (or fewer cells: a coarser dx)"
        ));
    }
    None
}

/// The options with the block capacities of the worlds summed (each world's planned from its
/// own initial mapping, as a single run's: the worlds' blocks are disjoint), unless given.
pub(super) fn batch_capacities(
    worlds: &[Scene],
    particles: &[Particles],
    options: CudaOptions,
) -> CudaOptions {
    let (mut g, mut p) = (0usize, 0usize);
    for (s, x) in worlds.iter().zip(particles) {
        let (_, blocks) = crate::setup::initial_blocks(s, Initial::Particles(x), &options);
        let c = Capacity::plan_blocks(s, x.len(), 0, blocks, &options);
        g = g.saturating_add(c.gblocks);
        p = p.saturating_add(c.pblocks);
    }
    CudaOptions {
        gblock_capacity: options.gblock_capacity.or(Some(g)),
        pblock_capacity: options.pblock_capacity.or(Some(p)),
        ..options
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn too_many_worlds_for_the_block_codes_are_refused_with_the_numbers() {
        let s = world_stride(32);
        assert!(grid_reach_refusal(1024, s, 32).is_none());
        let e = grid_reach_refusal(100_000, s, 32).expect("refused");
        assert!(e.contains("100000 worlds"), "{e}");
        assert!(e.contains("2097152"), "{e}");
        let fit: usize = e
            .split("at most ")
            .nth(1)
            .and_then(|t| t.split(' ').next())
            .and_then(|t| t.parse().ok())
            .expect("the count that fits");
        assert!(grid_reach_refusal(fit, s, 32).is_none());
        assert!(grid_reach_refusal(fit + 1, s, 32).is_some());
    }
}
