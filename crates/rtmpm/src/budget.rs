//! The run's budget on this machine: the estimate of `rtmpm_scene::budget` against the
//! memory available and the free space of the output disk.

use anyhow::{Result, bail};
use rtmpm_io::limits::host_memory_available;
use rtmpm_scene::{Budget, Scene};
use std::path::Path;

/// Free bytes (for an unprivileged user) of the file system holding `dir`, or of its nearest
/// existing ancestor; `None` where that is not known.
pub fn disk_available(dir: &Path) -> Option<u64> {
    let abs = std::path::absolute(dir).ok()?;
    let existing = abs.ancestors().find(|p| p.exists())?;
    let c = std::ffi::CString::new(existing.as_os_str().as_encoded_bytes()).ok()?;
    let mut st: libc::statvfs = unsafe { std::mem::zeroed() };
    // SAFETY: `c` is a NUL-terminated path and `st` a writable statvfs.
    if unsafe { libc::statvfs(c.as_ptr(), &mut st) } != 0 {
        return None;
    }
    (st.f_bavail as u64).checked_mul(st.f_frsize as u64)
}

/// Estimate the budget of a run of `scene` (`frames` overriding its duration), print the
/// warnings, and refuse (with the numbers and the fix) what cannot fit. `out` is the output
/// folder, `None` when no frame files are written.
pub fn enforce(scene: &Scene, frames: Option<u64>, out: Option<&Path>) -> Result<Budget> {
    enforce_for(scene, frames, out, None)
}

/// [`enforce`]; `cuda_lean`: the CUDA options when the host's memory is that of a CUDA run
/// built from the sampled positions ([`Budget::for_cuda_host`]: its state filled on the device,
/// or packed on the host; with the device fill and `sample=device`, nothing for the bodies the
/// device draws), not a CPU run's.
pub fn enforce_for(
    scene: &Scene,
    frames: Option<u64>,
    out: Option<&Path>,
    cuda_lean: Option<&rtmpm_cuda::CudaOptions>,
) -> Result<Budget> {
    let mut budget = Budget::estimate(scene, frames);
    if let Some(o) = cuda_lean {
        budget = budget.for_cuda_host(scene.precision, o.device_fill);
        if o.device_fill && o.device_sample {
            budget = budget.with_drawn_bodies(scene);
        }
    }
    for w in budget.warnings().into_iter().chain(scene.warnings()) {
        eprintln!("warning: {w}");
    }
    let disk = out.and_then(disk_available);
    let refusals = budget.refusals(host_memory_available(), disk, out.is_some());
    if !refusals.is_empty() {
        let text: Vec<String> = refusals.iter().map(|r| r.to_string()).collect();
        bail!(
            "scene `{}` does not fit this machine:\n{}",
            scene.name,
            text.join("\n")
        );
    }
    Ok(budget)
}
