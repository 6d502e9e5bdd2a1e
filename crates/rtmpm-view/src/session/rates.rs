//! Rates over the last second of wall-clock time: steps, particle-steps and pictures per
//! second for the heads-up line.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// The window the rates are taken over.
const WINDOW: Duration = Duration::from_secs(1);

/// Samples of (when, steps so far, particle-steps so far, pictures so far).
#[derive(Default)]
pub struct Rates {
    samples: VecDeque<(Instant, u64, f64, u64)>,
    /// Steps and particle-steps of previous simulations (before resets), so counts only grow.
    steps: u64,
    particle_steps: f64,
}

impl Rates {
    /// Count `steps` more steps of `particles` particles.
    pub fn stepped(&mut self, steps: u64, particles: u64) {
        self.steps += steps;
        self.particle_steps += steps as f64 * particles as f64;
    }

    /// A picture was published at `now` (the `pictures`-th); returns steps/s,
    /// particle-steps/s and pictures/s over the last second.
    pub fn sample(&mut self, now: Instant, pictures: u64) -> (f64, f64, f64) {
        self.samples
            .push_back((now, self.steps, self.particle_steps, pictures));
        while self
            .samples
            .front()
            .is_some_and(|s| now.duration_since(s.0) > WINDOW)
            && self.samples.len() > 2
        {
            self.samples.pop_front();
        }
        let (Some(a), Some(b)) = (self.samples.front(), self.samples.back()) else {
            return (0.0, 0.0, 0.0);
        };
        let dt = b.0.duration_since(a.0).as_secs_f64();
        if dt <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        (
            (b.1 - a.1) as f64 / dt,
            (b.2 - a.2) / dt,
            (b.3 - a.3) as f64 / dt,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates_are_counts_over_the_window() {
        let mut r = Rates::default();
        let t0 = Instant::now();
        assert_eq!(r.sample(t0, 1), (0.0, 0.0, 0.0));
        r.stepped(10, 100);
        let (s, ps, fps) = r.sample(t0 + Duration::from_millis(500), 2);
        assert!((s - 20.0).abs() < 1e-9 && (ps - 2000.0).abs() < 1e-6 && (fps - 2.0).abs() < 1e-9);
        // Samples older than the window drop out.
        r.stepped(5, 100);
        let (s, _, _) = r.sample(t0 + Duration::from_millis(2500), 3);
        assert!((s - 2.5).abs() < 1e-9, "{s}");
    }
}
