//! Snow plasticity, Stomakhin et al. 2013 (stub: to be implemented).

use crate::math::Mat3;

#[derive(Clone, Debug, PartialEq)]
pub struct Snow {
    /// Initial Lamé parameters (hardened by `exp(xi (1 - Jp))`).
    pub mu: f32,
    pub lambda: f32,
    /// Critical compression theta_c (e.g. 2.5e-2).
    pub critical_compression: f32,
    /// Critical stretch theta_s (e.g. 7.5e-3).
    pub critical_stretch: f32,
    /// Hardening coefficient xi (e.g. 10).
    pub hardening: f32,
}

impl Snow {
    pub fn kirchhoff(&self, _f: Mat3, _jp: f32) -> Mat3 {
        todo!()
    }
    pub fn project(&self, _f_trial: Mat3, _jp: &mut f32) -> Mat3 {
        todo!()
    }
    /// Upper bound of `lambda + 2 mu` over the admissible hardening range, for the CFL condition.
    pub fn max_stiffness(&self) -> f32 {
        todo!()
    }
}
