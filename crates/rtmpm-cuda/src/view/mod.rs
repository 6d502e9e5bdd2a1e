//! A live view of a run on this GPU: the picture drawn from the state in place ([`render`], with
//! the kernels of `kernels/render/`) and the user's steering between steps ([`steer`]: gravity
//! and the tool).

pub mod render;
pub mod steer;
