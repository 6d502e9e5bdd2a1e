//! Progress of `rtmpm run`: steps taken in chunks between looks at the clock, a line every few
//! seconds when stderr is not a terminal, and particle-step rates in human units.

use crate::simulation::Simulation;
use std::time::Instant;

/// Steps between two health checks of a multi-process run (every rank the same).
pub const RANK_CHUNK: u64 = 128;

/// Where a run stands: how many steps to take before looking at the clock again, and when the
/// next progress line is due. Periodic progress lines go to stderr when it is not a terminal (a
/// log file, a pipe, a batch job), where the progress bar does not show: every
/// `RTMPM_PROGRESS_SECONDS` (default 10).
pub struct Progress {
    particles: usize,
    frames: u64,
    every: Option<f64>,
    started: Instant,
    last: Instant,
    chunk: u64,
    /// The chunk never changes (multi-process runs).
    fixed: bool,
}

impl Progress {
    /// `fixed_chunk`: steps per chunk whatever the clock says (multi-process runs); `None`
    /// sizes the chunks by their wall time.
    pub fn new(particles: usize, frames: u64, fixed_chunk: Option<u64>) -> Progress {
        use std::io::IsTerminal;
        let every = std::env::var("RTMPM_PROGRESS_SECONDS")
            .ok()
            .and_then(|s| s.parse::<f64>().ok())
            .filter(|s| s.is_finite() && *s >= 0.0)
            .unwrap_or(10.0);
        Progress {
            particles,
            frames,
            every: (!std::io::stderr().is_terminal()).then_some(every),
            started: Instant::now(),
            last: Instant::now(),
            chunk: fixed_chunk.unwrap_or(1).max(1),
            fixed: fixed_chunk.is_some(),
        }
    }

    /// Steps to take before looking at the clock again.
    pub fn chunk(&self) -> u64 {
        self.chunk
    }

    /// Grow the chunk while a chunk takes under a quarter of a second, shrink it above one.
    pub fn chunk_took(&mut self, seconds: f64) {
        if self.fixed {
            return;
        }
        if seconds < 0.25 {
            self.chunk = (self.chunk * 2).min(1 << 16);
        } else if seconds > 1.0 {
            self.chunk = (self.chunk / 2).max(1);
        }
    }

    /// Print a progress line if one is due (stderr not a terminal, `every` seconds since the
    /// last).
    pub fn tick(&mut self, sim: &Simulation, start_step: u64) {
        let Some(every) = self.every else { return };
        if self.last.elapsed().as_secs_f64() < every {
            return;
        }
        self.last = Instant::now();
        let elapsed = self.started.elapsed().as_secs_f64();
        let rate = (sim.step - start_step) as f64 * self.particles as f64 / elapsed.max(1e-9);
        eprintln!(
            "progress: frame {}/{}, t = {:.6} s, dt = {:.3e} s, step {}, {}, elapsed {:.0} s",
            sim.frame,
            self.frames,
            sim.time,
            sim.last_dt,
            sim.step,
            human_rate(rate),
            elapsed
        );
    }
}

/// Particle-steps per second in human units.
pub fn human_rate(r: f64) -> String {
    if r >= 1e9 {
        format!("{:.2} G particle-steps/s", r / 1e9)
    } else if r >= 1e6 {
        format!("{:.2} M particle-steps/s", r / 1e6)
    } else {
        format!("{:.1} k particle-steps/s", r / 1e3)
    }
}

#[cfg(test)]
mod tests {
    use super::Progress;

    #[test]
    fn a_fixed_chunk_ignores_the_clock_and_a_free_one_follows_it() {
        // Multi-process runs: every rank must check health after the same steps.
        let mut fixed = Progress::new(10, 1, Some(128));
        for seconds in [0.0, 5.0, 0.01, 2.0] {
            fixed.chunk_took(seconds);
            assert_eq!(fixed.chunk(), 128);
        }
        let mut free = Progress::new(10, 1, None);
        assert_eq!(free.chunk(), 1);
        free.chunk_took(0.01);
        free.chunk_took(0.01);
        assert_eq!(free.chunk(), 4);
        free.chunk_took(2.0);
        assert_eq!(free.chunk(), 2);
    }
}
