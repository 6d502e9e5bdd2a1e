//! The particle positions of a body, found in parallel and deterministically: the same positions,
//! in the same order, bit for bit, as the one-thread walk, whatever the number of threads.
//!
//! Both walks draw their random numbers from one Pcg64 stream per body (O'Neill, "PCG: A Family
//! of Simple Fast Space-Efficient Statistically Good Algorithms for Random Number Generation",
//! 2014), three `f32` a point, each one step of the generator. A chunk of the walk that starts at
//! point `m` starts the stream `3 m` steps in (`Pcg64::advance`, a jump in O(log m)), so every
//! chunk draws exactly the numbers the one-thread walk draws at its points.
//!
//! * Lattice (regular and jittered sampling): the body's bounding box on the sub-cell lattice,
//!   walked in rows along x (z outermost, then y); a chunk is a run of whole rows.
//! * Random: tries in order, in batches; each batch is split into chunks of [`TRY_CHUNK`] tries,
//!   the accepted points are concatenated in try order and the walk stops at the `count`-th.

use rand::Rng;
use rand_pcg::Pcg64;
use rayon::prelude::*;
use rtmpm_geometry::Shape;
use rtmpm_physics::math::Vec3;
use std::sync::atomic::{AtomicU64, Ordering};

/// Lattice points a chunk of the lattice walk aims at (whole rows: at least one row); small in
/// tests, so that their bodies are walked in many chunks.
pub const LATTICE_CHUNK: u64 = if cfg!(test) { 300 } else { 1 << 16 };
/// Tries of one chunk of the random walk (small in tests, as above).
pub const TRY_CHUNK: u64 = if cfg!(test) { 1000 } else { 1 << 16 };
/// A batch of the random walk tries this many times the tries expected for the particles left
/// (then as many more as needed); under 1 in tests, so that they take several batches.
const BATCH_MARGIN: f64 = if cfg!(test) { 0.4 } else { 1.05 };

/// What a walk keeps: the positions, their count, or only whether there is one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    Keep,
    Count,
    First,
}

/// The positions a walk found, in walk order: `chunks` concatenated (empty unless
/// [`Mode::Keep`]), `count` of them (with [`Mode::First`]: 0 or at least 1).
#[derive(Debug, Default)]
pub struct Walked {
    pub chunks: Vec<Vec<Vec3>>,
    pub count: u64,
    /// Random walks: the tries made (in whole batches) and the points accepted among them (at
    /// least `count`: the last batch may find more than it keeps).
    pub tries: u64,
    pub accepted: u64,
}

/// Work done so far by a walk (lattice points visited or random tries) and the work expected,
/// for progress reports.
pub struct Counter<'a> {
    done: AtomicU64,
    total: AtomicU64,
    report: &'a (dyn Fn(u64, u64) + Sync),
}

impl<'a> Counter<'a> {
    /// A counter that calls `report(done, expected)` after every chunk.
    pub fn new(report: &'a (dyn Fn(u64, u64) + Sync)) -> Counter<'a> {
        Counter {
            done: AtomicU64::new(0),
            total: AtomicU64::new(0),
            report,
        }
    }

    /// Set the work expected.
    pub fn expect(&self, total: u64) {
        self.total.store(total, Ordering::Relaxed);
    }

    fn add(&self, n: u64) {
        let done = self.done.fetch_add(n, Ordering::Relaxed) + n;
        (self.report)(done, self.total.load(Ordering::Relaxed));
    }
}

/// The sub-cell lattice of a body's bounding box: points `origin + (i + 1/2, j + 1/2, k + 1/2) h`
/// for `i0 <= i < i0 + nx` and so on.
#[derive(Clone, Copy, Debug)]
pub struct Lattice {
    pub origin: Vec3,
    pub h: f32,
    pub first: [i64; 3],
    pub count: [u64; 3],
    pub jitter: bool,
}

impl Lattice {
    /// Points of the lattice (saturating).
    pub fn points(&self) -> u64 {
        self.count[0]
            .saturating_mul(self.count[1])
            .saturating_mul(self.count[2])
    }

    /// Walk rows `rows` (row `r` is `k = k0 + r / ny`, `j = j0 + r % ny`), calling `add` with
    /// every point inside `shape` until it returns false.
    fn rows(
        &self,
        shape: &Shape,
        rng: &Pcg64,
        rows: std::ops::Range<u64>,
        mut add: impl FnMut(Vec3) -> bool,
    ) {
        let [nx, ny, _] = self.count;
        let mut rng = rng.clone();
        if self.jitter {
            rng.advance(3 * rows.start as u128 * nx as u128);
        }
        let h = self.h;
        for r in rows {
            let k = self.first[2] + (r / ny) as i64;
            let j = self.first[1] + (r % ny) as i64;
            for i in self.first[0]..self.first[0] + nx as i64 {
                let mut x =
                    self.origin + Vec3::new(i as f32 + 0.5, j as f32 + 0.5, k as f32 + 0.5) * h;
                if self.jitter {
                    let r = Vec3::new(
                        rng.random::<f32>() - 0.5,
                        rng.random::<f32>() - 0.5,
                        rng.random::<f32>() - 0.5,
                    );
                    x += r * h;
                }
                if shape.contains(x) && !add(x) {
                    return;
                }
            }
        }
    }

    /// Rows of the lattice (`ny nz`; row `r` is `k = k0 + r / ny`, `j = j0 + r % ny`).
    pub fn rows_count(&self) -> u64 {
        self.count[1].saturating_mul(self.count[2])
    }

    /// Chunks of rows of the walk (as [`Lattice::walk`] cuts them).
    pub fn chunk_count(&self) -> u64 {
        let nx = self.count[0];
        if nx == 0 {
            return 0;
        }
        self.rows_count().div_ceil((LATTICE_CHUNK / nx).max(1))
    }

    /// The positions of chunk `c` of the walk, in order.
    pub fn chunk(&self, shape: &Shape, rng: &Pcg64, c: u64) -> Vec<Vec3> {
        let per_chunk = (LATTICE_CHUNK / self.count[0].max(1)).max(1);
        let range = c * per_chunk..((c + 1) * per_chunk).min(self.rows_count());
        let mut v = Vec::new();
        self.rows(shape, rng, range, |x| {
            v.push(x);
            true
        });
        v
    }

    /// Walk the whole lattice in parallel chunks of rows.
    pub fn walk(&self, shape: &Shape, rng: &Pcg64, mode: Mode, counter: &Counter) -> Walked {
        let [nx, ny, nz] = self.count;
        if nx == 0 || ny == 0 || nz == 0 {
            return Walked::default();
        }
        let rows = ny * nz;
        counter.expect(self.points());
        let per_chunk = (LATTICE_CHUNK / nx).max(1);
        let chunks = rows.div_ceil(per_chunk);
        let range = |c: u64| c * per_chunk..((c + 1) * per_chunk).min(rows);
        let done = |c: u64| counter.add((range(c).end - range(c).start) * nx);
        match mode {
            Mode::Keep => {
                let chunks: Vec<Vec<Vec3>> = (0..chunks)
                    .into_par_iter()
                    .map(|c| {
                        let mut v = Vec::new();
                        self.rows(shape, rng, range(c), |x| {
                            v.push(x);
                            true
                        });
                        done(c);
                        v
                    })
                    .collect();
                let count = chunks.iter().map(|c| c.len() as u64).sum();
                Walked {
                    chunks,
                    count,
                    ..Walked::default()
                }
            }
            Mode::Count => {
                let count = (0..chunks)
                    .into_par_iter()
                    .map(|c| {
                        let mut n = 0u64;
                        self.rows(shape, rng, range(c), |_| {
                            n += 1;
                            true
                        });
                        done(c);
                        n
                    })
                    .sum();
                Walked {
                    count,
                    ..Walked::default()
                }
            }
            Mode::First => {
                let any = (0..chunks).into_par_iter().any(|c| {
                    let mut found = false;
                    self.rows(shape, rng, range(c), |_| {
                        found = true;
                        false
                    });
                    done(c);
                    found
                });
                Walked {
                    count: any as u64,
                    ..Walked::default()
                }
            }
        }
    }
}

/// The tries of a random walk that placed `count` points in `tries` tries ([`random`]): its
/// positions again, in chunks of [`TRY_CHUNK`] tries, without the batches.
#[derive(Clone, Copy, Debug)]
pub struct RandomTries {
    pub lo: Vec3,
    pub hi: Vec3,
    pub tries: u64,
    pub count: u64,
}

impl RandomTries {
    /// Chunks of [`TRY_CHUNK`] tries.
    pub fn chunk_count(&self) -> u64 {
        self.tries.div_ceil(TRY_CHUNK)
    }

    /// The accepted points of chunk `c`'s tries, in order (all of them, past `count` too).
    fn tries_of(&self, shape: &Shape, rng: &Pcg64, c: u64, mut f: impl FnMut(Vec3)) {
        let t0 = c * TRY_CHUNK;
        let t1 = (t0 + TRY_CHUNK).min(self.tries);
        let mut r = rng.clone();
        r.advance(3 * t0 as u128);
        for _ in t0..t1 {
            let u = Vec3::new(r.random::<f32>(), r.random::<f32>(), r.random::<f32>());
            let x = self.lo + u * (self.hi - self.lo);
            if shape.contains(x) {
                f(x);
            }
        }
    }

    /// The index of each chunk's first accepted point (`chunk_count + 1` entries).
    pub fn starts(&self, shape: &Shape, rng: &Pcg64) -> Vec<u64> {
        let counts: Vec<u64> = (0..self.chunk_count())
            .into_par_iter()
            .map(|c| {
                let mut n = 0;
                self.tries_of(shape, rng, c, |_| n += 1);
                n
            })
            .collect();
        let mut starts = vec![0u64];
        for n in counts {
            starts.push(starts[starts.len() - 1] + n);
        }
        starts
    }

    /// The positions of chunk `c` (its first point's index `start`, from [`RandomTries::starts`])
    /// that are among the walk's `count`.
    pub fn chunk(&self, shape: &Shape, rng: &Pcg64, c: u64, start: u64) -> Vec<Vec3> {
        let mut v = Vec::new();
        let keep = self.count.saturating_sub(start) as usize;
        self.tries_of(shape, rng, c, |x| {
            if v.len() < keep {
                v.push(x)
            }
        });
        v
    }
}

/// Uniformly random points of the box `[lo, hi]` kept inside `shape`, in try order, until `count`
/// are placed (with [`Mode::First`]: until one is) or `max_tries` tries are spent. Returns the
/// points and how many were placed (fewer than the target only when the tries ran out).
#[allow(clippy::too_many_arguments)]
pub fn random(
    shape: &Shape,
    lo: Vec3,
    hi: Vec3,
    count: u64,
    fill: f64,
    max_tries: u64,
    rng: &Pcg64,
    mode: Mode,
    counter: &Counter,
) -> Walked {
    let target = if mode == Mode::First {
        count.min(1)
    } else {
        count
    };
    let keep = mode == Mode::Keep;
    counter.expect((target as f64 / fill.max(1e-30)).min(max_tries as f64) as u64);
    let mut out = Walked::default();
    let mut tries = 0u64;
    while out.count < target && tries < max_tries {
        // Enough tries for what is left (5 % more than expected), at most what is allowed.
        let need = (target - out.count) as f64 / fill.max(1e-30);
        let batch = ((need * BATCH_MARGIN).min(max_tries as f64) as u64)
            .saturating_add(TRY_CHUNK)
            .min(max_tries - tries);
        let start = tries;
        let results: Vec<(u64, Vec<Vec3>)> = (0..batch.div_ceil(TRY_CHUNK))
            .into_par_iter()
            .map(|c| {
                let t0 = start + c * TRY_CHUNK;
                let t1 = (t0 + TRY_CHUNK).min(start + batch);
                let mut r = rng.clone();
                r.advance(3 * t0 as u128);
                let (mut n, mut v) = (0u64, Vec::new());
                for _ in t0..t1 {
                    let u = Vec3::new(r.random::<f32>(), r.random::<f32>(), r.random::<f32>());
                    let x = lo + u * (hi - lo);
                    if shape.contains(x) {
                        n += 1;
                        if keep {
                            v.push(x);
                        }
                    }
                }
                counter.add(t1 - t0);
                (n, v)
            })
            .collect();
        tries += batch;
        out.tries = tries;
        out.accepted += results.iter().map(|r| r.0).sum::<u64>();
        for (n, mut v) in results {
            let left = target - out.count;
            if n >= left {
                v.truncate(left as usize);
                out.count = target;
                if keep {
                    out.chunks.push(v);
                }
                break;
            }
            out.count += n;
            if keep {
                out.chunks.push(v);
            }
        }
    }
    out
}
