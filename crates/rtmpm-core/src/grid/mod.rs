//! The sparse grid layout of seed 000.
