//! Drucker-Prager sand, Klar et al. 2016 (stub: to be implemented).

use crate::math::Mat3;

#[derive(Clone, Debug, PartialEq)]
pub struct DruckerPrager {
    pub mu: f32,
    pub lambda: f32,
    /// Friction angle (degrees).
    pub friction_angle: f32,
    /// Cohesion, as a log-strain shift of the cone tip (0 = dry sand).
    pub cohesion: f32,
}

impl DruckerPrager {
    pub fn kirchhoff(&self, _f: Mat3) -> Mat3 {
        todo!()
    }
    pub fn project(&self, _f_trial: Mat3, _q: &mut f32) -> Mat3 {
        todo!()
    }
}
