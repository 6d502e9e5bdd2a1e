//! The inter-GPU synchronisation of transport=p2p (the GPUs of one process), two kinds
//! (`--cuda-options barrier=spin|events`):
//!
//! - spin (the spin-lock barrier of Fei, Huang & Gao, "Real-Time Simulation of MPM on Modern GPUs" (GTC 2022)): `kernels/multi/barrier.cu`, a one-thread kernel on every GPU
//!   that adds 1 to a counter in GPU 0's memory with a system-scope atomic and spins until every
//!   GPU arrived. Everything stays on the device, so a step with barriers is captured in a CUDA
//!   graph and replayed like a single-GPU step.
//! - events: every GPU records an event on its stream and its stream waits on the other GPUs'
//!   events (`cuStreamWaitEvent` across devices). A wait binds to the event's most recent record
//!   at the time it is enqueued, so the host threads meet ([`HostBarrier`]) between recording and
//!   waiting; a CUDA graph launched later could not bind to the peers' records of the same step,
//!   so this kind runs without CUDA graphs.

use crate::contract::Ctx;
use crate::kernels::{Kernel, Kernels, cfg};
use cudarc::driver::{CudaStream, DriverError, PushKernelArg};
use std::sync::{Condvar, Mutex};
use std::time::Duration;

pub use crate::contract::SpinBarrier;

/// How long a GPU (spin) or a host thread (events) waits for the others before giving up.
pub const TIMEOUT: Duration = Duration::from_secs(10);

/// Enqueue the spin barrier on `s`.
pub(crate) fn enqueue_spin(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    b: &SpinBarrier,
) -> Result<(), DriverError> {
    // SAFETY: `count` and `calls` are live u64 on GPUs this one has peer access to.
    unsafe {
        s.launch_builder(&k[Kernel::BarrierSpin])
            .arg(c)
            .arg(b)
            .launch(cfg(1, 1))?;
    }
    Ok(())
}

/// Make `s` wait for the most recent record of each event (`CUevent` handles as integers, of any
/// GPU of this process).
pub(crate) fn wait_events(s: &CudaStream, events: &[usize]) -> Result<(), DriverError> {
    for &e in events {
        // SAFETY: `e` is a live event of this process; a stream may wait on another device's event.
        unsafe {
            cudarc::driver::sys::cuStreamWaitEvent(
                s.cu_stream(),
                e as cudarc::driver::sys::CUevent,
                0,
            )
        }
        .result()?;
    }
    Ok(())
}

/// A reusable barrier of the host threads driving the GPUs (events kind), with a time limit so
/// that a thread that failed cannot hang the others.
pub struct HostBarrier {
    n: usize,
    state: Mutex<(u64, usize)>,
    cv: Condvar,
}

impl HostBarrier {
    /// A barrier of `n` threads.
    pub fn new(n: usize) -> HostBarrier {
        HostBarrier {
            n,
            state: Mutex::new((0, 0)),
            cv: Condvar::new(),
        }
    }

    /// Wait until all `n` threads called `wait` (generation by generation).
    pub fn wait(&self, timeout: Duration) -> Result<(), String> {
        let mut g = self
            .state
            .lock()
            .map_err(|_| "host barrier poisoned".to_string())?;
        let round = g.0;
        g.1 += 1;
        if g.1 == self.n {
            g.0 += 1;
            g.1 = 0;
            self.cv.notify_all();
            return Ok(());
        }
        let (g, t) = self
            .cv
            .wait_timeout_while(g, timeout, |s| s.0 == round)
            .map_err(|_| "host barrier poisoned".to_string())?;
        if t.timed_out() && g.0 == round {
            return Err(format!(
                "the GPU threads did not meet within {} s (another GPU's thread failed)",
                timeout.as_secs()
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;
    use std::sync::atomic::{AtomicUsize, Ordering};

    #[test]
    fn host_barrier_lets_no_thread_pass_before_all_arrived() {
        let n = 3;
        let b = Arc::new(HostBarrier::new(n));
        let arrived = Arc::new(AtomicUsize::new(0));
        let hs: Vec<_> = (0..n)
            .map(|_| {
                let (b, arrived) = (b.clone(), arrived.clone());
                std::thread::spawn(move || {
                    for round in 1..=50 {
                        arrived.fetch_add(1, Ordering::SeqCst);
                        b.wait(TIMEOUT).unwrap();
                        // Everyone arrived at this round before anyone passed it.
                        assert!(arrived.load(Ordering::SeqCst) >= round * n);
                        b.wait(TIMEOUT).unwrap();
                    }
                })
            })
            .collect();
        for h in hs {
            h.join().unwrap();
        }
    }

    #[test]
    fn host_barrier_times_out_when_a_thread_is_missing() {
        let b = HostBarrier::new(2);
        let e = b.wait(Duration::from_millis(20)).unwrap_err();
        assert!(e.contains("did not meet"), "{e}");
    }
}
