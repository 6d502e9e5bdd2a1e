//! von Mises (J2) elastoplasticity (stub: to be implemented).

use crate::math::Mat3;

#[derive(Clone, Debug, PartialEq)]
pub struct VonMises {
    pub mu: f32,
    pub lambda: f32,
    /// Initial yield stress (Pa).
    pub yield_stress: f32,
    /// Linear isotropic hardening modulus (Pa); 0 = perfectly plastic.
    pub hardening: f32,
}

impl VonMises {
    pub fn kirchhoff(&self, _f: Mat3) -> Mat3 {
        todo!()
    }
    pub fn project(&self, _f_trial: Mat3, _eps_p: &mut f32) -> Mat3 {
        todo!()
    }
}
