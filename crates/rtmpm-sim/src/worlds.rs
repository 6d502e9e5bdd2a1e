//! Backends that hold the worlds of a batch in one set of arrays, stepped together (one launch
//! per stage for every world): the driver steps them as one [`Backend`] and reads, freezes and
//! writes them world by world through [`Worlds`].

use crate::backend::Backend;
use crate::error::SimError;
use rtmpm_physics::Particles;

/// A backend holding several independent worlds: particles of world `w` never touch another
/// world's grid, each world keeps its own coordinates and material indices.
pub trait Worlds: Backend {
    /// Number of worlds.
    fn worlds(&self) -> usize;

    /// Every world's particles, in its own coordinates and material indices, world by world.
    fn read_worlds(&mut self) -> Result<Vec<Particles>, SimError>;

    /// Put world `w`'s particles to `particles` (as many as it has, in its own material
    /// indices); the other worlds are not touched.
    fn put_world(&mut self, w: usize, particles: &Particles) -> Result<(), SimError>;

    /// The world of particle `index` (original order over all worlds, as
    /// [`crate::BadParticle::index`] and [`crate::Blowup::particle`] give it) and its index in
    /// that world.
    fn world_of_particle(&self, index: usize) -> Option<(usize, usize)>;
}
