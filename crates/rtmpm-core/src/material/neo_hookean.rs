//! NeoHookean hyperelasticity (stub: to be implemented).

use crate::math::Mat3;

#[derive(Clone, Debug, PartialEq)]
pub struct NeoHookean {
    pub mu: f32,
    pub lambda: f32,
}

impl NeoHookean {
    pub fn kirchhoff(&self, _f: Mat3) -> Mat3 {
        todo!()
    }
}
