//! The set-up of a run before its first step: sampling the bodies (with progress lines on
//! stderr, also when it is not a terminal) and building the backend, timed.

use anyhow::Result;
use rtmpm_physics::Particles;
use rtmpm_scene::sampling::{SampleProgress, SampledBody};
use rtmpm_scene::{Scene, sampling};
use std::sync::Mutex;
use std::time::Instant;

/// Seconds between two progress lines of the set-up: `RTMPM_PROGRESS_SECONDS` (as for the
/// steps), else 5.
fn every() -> f64 {
    std::env::var("RTMPM_PROGRESS_SECONDS")
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s >= 0.0)
        .unwrap_or(5.0)
}

/// One progress line of the sampling.
fn line(p: SampleProgress, elapsed: f64) -> String {
    let pct = 100.0 * p.done as f64 / p.total.max(1) as f64;
    format!(
        "set-up: sampling body {} of {}: {:.0} % ({:.3e} of {:.3e} positions tried), {elapsed:.0} s",
        p.body + 1,
        p.bodies,
        pct.min(100.0),
        p.done as f64,
        p.total as f64
    )
}

/// The time the set-up took, phase by phase.
#[derive(Clone, Copy, Debug, Default)]
pub struct SetupTimes {
    /// Sampling the bodies (s).
    pub sample: f64,
    /// Building the backend: for CUDA the host's packing, the upload, the kernels (s).
    pub backend: f64,
}

impl SetupTimes {
    /// The whole set-up (s).
    pub fn total(&self) -> f64 {
        self.sample + self.backend
    }

    /// "12.3 s (sampling 4.5 s, backend 7.8 s)".
    pub fn describe(&self) -> String {
        format!(
            "{:.2} s (sampling {:.2} s, backend {:.2} s)",
            self.total(),
            self.sample,
            self.backend
        )
    }
}

/// The progress reporter of a sampling started at `start`: a line every `every` seconds.
fn reporter(start: Instant, every: f64) -> impl Fn(SampleProgress) + Sync {
    let last = Mutex::new(Instant::now());
    move |p: SampleProgress| {
        // Only one thread looks at the clock at a time; the others go on.
        if let Ok(mut last) = last.try_lock()
            && last.elapsed().as_secs_f64() >= every
        {
            *last = Instant::now();
            eprintln!("{}", line(p, start.elapsed().as_secs_f64()));
        }
    }
}

/// [`sample`], the bodies' positions only (for a backend that packs them itself); with `defer`
/// the bodies a GPU can draw are only counted (`rtmpm_scene::deferred`: the host keeps
/// none of their positions).
pub fn sample_bodies(scene: &Scene, defer: bool) -> Result<(Vec<SampledBody>, f64)> {
    let start = Instant::now();
    let every = every();
    let report = reporter(start, every);
    let bodies = if defer {
        rtmpm_scene::deferred::sample_bodies_deferred(scene, &report)?
    } else {
        sampling::sample_bodies(scene, &report)?
    };
    let seconds = start.elapsed().as_secs_f64();
    if seconds >= every {
        let n: usize = bodies.iter().map(|b| b.len()).sum();
        eprintln!("set-up: sampled {n} particles in {seconds:.1} s");
    }
    Ok((bodies, seconds))
}

/// Sample the scene's bodies, printing a progress line every few seconds while it lasts and a
/// summary when it took more than one such period; returns the particles and the seconds taken.
pub fn sample(scene: &Scene) -> Result<(Particles, f64)> {
    let start = Instant::now();
    let every = every();
    let particles = scene.sample_particles_with(&reporter(start, every))?;
    let seconds = start.elapsed().as_secs_f64();
    if seconds >= every {
        eprintln!(
            "set-up: sampled {} particles in {seconds:.1} s",
            particles.len()
        );
    }
    Ok((particles, seconds))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_progress_line_says_body_share_and_time() {
        let p = SampleProgress {
            body: 1,
            bodies: 4,
            done: 250,
            total: 1000,
        };
        let l = line(p, 12.4);
        assert!(
            l.contains("body 2 of 4") && l.contains("25 %") && l.ends_with("12 s"),
            "{l}"
        );
    }
}
