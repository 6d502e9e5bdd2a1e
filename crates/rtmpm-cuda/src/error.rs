//! The crate's errors: why CUDA cannot be used ([`Unavailable`], from the probe), and a failed
//! driver call as the simulation's [`SimError`] ([`err`]), naming what was being done.

use cudarc::driver::DriverError;
use rtmpm_sim::SimError;
use std::fmt;

/// A failed driver call while doing `what`, as a [`SimError::Backend`]: "CUDA: {what}: {error}".
/// For `map_err`: `stream.synchronize().map_err(err("synchronize"))?`.
pub(crate) fn err(what: &str) -> impl Fn(DriverError) -> SimError + '_ {
    move |e| SimError::Backend(format!("CUDA: {what}: {e:?}"))
}

/// Why CUDA cannot be used.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Unavailable {
    /// libcuda.so could not be loaded.
    NoDriverLibrary,
    /// libnvrtc.so.13 could not be loaded.
    NoNvrtc,
    /// The driver reports no device.
    NoDevice,
    /// A driver call failed.
    Driver(String),
}

impl fmt::Display for Unavailable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Unavailable::NoDriverLibrary => {
                write!(f, "libcuda.so not found (no NVIDIA driver installed)")
            }
            Unavailable::NoNvrtc => write!(
                f,
                "libnvrtc.so.13 not found (pip install nvidia-cuda-nvrtc==13.0.*, set RTMPM_NVRTC_LIB or LD_LIBRARY_PATH)"
            ),
            Unavailable::NoDevice => write!(f, "no CUDA device found"),
            Unavailable::Driver(m) => write!(f, "CUDA driver error: {m}"),
        }
    }
}

impl std::error::Error for Unavailable {}
