//! The particle state on the device, in the backend's precision: host upload and download.
//!
//! Structure of arrays of [`StateLayout::words`] words per particle, word `w` of particle `i` at
//! `w * cap + i` (`cap`: the particle capacity, at least `n`), each field where the backend's
//! [`StateLayout`] puts it. A word is an f32 (`real` = float) or an f64 (kernels compiled with
//! `RTMPM_F64`); the material id and the original index are stored as integer bits in the low 32
//! bits of their word (`state_bits` in `kernels/common.cuh`), the compact layouts' v and C words
//! as the bits of [`crate::state::codec`]'s formats. The [`Particles`] interface is f32: the upload
//! widens exactly (compact: rounds v and C to their formats), the download rounds to nearest.

//!
//! * [`word`]: one word in either precision;
//! * [`fields`]: the words of each field in a layout (C in the compact format, F in one word
//!   in a fluid layout), written and read back;
//! * [`pack`]: the image of the particles, packed on the host;
//! * [`unpack`]: the particles back from an image, in original order;
//! * [`edit`]: the words that new positions, velocities, C or F of the particles write;
//! * [`codec`]: the shared-exponent codec of the compact state.

pub mod codec;
mod edit;
mod fields;
mod pack;
mod unpack;
mod word;

pub use edit::edit_rows;
pub use pack::{body_constant_words, map_positions, max_speed, pack, pack_bodies, pack_into};
pub use unpack::{resize_particles, scatter_f32, unpack, unpack_rows, unpack_x_v_f64};

use crate::contract::StateLayout;
use crate::options::CudaOptions;
use rtmpm_physics::material::Model;
use rtmpm_scene::{ParticleState, Precision, Scene};

/// Bytes of one state word.
pub fn word_bytes(f64: bool) -> usize {
    if f64 { 8 } else { 4 }
}

/// True for each material of `scene` that is a fluid (whose F the state keeps as J^(1/3) I).
pub fn fluid_materials(scene: &Scene) -> Vec<bool> {
    scene
        .materials
        .iter()
        .map(|m| matches!(m.model, Model::Fluid(_)))
        .collect()
}

/// The state layout of a backend for `scene` with `options`: [`StateLayout::Fluid`] when every
/// material is a fluid (unless `fluid_state` is off), compact with the scene's
/// `[solver] particle_state = "compact"` or the option `compact_state` (`state=compact`). The
/// compact state is single precision only: asked for in f64 (the scene's precision or the
/// option), an error.
pub fn layout_for(scene: &Scene, options: &CudaOptions) -> Result<StateLayout, String> {
    let compact = options.compact_state || scene.particle_state == ParticleState::Compact;
    let f64 = options.f64 || scene.precision == Precision::F64;
    if compact && f64 {
        return Err(
            "the compact particle state ([solver] particle_state = \"compact\") is \
                    single precision only: use particle_state = \"f32\" with f64"
                .into(),
        );
    }
    let all_fluid = fluid_materials(scene).iter().all(|f| *f);
    Ok(StateLayout::choose(all_fluid, compact, options.fluid_state))
}

#[cfg(test)]
mod tests;
