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
