//! Weakly compressible fluid tracking only the volume ratio `J` (stub: to be implemented).

use crate::math::Mat3;

/// Equation of state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Eos {
    /// `p = K (1 - J)` (mpm88's linear model).
    Linear,
    /// `p = K (J^-gamma - 1)` (Tait / Cole).
    Tait { gamma: f32 },
}

/// Weakly compressible fluid.
#[derive(Clone, Debug, PartialEq)]
pub struct Fluid {
    /// Bulk modulus K (Pa).
    pub bulk_modulus: f32,
    pub eos: Eos,
    /// Dynamic viscosity (Pa s).
    pub viscosity: f32,
}

impl Fluid {
    pub fn kirchhoff(&self, _f: Mat3, _c: Mat3) -> Mat3 {
        todo!()
    }
    pub fn project(&self, _f_trial: Mat3) -> Mat3 {
        todo!()
    }
    /// Factor on K giving the small-strain stiffness dp/d(-J) at J = 1 (1 for linear, gamma for Tait).
    pub fn eos_stiffness_factor(&self) -> f32 {
        match self.eos {
            Eos::Linear => 1.0,
            Eos::Tait { gamma } => gamma,
        }
    }
}
