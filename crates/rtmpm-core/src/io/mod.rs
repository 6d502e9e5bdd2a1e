//! Output and checkpoint files. Every file is written to a temporary name and renamed.

pub mod atomic;
pub mod checkpoint;
pub mod ply;
pub mod vtu;

pub use atomic::write_atomic;
