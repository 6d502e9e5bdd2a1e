//! The run's budget on this machine: the estimate of `rtmpm_scene::budget` against the
//! memory available and the free space of the output disk.

use anyhow::{Result, bail};
use rtmpm_io::limits::{host_memory_available, human_bytes};
use rtmpm_scene::budget::BudgetIssue;
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
    enforce_for(scene, frames, out, None, None, None)
}

/// The host memory of a run's background frame writer (`--frames-in-flight`, `--frame-chunk`):
/// its pool of chunk buffers, as [`rtmpm_driver::stream::FrameStreamer`] allocates it.
#[derive(Clone, Copy, Debug)]
pub struct FrameBuffers {
    /// Frames written while the simulation steps on.
    pub frames_in_flight: usize,
    /// Particles per chunk.
    pub chunk: usize,
    /// Bytes of a particle's columns.
    pub bytes_per_particle: u64,
}

impl FrameBuffers {
    /// Bytes of the pool for frames of `particles` particles: `max(2, F x chunks a frame)`
    /// chunks of `min(chunk, particles)` particles.
    pub fn bytes(&self, particles: u64) -> u64 {
        let cap = (self.chunk.max(1) as u64).min(particles.max(1));
        let per_frame = particles.div_ceil(cap).max(1);
        let buffers = (self.frames_in_flight as u64)
            .saturating_mul(per_frame)
            .max(2);
        buffers
            .saturating_mul(cap)
            .saturating_mul(self.bytes_per_particle)
    }
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
    buffers: Option<FrameBuffers>,
    resumed_particles: Option<u64>,
) -> Result<Budget> {
    let mut budget = match resumed_particles {
        Some(n) => Budget::estimate_resumed(scene, frames, n),
        None => Budget::estimate(scene, frames),
    };
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
    let available = host_memory_available();
    let buffer_bytes = buffers.map_or(0, |b| b.bytes(budget.particles));
    budget.host_bytes = budget.host_bytes.saturating_add(buffer_bytes);
    let mut refusals = budget.refusals(available, disk, out.is_some());
    if let (Some(b), Some(avail)) = (buffers, available)
        && buffer_bytes > avail / 2
    {
        refusals.push(BudgetIssue {
            message: format!(
                "--frames-in-flight {} keeps the columns of that many frames of about {} \
                 particles in memory ({} bytes a particle, chunks of --frame-chunk {}): about \
                 {}, more than half of the {} available",
                b.frames_in_flight,
                rtmpm_scene::budget::count(budget.particles),
                b.bytes_per_particle,
                b.chunk,
                human_bytes(buffer_bytes),
                human_bytes(avail)
            ),
            fix: "lower --frames-in-flight (1, the default, writes one frame while the next \
                  steps run; 0 writes each frame before the next step)"
                .into(),
        });
    }
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
