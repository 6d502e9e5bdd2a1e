//! Whether CUDA can be used here, and what the device is: [`probe`] and [`probe_device`] say
//! why CUDA is unusable ([`Unavailable`]) instead of panicking; [`device_count`].

use crate::compile;
use crate::error::Unavailable;

/// What the device is.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceInfo {
    /// Device name.
    pub name: String,
    /// Compute capability (major, minor).
    pub compute_capability: (i32, i32),
    /// Total memory (bytes).
    pub memory: usize,
    /// Streaming multiprocessors.
    pub sm_count: i32,
    /// Driver version, e.g. 13000.
    pub driver_version: i32,
}

fn driver_present() -> bool {
    std::panic::catch_unwind(|| unsafe { cudarc::driver::sys::is_culib_present() }).unwrap_or(false)
}

/// Probe CUDA device 0. Never panics.
pub fn probe() -> Result<DeviceInfo, Unavailable> {
    probe_device(0)
}

/// Number of CUDA devices (0 when the driver or NVRTC is missing). Never panics.
pub fn device_count() -> usize {
    if !driver_present() || !compile::nvrtc_available() {
        return 0;
    }
    std::panic::catch_unwind(|| cudarc::driver::CudaContext::device_count().unwrap_or(0))
        .unwrap_or(0)
        .max(0) as usize
}

/// Probe CUDA device `ordinal`. Never panics.
pub fn probe_device(ordinal: usize) -> Result<DeviceInfo, Unavailable> {
    if !driver_present() {
        return Err(Unavailable::NoDriverLibrary);
    }
    if !compile::nvrtc_available() {
        return Err(Unavailable::NoNvrtc);
    }
    let r = std::panic::catch_unwind(|| -> Result<DeviceInfo, Unavailable> {
        use cudarc::driver::{CudaContext, sys::CUdevice_attribute};
        let n = CudaContext::device_count().map_err(|e| Unavailable::Driver(format!("{e:?}")))?;
        if n < 1 || ordinal >= n as usize {
            return Err(Unavailable::NoDevice);
        }
        let ctx = CudaContext::new(ordinal).map_err(|e| Unavailable::Driver(format!("{e:?}")))?;
        let d = |e| Unavailable::Driver(format!("{e:?}"));
        let mut driver_version = 0;
        // SAFETY: out-parameter.
        unsafe { cudarc::driver::sys::cuDriverGetVersion(&mut driver_version) };
        Ok(DeviceInfo {
            name: ctx.name().map_err(d)?,
            compute_capability: ctx.compute_capability().map_err(d)?,
            memory: ctx.total_mem().map_err(d)?,
            sm_count: ctx
                .attribute(CUdevice_attribute::CU_DEVICE_ATTRIBUTE_MULTIPROCESSOR_COUNT)
                .map_err(d)?,
            driver_version,
        })
    });
    match r {
        Ok(r) => r,
        Err(_) => Err(Unavailable::Driver(
            "the CUDA driver panicked during probing".into(),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn probe_never_panics() {
        match probe() {
            Ok(d) => println!("CUDA device: {d:?}"),
            Err(e) => println!("CUDA unavailable: {e}"),
        }
    }
}
