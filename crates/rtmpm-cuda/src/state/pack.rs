//! The device image of the particles, packed on the host in parallel: from [`Particles`]
//! ([`pack`]) or straight from the positions of sampled bodies ([`pack_bodies`]), and what the
//! device fill needs of a body ([`body_constant_words`]); the sampled bodies' positions and
//! speeds in the packing's order ([`map_positions`], [`max_speed`]).

use super::fields::*;
use super::word::Word;
use crate::contract::StateLayout;
use rayon::prelude::*;
use rtmpm_physics::Particles;
use rtmpm_physics::math::{Mat3, Vec3};
use rtmpm_scene::sampling::{BodyPositions, SampledBody};

/// The device image of `particles` (f64 words when `f64`), SoA with stride `cap` (at least the
/// particle count; the words past the particles are zero); `fluid` has one entry per material
/// (true for a fluid) and materials must be below its length. `ids`: the original index of each
/// particle (one GPU of several), else 0..n. A fluid particle's F is written as J^(1/3) I with
/// J = det F: the form the fluid's projection keeps it in (the same J, so the same stress), which
/// the kernels rely on to read and write only its diagonal (`load_deformation` in state.cuh); a
/// fluid layout keeps the one word J^(1/3) (every material must then be a fluid).
pub fn pack(
    particles: &Particles,
    fluid: &[bool],
    layout: StateLayout,
    f64: bool,
    cap: usize,
    ids: Option<&[u32]>,
) -> Result<Vec<u8>, String> {
    check_layout(fluid, layout, f64)?;
    if f64 {
        pack_words::<f64>(particles, fluid, layout, cap, ids)
    } else {
        pack_words::<f32>(particles, fluid, layout, cap, ids)
    }
}

/// [`pack`] appended to `out`: its bytes so far kept, the image (stride `cap`) after them, in
/// memory the caller keeps between calls (a GPU batch's puts pack a few worlds a call, where
/// a fresh image's allocation and first touch of its pages cost more than the packing), in
/// tasks of a few hundred particles on every core (the same bytes as [`pack`]'s).
pub fn pack_into(
    particles: &Particles,
    fluid: &[bool],
    layout: StateLayout,
    f64: bool,
    cap: usize,
    out: &mut Vec<u8>,
) -> Result<(), String> {
    check_layout(fluid, layout, f64)?;
    if f64 {
        pack_words_into::<f64>(particles, fluid, layout, cap, out)
    } else {
        pack_words_into::<f32>(particles, fluid, layout, cap, out)
    }
}

/// Each word of `row` (a task's piece of one field's row), the `k`th `word(k)`.
fn fill_words<W: Word>(row: &mut [u8], mut word: impl FnMut(usize) -> W) {
    for (k, out) in row.chunks_exact_mut(W::BYTES).enumerate() {
        word(k).put(out);
    }
}

/// Particles a task of the packing writes (at most).
pub(super) const PACK_CHUNK: usize = 1 << 14;

/// Where a task's particles come from: particles `start..` of a [`Particles`], or positions of
/// a sampled body.
enum Source<'a> {
    Particles(&'a Particles, usize),
    Shape(&'a BodyPositions, &'a [Vec3]),
}

/// The words every particle of the body `b` shares in `layout` ([`StateLayout`]) and precision
/// (`f64`), as (state word, bits): what the device fill writes for each of them
/// (`crate::setup::fill`): all but x, v and the id.
pub fn body_constant_words(
    layout: StateLayout,
    f64: bool,
    b: &BodyPositions,
    fluid: bool,
) -> Vec<(usize, u64)> {
    if f64 {
        body_words::<f64>(layout, b, fluid)
    } else {
        body_words::<f32>(layout, b, fluid)
    }
}

/// The image of `n` particles with stride `cap`, written in parallel straight into the bytes it
/// returns (one copy of the state, whose rows past `n` stay untouched zero pages until they are
/// uploaded). `tasks` cover particles `0..n` in order, each with its source and length; the
/// materials are in range of `fluid` (checked by the callers).
fn write_image<W: Word>(
    tasks: Vec<(Source, usize)>,
    n: usize,
    cap: usize,
    fluid: &[bool],
    l: StateLayout,
    ids: Option<&[u32]>,
) -> Vec<u8> {
    let mut bytes = vec![0u8; l.words() * cap * W::BYTES];
    write_image_into::<W>(tasks, n, cap, fluid, l, ids, &mut bytes);
    bytes
}

/// [`write_image`] into `bytes` (zeroed, `l.words() * cap` words).
fn write_image_into<W: Word>(
    tasks: Vec<(Source, usize)>,
    n: usize,
    cap: usize,
    fluid: &[bool],
    l: StateLayout,
    ids: Option<&[u32]>,
    bytes: &mut [u8],
) {
    let words = l.words();
    if n == 0 {
        return;
    }
    // Each task's piece of each field's row.
    let mut pieces: Vec<Vec<&mut [u8]>> = tasks.iter().map(|_| Vec::with_capacity(words)).collect();
    for row in bytes.chunks_mut(cap * W::BYTES) {
        let mut rest = &mut row[..n * W::BYTES];
        for ((_, len), task) in tasks.iter().zip(pieces.iter_mut()) {
            let (piece, tail) = rest.split_at_mut(len * W::BYTES);
            task.push(piece);
            rest = tail;
        }
    }
    let mut first = Vec::with_capacity(tasks.len());
    let mut at = 0;
    for (_, len) in &tasks {
        first.push(at);
        at += len;
    }
    tasks
        .into_par_iter()
        .zip(pieces)
        .zip(first)
        .for_each(|(((source, len), mut rows), first)| match source {
            // Row by row (each field's words of the task's particles one after another), the
            // words of C and F made once a particle: the same bytes as particle by particle,
            // several times faster (no slice of a row made per word).
            Source::Particles(p, start) => {
                let r = start..start + len;
                let (x, v) = (&p.x[r.clone()], &p.v[r.clone()]);
                for a in 0..3 {
                    fill_words(rows[l.x() + a], |k| W::from_f32(x[k][a]));
                }
                let nv = v_words::<W>(l, Vec3::ZERO).1;
                for e in 0..nv {
                    fill_words(rows[l.v() + e], |k| v_words::<W>(l, v[k]).0[e]);
                }
                let cw: Vec<[W; 9]> = p.c[r.clone()]
                    .iter()
                    .map(|&c| c_words::<W>(l, c).0)
                    .collect();
                let nc = c_words::<W>(l, Mat3::ZERO).1;
                for e in 0..nc {
                    fill_words(rows[l.c() + e], |k| cw[k][e]);
                }
                let fw: Vec<[W; 9]> = r
                    .clone()
                    .map(|i| f_words::<W>(l, packed_f(p.f[i], fluid[p.material[i] as usize])).0)
                    .collect();
                for e in 0..l.f_words() {
                    fill_words(rows[l.f() + e], |k| fw[k][e]);
                }
                if let Some(pl) = l.plastic() {
                    fill_words(rows[pl], |k| W::from_f32(p.plastic[start + k]));
                }
                fill_words(rows[l.mass()], |k| W::from_f32(p.mass[start + k]));
                fill_words(rows[l.vol0()], |k| W::from_f32(p.vol0[start + k]));
                fill_words(rows[l.material()], |k| W::from_id(p.material[start + k]));
                fill_words(rows[l.id()], |k| {
                    W::from_id(ids.map_or((first + k) as u32, |ids| ids[first + k]))
                });
            }
            // Field by field: all but x, v and id are the body's constants (row fills).
            Source::Shape(b, xs) => {
                let fill = |row: &mut [u8], v: W| {
                    let mut word = [0u8; 8];
                    v.put(&mut word);
                    for w in row.chunks_exact_mut(W::BYTES) {
                        w.copy_from_slice(&word[..W::BYTES]);
                    }
                };
                let f = packed_f(Mat3::IDENTITY, fluid[b.material as usize]);
                let (c, nc) = c_words::<W>(l, b.c);
                let (fm, nf) = f_words::<W>(l, f);
                (0..nc).for_each(|e| fill(rows[l.c() + e], c[e]));
                (0..nf).for_each(|e| fill(rows[l.f() + e], fm[e]));
                if let Some(pl) = l.plastic() {
                    fill(rows[pl], W::from_f32(b.plastic));
                }
                fill(rows[l.mass()], W::from_f32(b.mass));
                fill(rows[l.vol0()], W::from_f32(b.vol0));
                fill(rows[l.material()], W::from_id(b.material));
                for (k, &x) in xs.iter().enumerate() {
                    let at = k * W::BYTES;
                    for a in 0..3 {
                        W::from_f32(x[a]).put(&mut rows[l.x() + a][at..]);
                    }
                    let (v, nv) = v_words::<W>(l, b.velocity_at(x));
                    for (e, w) in v.iter().enumerate().take(nv) {
                        w.put(&mut rows[l.v() + e][at..]);
                    }
                    let i = first + k;
                    W::from_id(ids.map_or(i as u32, |ids| ids[i])).put(&mut rows[l.id()][at..]);
                }
            }
        });
}

/// Tasks of [`write_image`] over particles `0..n` of `p`.
fn particle_tasks(p: &Particles) -> Vec<(Source<'_>, usize)> {
    particle_tasks_of(p, PACK_CHUNK)
}

/// Tasks of at most `chunk` particles over particles `0..n` of `p`.
fn particle_tasks_of(p: &Particles, chunk: usize) -> Vec<(Source<'_>, usize)> {
    (0..p.len())
        .step_by(chunk)
        .map(|s| (Source::Particles(p, s), chunk.min(p.len() - s)))
        .collect()
}

/// Particles a task of [`pack_into`] writes (at most): a put's few thousand particles (about
/// 100 ns each packed on one core) spread over every core.
const PUT_CHUNK: usize = 512;

/// The first particle whose material is not below `fluid.len()`.
fn bad_material(p: &Particles, fluid: &[bool]) -> Option<usize> {
    p.material
        .par_iter()
        .position_first(|&m| fluid.get(m as usize).is_none())
}

/// The image of [`pack`].
fn pack_words<W: Word>(
    p: &Particles,
    fluid: &[bool],
    l: StateLayout,
    cap: usize,
    ids: Option<&[u32]>,
) -> Result<Vec<u8>, String> {
    let n = p.len();
    let cap = cap.max(n);
    if ids.is_some_and(|ids| ids.len() != n) {
        return Err("CUDA backend: one id per particle".into());
    }
    if let Some(i) = bad_material(p, fluid) {
        return Err(format!(
            "particle {i} has material {} out of range",
            p.material[i]
        ));
    }
    Ok(write_image::<W>(particle_tasks(p), n, cap, fluid, l, ids))
}

/// [`pack_words`] appended to `out` (ids `0..n`).
fn pack_words_into<W: Word>(
    p: &Particles,
    fluid: &[bool],
    l: StateLayout,
    cap: usize,
    out: &mut Vec<u8>,
) -> Result<(), String> {
    let n = p.len();
    let cap = cap.max(n);
    if let Some(i) = bad_material(p, fluid) {
        return Err(format!(
            "particle {i} has material {} out of range",
            p.material[i]
        ));
    }
    let start = out.len();
    out.resize(start + l.words() * cap * W::BYTES, 0);
    let tasks = particle_tasks_of(p, PUT_CHUNK);
    write_image_into::<W>(tasks, n, cap, fluid, l, None, &mut out[start..]);
    Ok(())
}

/// The device image (stride: the particle count, ids `0..n`) of the particles of sampled bodies
/// ([`rtmpm_scene::sampling::sample_bodies`]), written straight from their positions:
/// byte for byte what [`pack`] makes of the [`Particles`] that
/// [`rtmpm_scene::Scene::sample_particles`] returns, without the host ever holding those (112
/// bytes a particle): a backend built from it needs the image (4 bytes a word: 116 bytes a
/// particle in the 29-word f32 layout) and the positions (12) only.
pub fn pack_bodies(
    bodies: &[SampledBody],
    fluid: &[bool],
    layout: StateLayout,
    f64: bool,
) -> Result<Vec<u8>, String> {
    check_layout(fluid, layout, f64)?;
    let mut tasks = Vec::new();
    let mut n = 0usize;
    for body in bodies {
        match body {
            SampledBody::Points(p) => {
                if let Some(i) = bad_material(p, fluid) {
                    return Err(format!(
                        "particle {} has material {} out of range",
                        n + i,
                        p.material[i]
                    ));
                }
                tasks.extend(particle_tasks(p));
            }
            SampledBody::Shape(b) => {
                if b.count > 0 && fluid.get(b.material as usize).is_none() {
                    return Err(format!(
                        "particle {n} has material {} out of range",
                        b.material
                    ));
                }
                for chunk in &b.chunks {
                    for xs in chunk.chunks(PACK_CHUNK) {
                        tasks.push((Source::Shape(b, xs), xs.len()));
                    }
                }
            }
            // The backend walks deferred bodies before it packs on the host (`sample::walked`).
            SampledBody::Deferred(_) => {
                return Err(format!(
                    "particle {n}: a body whose positions were left to the device reached the \
                     host packing"
                ));
            }
        }
        n += body.len();
    }
    Ok(if f64 {
        write_image::<f64>(tasks, n, n, fluid, layout, None)
    } else {
        write_image::<f32>(tasks, n, n, fluid, layout, None)
    })
}

/// Every position of the sampled bodies, in order, in parallel (the particles' order of
/// [`pack_bodies`]), each mapped by `f`: e.g. the stencil bases of `capacity::bases` without the
/// particles.
pub fn map_positions<T: Send>(
    bodies: &[SampledBody],
    f: impl Fn(Vec3) -> T + Sync + Send,
) -> Vec<T> {
    let mut out = Vec::with_capacity(bodies.iter().map(|b| b.len()).sum());
    for body in bodies {
        match body {
            SampledBody::Points(p) => out.par_extend(p.x.par_iter().map(|&x| f(x))),
            SampledBody::Shape(b) => {
                for chunk in &b.chunks {
                    out.par_extend(chunk.par_iter().map(|&x| f(x)));
                }
            }
            SampledBody::Deferred(d) => {
                for part in d.map_chunks(|c| c.iter().map(|&x| f(x)).collect::<Vec<T>>()) {
                    out.extend(part);
                }
            }
        }
    }
    out
}

/// The largest initial speed of the sampled bodies' particles: what
/// `particles.v.iter().map(|v| v.length()).fold(0.0, f32::max)` gives for their particles.
pub fn max_speed(bodies: &[SampledBody]) -> f32 {
    let speed = |v: Vec3| v.length();
    bodies
        .iter()
        .map(|body| match body {
            SampledBody::Points(p) => p.v.par_iter().map(|&v| speed(v)).reduce(|| 0.0, f32::max),
            // Without spin every particle moves at v0 (+-0 added: the same length).
            SampledBody::Shape(b) if b.angular_velocity == Vec3::ZERO => {
                if b.count > 0 {
                    speed(b.velocity)
                } else {
                    0.0
                }
            }
            // A deferred body's velocity is uniform.
            SampledBody::Deferred(d) => {
                if d.shared.count > 0 {
                    speed(d.shared.velocity)
                } else {
                    0.0
                }
            }
            SampledBody::Shape(b) => b
                .chunks
                .par_iter()
                .flat_map_iter(|c| c.iter().map(|&x| speed(b.velocity_at(x))))
                .reduce(|| 0.0, f32::max),
        })
        .fold(0.0, f32::max)
}
