//! rtmpm CUDA backend.
pub mod compile;
