//! Quadratic B-spline shape functions (MLS-MPM).
