//! The validation cases, one module per physical problem; each case is a function of the
//! run's context returning its rows (and keeping its plots).

pub mod bar;
pub mod column;
pub mod dam_break;
pub mod disks;
pub mod free_fall;
pub mod granular;
pub mod hydrostatic;
pub mod rigid;
pub mod slump;
