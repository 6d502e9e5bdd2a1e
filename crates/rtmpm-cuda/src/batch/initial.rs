//! Resets to the initial state without packing or upload: every world's particles at time 0
//! kept on the device as one packed image ([`CudaBatch::keep_initial`]), and worlds put back
//! from it by launches alone ([`CudaBatch::put_initial`]).
//!
//! Why: a reset of a few worlds through [`CudaBatch::put_worlds`] gathers their particles,
//! packs them into the state's words and uploads the image, every call (for 4 worlds of 1,024
//! particles, 475 KB packed and copied: most of a Python step loop's host time a reset call);
//! the image of the initial particles is the same every time. Kept once, a reset is one
//! put launch per run of consecutive worlds reading it in place (its rows have the
//! stride of the whole image, `kernels/batch.cu`). The words put are the same as a put of those
//! particles packs (the same packing, [`crate::state::pack_into`], of the same particles: only
//! the id word, which the kernel skips, and the stride differ), so a world put back either way
//! is the same bit for bit. `RTMPM_BATCH_RESET=old` keeps nothing (resets then put the
//! particles as before; for A/B comparisons in one binary).

use super::CudaBatch;
use super::put_slots::within_x;
use super::staging::old_resets;
use crate::error::err;
use crate::waits::WaitReason;
use rtmpm_physics::Particles;
use rtmpm_sim::SimError;

/// `RTMPM_RESET_TIMING=1`: where a put from the kept image spends the host's time, printed to
/// stderr every 100 puts (the means of finding the runs of worlds and of the launches); off by
/// default.
static INITIAL_TIMING: rtmpm_sim::timing::PartTimes<2> = rtmpm_sim::timing::PartTimes::new(
    "RTMPM_RESET_TIMING",
    "put_initial",
    "worlds",
    ["runs", "launches"],
);

/// Device memory [`CudaBatch::keep_initial`] leaves free past the image and the rewind point
/// (the puts' buffer, the device arrays, other users of the GPU).
const SPARE_BYTES: usize = 256 << 20;

impl CudaBatch {
    /// Keep every world's particles at time 0, `initial[w]` (world `w`'s, in its own material
    /// indices; what a reset puts back), on the device as one packed image (original order,
    /// rows of the batch's particle count), so that [`CudaBatch::put_initial`] puts worlds back
    /// to them with launches alone. Packed on the host and uploaded once (as much device memory
    /// as the particle state's rows; replaced by a later call). `Ok(false)`: nothing kept, the
    /// device's free memory would not also hold the rewind point and 256 MB more, or
    /// `RTMPM_BATCH_RESET=old` (resets then put the particles with [`CudaBatch::put_worlds`]). Refused, before anything is kept, when `initial` does
    /// not fit the worlds (their count, each world's particles, their materials).
    pub fn keep_initial(&mut self, initial: &[Particles]) -> Result<bool, SimError> {
        if initial.len() != self.worlds() {
            return Err(SimError::Backend(format!(
                "CUDA batch: initial particles of {} worlds given, the batch has {}",
                initial.len(),
                self.worlds()
            )));
        }
        for (w, p) in initial.iter().enumerate() {
            self.check_put(w, p)?;
        }
        self.initial = None;
        if old_resets() {
            return Ok(false);
        }
        let bytes = self.initial_image(initial)?;
        let b = &mut self.backend;
        let stream = b.stream.clone();
        // Not at the cost of the rewind point (as large as the state, allocated at the first
        // advance) or of the memory the batch's other buffers may still ask for.
        let point = if self.point.is_none() {
            b.buffers.state.len()
        } else {
            0
        };
        let (free, _) = stream
            .context()
            .mem_get_info()
            .map_err(err("memory info"))?;
        if free < bytes.len() + point + SPARE_BYTES {
            return Ok(false);
        }
        // SAFETY: the copy below writes every byte before a launch reads it.
        let Ok(mut buf) = b.waits.wait(WaitReason::Alloc, || unsafe {
            stream.alloc::<u8>(bytes.len())
        }) else {
            return Ok(false);
        };
        // Once, at the batch's set-up: from pageable memory (which may wait for the stream).
        b.waits.wait(WaitReason::Pageable, || ());
        stream
            .memcpy_htod(&bytes, &mut buf)
            .map_err(err("upload the worlds' initial particles"))?;
        self.initial = Some(buf);
        let (lo, hi) = (self.clock.domain_min.x, self.clock.domain_max.x);
        self.initial_within = initial.iter().all(|p| within_x(p, lo, hi));
        Ok(true)
    }

    /// Bytes of the image [`CudaBatch::keep_initial`] kept on the device (0: none).
    pub fn initial_bytes(&self) -> usize {
        self.initial.as_ref().map_or(0, |b| b.len())
    }

    /// The packed image of every world's `initial` particles (their materials as the kernels'
    /// rows, `w * materials + k`), rows of the batch's particle count: [`crate::state::pack_into`]
    /// of them all, as [`CudaBatch::put_worlds`] packs a run of worlds.
    fn initial_image(&self, initial: &[Particles]) -> Result<Vec<u8>, SimError> {
        let mut all = Particles::default();
        for (w, p) in initial.iter().enumerate() {
            let at = all.len();
            all.extend(p);
            for k in &mut all.material[at..] {
                *k += (w * self.materials) as u32;
            }
        }
        let fluid = crate::state::fluid_materials(&self.backend.scene);
        let (layout, f64) = (self.backend.layout, self.backend.options.f64);
        let mut bytes = Vec::new();
        crate::state::pack_into(&all, &fluid, layout, f64, all.len(), &mut bytes)
            .map_err(SimError::Backend)?;
        Ok(bytes)
    }

    /// Put each world of `worlds` back to its particles kept by [`CudaBatch::keep_initial`], as
    /// [`CudaBatch::put_worlds`] of those particles does (the same words, the mapping rebuilt
    /// only where a particle put leaves its zone, the P2G redone at the next step with G2P2G),
    /// with no packing and no upload: one put launch a run of consecutive worlds
    /// listed, reading the kept image in place, queued on the stream (no wait). Every world is
    /// checked before any changes (a world listed twice is put once). `Ok(false)`: no image kept
    /// (nothing changed; put the particles with [`CudaBatch::put_worlds`]).
    pub fn put_initial(&mut self, worlds: &[usize]) -> Result<bool, SimError> {
        if self.initial.is_none() {
            return Ok(false);
        }
        let t0 = std::time::Instant::now();
        if let Some(&w) = worlds.iter().find(|&&w| w >= self.worlds()) {
            return Err(SimError::Backend(format!(
                "CUDA batch: no world {w} (the batch has {})",
                self.worlds()
            )));
        }
        let runs = initial_runs(worlds, &self.offsets);
        let t1 = std::time::Instant::now();
        if !self.initial_within {
            self.put_slots.doubt();
        }
        let Some(image) = self.initial.as_ref() else {
            return Ok(false);
        };
        let word = if self.backend.options.f64 { 8 } else { 4 };
        let stride = self.backend.n as u32;
        for &(first, count) in &runs {
            // Rows of the whole image (stride n), from particle `first` of its first row.
            self.launch_put(&image.slice(first as usize * word..), first, count, stride)
                .map_err(err("put worlds back to their initial particles"))?;
        }
        if !runs.is_empty() {
            self.note_put(worlds.iter().copied())?;
        }
        INITIAL_TIMING.record(worlds.len(), [t0, t1], std::time::Instant::now());
        Ok(true)
    }
}

/// The runs of consecutive worlds among `worlds` (any order, repeats allowed; each below
/// `offsets.len() - 1`) as (first particle, particles), in world order: world `w`'s particles
/// are `offsets[w]..offsets[w + 1]`. Proportional to the worlds listed, not to the batch.
pub(super) fn initial_runs(worlds: &[usize], offsets: &[usize]) -> Vec<(u32, u32)> {
    let mut sorted = worlds.to_vec();
    sorted.sort_unstable();
    sorted.dedup();
    let mut runs: Vec<(u32, u32)> = Vec::new();
    let mut last = None;
    for w in sorted {
        let (first, end) = (offsets[w] as u32, offsets[w + 1] as u32);
        match runs.last_mut() {
            Some(run) if last == Some(w.wrapping_sub(1)) => run.1 = end - run.0,
            _ => runs.push((first, end - first)),
        }
        last = Some(w);
    }
    runs
}

#[cfg(test)]
mod tests {
    use super::initial_runs;
    use rtmpm_physics::Particles;
    use std::time::Instant;

    /// Runs join consecutive worlds only, in world order, whatever the order and repeats given;
    /// each covers exactly its worlds' particles (worlds of 3, 5, 2, 4 and 6 particles).
    #[test]
    fn runs_cover_the_listed_worlds_particles_and_no_others() {
        let offsets = [0, 3, 8, 10, 14, 20];
        assert_eq!(initial_runs(&[], &offsets), vec![]);
        assert_eq!(initial_runs(&[2], &offsets), vec![(8, 2)]);
        assert_eq!(initial_runs(&[1, 2], &offsets), vec![(3, 7)]);
        assert_eq!(initial_runs(&[2, 1, 2, 1], &offsets), vec![(3, 7)]);
        assert_eq!(
            initial_runs(&[4, 0, 2], &offsets),
            vec![(0, 3), (8, 2), (14, 6)]
        );
        assert_eq!(
            initial_runs(&[0, 1, 3, 4], &offsets),
            vec![(0, 8), (10, 10)]
        );
        assert_eq!(initial_runs(&[0, 1, 2, 3, 4], &offsets), vec![(0, 20)]);
    }

    /// The sand bed of bench/python_batch_gpu.py (1,024 particles a world).
    fn sand_bed() -> rtmpm_scene::Scene {
        let text = "[domain]\nmin = [0,0,0]\nmax = [0.4,0.35,0.4]\ndx = 0.025\n[time]\n\
                    duration = 1.0\ndt = 4e-4\n[[material]]\nname = \"sand\"\n\
                    type = \"drucker_prager\"\ndensity = 1600.0\nyoungs_modulus = 5e5\n\
                    poisson_ratio = 0.3\nfriction_angle = 35.0\n[[body]]\nmaterial = \"sand\"\n\
                    shape = \"box\"\nmin = [0.1, 0.1, 0.1]\nmax = [0.3, 0.15, 0.3]\n\
                    particles_per_cell = 8\n";
        rtmpm_scene::Scene::from_toml(text, "test").unwrap_or_else(|e| panic!("{e}"))
    }

    /// The host's work of a reset call of bench/python_batch_gpu.py (256 worlds of 1,024 sand
    /// particles, 4 consecutive worlds reset a call) on this machine, with no GPU
    /// (`cargo test --release -p rtmpm-cuda --lib reset_host_timing -- --ignored --nocapture`):
    /// the parts of the put as before the kept image (`RTMPM_BATCH_RESET=old`): the start states
    /// (Python's copies of the initial particles, which both paths make: the driver keeps them),
    /// the run gathered, packed ([`crate::state::pack_into`], on every core) and copied into
    /// page-locked memory (here a kept host buffer); and the kept image's host work (the runs).
    /// With `cold`, 64 MB written between calls (the step's work on the other cores and the
    /// device's leave the worlds' memory out of this thread's caches). Prints medians of 200.
    #[test]
    #[ignore = "a timing, not a check"]
    fn reset_host_timing() {
        let scene = sand_bed();
        let p = scene.sample_particles().expect("particles");
        assert_eq!(p.len(), 1024);
        let (worlds, k) = (256, 4);
        let initial: Vec<Particles> = (0..worlds).map(|_| p.clone()).collect();
        let offsets: Vec<usize> = (0..=worlds).map(|w| w * p.len()).collect();
        let mut merged = scene.clone();
        merged.materials = (0..worlds).flat_map(|_| scene.materials.clone()).collect();
        let fluid = crate::state::fluid_materials(&merged);
        let layout =
            crate::state::layout_for(&merged, &crate::CudaOptions::default()).expect("layout");
        let mut junk = vec![0u8; 64 << 20];
        let (mut run, mut bytes, mut pinned) = (Particles::default(), Vec::new(), Vec::new());
        let med = |mut v: Vec<f64>| {
            v.sort_by(f64::total_cmp);
            1e6 * v[v.len() / 2]
        };
        for cold in [false, true] {
            let mut parts: [Vec<f64>; 5] = Default::default();
            for c in 0..200 {
                if cold {
                    for (i, b) in junk.iter_mut().enumerate().step_by(64) {
                        *b = b.wrapping_add(i as u8);
                    }
                }
                let list: Vec<usize> = (0..k).map(|j| (c * k + j) % worlds).collect();
                let t0 = Instant::now();
                let starts: Vec<Particles> = list.iter().map(|&w| initial[w].clone()).collect();
                let t1 = Instant::now();
                super::super::put::clear_particles(&mut run);
                for (&w, s) in list.iter().zip(&starts) {
                    let at = run.len();
                    run.extend(s);
                    for m in &mut run.material[at..] {
                        *m += w as u32;
                    }
                }
                let t2 = Instant::now();
                bytes.clear();
                crate::state::pack_into(&run, &fluid, layout, false, run.len(), &mut bytes)
                    .expect("pack");
                let t3 = Instant::now();
                pinned.resize(bytes.len(), 0u8);
                pinned.copy_from_slice(&bytes);
                let t4 = Instant::now();
                let runs = initial_runs(&list, &offsets);
                let t5 = Instant::now();
                std::hint::black_box((&starts, &pinned, &runs));
                for (i, (a, b)) in [(t0, t1), (t1, t2), (t2, t3), (t3, t4), (t4, t5)]
                    .into_iter()
                    .enumerate()
                {
                    parts[i].push((b - a).as_secs_f64());
                }
            }
            let [start, gather, pack, copy, runs] = parts.map(med);
            println!(
                "caches {}: start states {start:.1} us; before the kept image: gather {gather:.1} \
                 us, pack {pack:.1} us, copy of the image ({} KB) {copy:.1} us; the kept image's \
                 runs {runs:.2} us (medians of 200 calls of {k} resets, {worlds} worlds of {} \
                 particles)",
                if cold { "flushed" } else { "warm" },
                pinned.len() / 1024,
                p.len()
            );
        }
        std::hint::black_box(&junk);
    }
}
