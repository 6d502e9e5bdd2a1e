//! The host's waits for the device, counted by reason ([`HostWaits`]): every place of a
//! backend's (and a batch's) step, put, pose and read paths where the host blocks until the
//! device has done queued work (a read of control words or sums, an event or stream
//! synchronised, page-locked upload memory still in use, device or page-locked memory
//! allocated) counts one wait of its reason, always (one relaxed atomic add: no cost worth a
//! switch). `RTMPM_SYNC_TRACE=1` also times each wait (the seconds a reason's waits took) and,
//! when the backend is dropped, prints the counts and seconds to stderr; `RTMPM_SYNC_TRACE=2`
//! also prints every wait as it ends. A test asserts how many waits a loop makes
//! (`CudaBatch::host_waits`, Python's `BatchSimulation.host_waits`); a benchmark prints them
//! per call (`bench/python_batch_gpu.py`).
//!
//! A wait is counted where the host blocks whether or not the device was already done (so the
//! counts of a loop do not depend on the device's speed); the traced seconds say how long the
//! waits took.

use std::sync::OnceLock;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Why the host waited for the device.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum WaitReason {
    /// The health check's control words: the check ending a step call (or the check a step call
    /// with deferred checks left, made as the next call begins).
    Check,
    /// Other control words (the fastest particle of a CFL step, the rebuild count, block
    /// counts).
    Control,
    /// Particles read to the host (a state read, a blow-up's report, the worlds of a rewind).
    Read,
    /// The rigid bodies' sums of a step (a dynamic body's step, a load read).
    Sums,
    /// Page-locked upload memory still read by an earlier copy, every buffer of its ring in use
    /// (the host that many uploads ahead of the device).
    Staging,
    /// A copy to the device from pageable host memory, which the driver may make wait for the
    /// stream to reach it (counted whether or not it did).
    Pageable,
    /// Device memory or page-locked host memory allocated (a buffer grown).
    Alloc,
    /// The stream or the whole device synchronised (a rewind, `synchronize`, device arrays
    /// handed out to other streams).
    Sync,
}

impl WaitReason {
    /// Every reason, in the order of [`WaitCounts`].
    pub const ALL: [WaitReason; 8] = [
        WaitReason::Check,
        WaitReason::Control,
        WaitReason::Read,
        WaitReason::Sums,
        WaitReason::Staging,
        WaitReason::Pageable,
        WaitReason::Alloc,
        WaitReason::Sync,
    ];

    /// Its name in the counts (`check`, `control`, ...).
    pub fn name(self) -> &'static str {
        match self {
            WaitReason::Check => "check",
            WaitReason::Control => "control",
            WaitReason::Read => "read",
            WaitReason::Sums => "sums",
            WaitReason::Staging => "staging",
            WaitReason::Pageable => "pageable",
            WaitReason::Alloc => "alloc",
            WaitReason::Sync => "sync",
        }
    }

    fn index(self) -> usize {
        self as usize
    }
}

const N: usize = WaitReason::ALL.len();

/// `RTMPM_BATCH_WAITS=old`: the host's waits of the batch paths as before they were cut (the
/// check reads the control words when made, the control words are written from pageable
/// memory, the batch's page-locked uploads wait for their buffer in turn: four for the rigid
/// bodies' table, one for the puts; Python's overlapped `step` calls cut into learnt chunks);
/// for A/B comparisons in one binary. Read once.
pub fn old_waits() -> bool {
    static OLD: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *OLD.get_or_init(|| std::env::var("RTMPM_BATCH_WAITS").is_ok_and(|v| v.trim() == "old"))
}

/// `RTMPM_SYNC_TRACE`: 0 (unset: count only), 1 (time the waits, print them at the end), 2
/// (also print each wait). Read once.
pub fn trace_level() -> u8 {
    static LEVEL: OnceLock<u8> = OnceLock::new();
    *LEVEL.get_or_init(|| {
        std::env::var("RTMPM_SYNC_TRACE")
            .ok()
            .and_then(|v| v.trim().parse::<u8>().ok())
            .unwrap_or(0)
    })
}

/// The waits of one backend (shared by its parts: the batch's bodies and uploads).
#[derive(Default, Debug)]
pub struct HostWaits {
    counts: [AtomicU64; N],
    nanos: [AtomicU64; N],
}

impl HostWaits {
    /// `work` (which blocks until the device has done something), counted as one wait of
    /// `why` (and timed with `RTMPM_SYNC_TRACE`).
    pub fn wait<T>(&self, why: WaitReason, work: impl FnOnce() -> T) -> T {
        let t0 = (trace_level() > 0).then(Instant::now);
        let r = work();
        self.counts[why.index()].fetch_add(1, Ordering::Relaxed);
        if let Some(t0) = t0 {
            let ns = t0.elapsed().as_nanos() as u64;
            self.nanos[why.index()].fetch_add(ns, Ordering::Relaxed);
            if trace_level() > 1 {
                eprintln!(
                    "rtmpm: host wait ({}) {:.1} us",
                    why.name(),
                    ns as f64 * 1e-3
                );
            }
        }
        r
    }

    /// The counts (and traced seconds) so far.
    pub fn snapshot(&self) -> WaitCounts {
        WaitCounts {
            counts: std::array::from_fn(|i| self.counts[i].load(Ordering::Relaxed)),
            seconds: std::array::from_fn(|i| self.nanos[i].load(Ordering::Relaxed) as f64 * 1e-9),
        }
    }
}

impl Drop for HostWaits {
    /// With `RTMPM_SYNC_TRACE`, the backend's waits in all, on stderr.
    fn drop(&mut self) {
        let all = self.snapshot();
        if trace_level() > 0 && all.total() > 0 {
            eprintln!("rtmpm: host waits for the device: {all}");
        }
    }
}

/// Waits by reason ([`HostWaits::snapshot`]): how many, and (with `RTMPM_SYNC_TRACE`) how long.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WaitCounts {
    /// Waits of each reason, in the order of [`WaitReason::ALL`].
    pub counts: [u64; N],
    /// Their seconds (0 without `RTMPM_SYNC_TRACE`).
    pub seconds: [f64; N],
}

impl WaitCounts {
    /// Waits of reason `why`.
    pub fn get(&self, why: WaitReason) -> u64 {
        self.counts[why.index()]
    }

    /// Waits of every reason.
    pub fn total(&self) -> u64 {
        self.counts.iter().sum()
    }

    /// The waits since `earlier` (a snapshot of the same backend taken before).
    pub fn since(&self, earlier: &WaitCounts) -> WaitCounts {
        WaitCounts {
            counts: std::array::from_fn(|i| self.counts[i].saturating_sub(earlier.counts[i])),
            seconds: std::array::from_fn(|i| self.seconds[i] - earlier.seconds[i]),
        }
    }

    /// (name, count, seconds) of every reason, in the order of [`WaitReason::ALL`].
    pub fn rows(&self) -> impl Iterator<Item = (&'static str, u64, f64)> + '_ {
        WaitReason::ALL
            .iter()
            .map(|r| (r.name(), self.counts[r.index()], self.seconds[r.index()]))
    }
}

impl std::fmt::Display for WaitCounts {
    /// `check 20 (3.1 ms), staging 0, ...`: the reasons with waits (`none` without any).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut first = true;
        for (name, n, s) in self.rows().filter(|r| r.1 > 0) {
            if !first {
                write!(f, ", ")?;
            }
            first = false;
            if s > 0.0 {
                write!(f, "{name} {n} ({:.3} ms)", s * 1e3)?;
            } else {
                write!(f, "{name} {n}")?;
            }
        }
        if first {
            write!(f, "none")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn waits_are_counted_by_reason_and_since_an_earlier_snapshot() {
        let w = HostWaits::default();
        assert_eq!(w.wait(WaitReason::Check, || 7), 7);
        let before = w.snapshot();
        w.wait(WaitReason::Staging, || ());
        w.wait(WaitReason::Staging, || ());
        w.wait(WaitReason::Check, || ());
        let d = w.snapshot().since(&before);
        assert_eq!(d.get(WaitReason::Staging), 2);
        assert_eq!(d.get(WaitReason::Check), 1);
        assert_eq!(d.get(WaitReason::Alloc), 0);
        assert_eq!(d.total(), 3);
        assert_eq!(w.snapshot().get(WaitReason::Check), 2);
        let text = d.to_string();
        assert!(text.starts_with("check 1"), "{text}");
        assert!(text.contains("staging 2"), "{text}");
        assert!(!text.contains("alloc"), "{text}");
        assert_eq!(WaitCounts::default().to_string(), "none");
        let names: Vec<&str> = WaitReason::ALL.iter().map(|r| r.name()).collect();
        assert_eq!(
            names,
            [
                "check", "control", "read", "sums", "staging", "pageable", "alloc", "sync"
            ]
        );
    }
}
