//! Helpers shared by the GPU test files of worlds in a batch (`tests/batch_*.rs`: the batch's
//! worlds against their separate runs) and of several GPUs (`tests/multi_gpu_*.rs`: several
//! GPUs against one): whether a GPU is there, reading a backend's particles; the comparisons of
//! a batch's worlds ([`batch`]) and the set-up of the runs on several GPUs ([`multi`]).
#![allow(dead_code)] // each test binary uses its part

pub mod batch;
pub mod multi;

use rtmpm_physics::Particles;
use rtmpm_sim::Backend;

/// True when a usable CUDA GPU is there; else says why the test is skipped.
pub fn gpu() -> bool {
    match rtmpm_cuda::probe() {
        Ok(_) => true,
        Err(e) => {
            println!("skipped: no usable CUDA GPU ({e})");
            false
        }
    }
}

/// Every particle of `b`.
pub fn read(b: &mut dyn Backend) -> Particles {
    let mut p = Particles::default();
    b.read_particles(&mut p).expect("read particles");
    p
}
