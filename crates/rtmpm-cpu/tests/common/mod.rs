//! The crates under test in this precision. rtmpm-cpu-f64 compiles these test files a second
//! time (`[[test]] path`), with its feature `f64`: `cpu` is then rtmpm-cpu-f64 (every quantity
//! of the step in f64) and `physics32` the f32 physics of the particles' interface (frames,
//! edits), which is `physics` in rtmpm-cpu.
#![allow(unused_imports)]

#[cfg(not(feature = "f64"))]
pub use physics as physics32;
#[cfg(not(feature = "f64"))]
pub use rtmpm_cpu as cpu;
#[cfg(feature = "f64")]
pub use rtmpm_cpu_f64 as cpu;
#[cfg(feature = "f64")]
pub use rtmpm_physics as physics32;

/// The state of every particle as bits (x, v, F, C, plastic), for bit-for-bit comparisons.
#[allow(dead_code)]
pub fn bits(p: &rtmpm_sim::Particles) -> Vec<u32> {
    let mut out = Vec::new();
    for i in 0..p.len() {
        out.extend(p.x[i].to_array().map(f32::to_bits));
        out.extend(p.v[i].to_array().map(f32::to_bits));
        out.extend(p.f[i].to_cols_array().map(f32::to_bits));
        out.extend(p.c[i].to_cols_array().map(f32::to_bits));
        out.push(p.plastic[i].to_bits());
    }
    out
}
