//! The particle state on the device, in the backend's precision: host upload and download.
//!
//! Structure of arrays of [`StateLayout::words`] words per particle, word `w` of particle `i` at
//! `w * cap + i` (`cap`: the particle capacity, at least `n`), each field where the backend's
//! [`StateLayout`] puts it. A word is an f32 (`real` = float) or an f64 (kernels compiled with
//! `RTMPM_F64`); the material id and the original index are stored as integer bits in the low 32
//! bits of their word (`state_bits` in `kernels/common.cuh`), the compact layouts' v and C words
//! as the bits of [`crate::state::codec`]'s formats. The [`Particles`] interface is f32: the upload
//! widens exactly (compact: rounds v and C to their formats), the download rounds to nearest.

pub mod codec;

use crate::contract::*;
use crate::options::CudaOptions;
use rayon::prelude::*;
use rtmpm_core::material::Model;
use rtmpm_core::math::{Mat3, Vec3};
use rtmpm_core::scene::sampling::{BodyPositions, SampledBody};
use rtmpm_core::scene::{ParticleState, Precision};
use rtmpm_core::{Particles, Scene};

/// One word of the device state.
trait Word: Copy + Default {
    const BYTES: usize;
    fn from_f32(x: f32) -> Self;
    fn from_id(bits: u32) -> Self;
    fn read(bytes: &[u8]) -> Self;
    /// Write the word's little-endian bytes at the start of `out`.
    fn put(self, out: &mut [u8]);
    fn to_f32(self) -> f32;
    fn to_f64(self) -> f64;
    fn id(self) -> u32;
}

impl Word for f32 {
    const BYTES: usize = 4;
    fn from_f32(x: f32) -> Self {
        x
    }
    fn from_id(bits: u32) -> Self {
        f32::from_bits(bits)
    }
    fn read(b: &[u8]) -> Self {
        f32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }
    fn put(self, out: &mut [u8]) {
        out[..Self::BYTES].copy_from_slice(&self.to_le_bytes());
    }
    fn to_f32(self) -> f32 {
        self
    }
    fn to_f64(self) -> f64 {
        self as f64
    }
    fn id(self) -> u32 {
        self.to_bits()
    }
}

impl Word for f64 {
    const BYTES: usize = 8;
    fn from_f32(x: f32) -> Self {
        x as f64
    }
    fn from_id(bits: u32) -> Self {
        f64::from_bits(bits as u64)
    }
    fn read(b: &[u8]) -> Self {
        f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]])
    }
    fn put(self, out: &mut [u8]) {
        out[..Self::BYTES].copy_from_slice(&self.to_le_bytes());
    }
    fn to_f32(self) -> f32 {
        self as f32
    }
    fn to_f64(self) -> f64 {
        self
    }
    fn id(self) -> u32 {
        self.to_bits() as u32
    }
}

mod words;
use words::*;

/// Bytes of one state word.
pub fn word_bytes(f64: bool) -> usize {
    if f64 { 8 } else { 4 }
}

/// True for each material of `scene` that is a fluid (whose F the state keeps as J^(1/3) I).
pub fn fluid_materials(scene: &Scene) -> Vec<bool> {
    scene
        .materials
        .iter()
        .map(|m| matches!(m.model, Model::Fluid(_)))
        .collect()
}

/// The state layout of a backend for `scene` with `options`: [`StateLayout::Fluid`] when every
/// material is a fluid (unless `fluid_state` is off), compact with the scene's
/// `[solver] particle_state = "compact"` or the option `compact_state` (`state=compact`). The
/// compact state is single precision only: asked for in f64 (the scene's precision or the
/// option), an error.
pub fn layout_for(scene: &Scene, options: &CudaOptions) -> Result<StateLayout, String> {
    let compact = options.compact_state || scene.particle_state == ParticleState::Compact;
    let f64 = options.f64 || scene.precision == Precision::F64;
    if compact && f64 {
        return Err(
            "the compact particle state ([solver] particle_state = \"compact\") is \
                    single precision only: use particle_state = \"f32\" with f64"
                .into(),
        );
    }
    let all_fluid = fluid_materials(scene).iter().all(|f| *f);
    Ok(StateLayout::choose(all_fluid, compact, options.fluid_state))
}

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

/// Particles a task of the packing writes (at most).
const PACK_CHUNK: usize = 1 << 14;

/// The values of one particle as they are packed (F already in its packed form).
struct Packed {
    x: Vec3,
    v: Vec3,
    c: Mat3,
    f: Mat3,
    plastic: f32,
    mass: f32,
    vol0: f32,
    material: u32,
}

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

/// A fluid particle's F in its packed form, J^(1/3) I; a solid's as it is.
pub(crate) fn packed_f(f: Mat3, fluid: bool) -> Mat3 {
    if fluid {
        Mat3::from_diagonal(Vec3::splat(f.determinant().cbrt()))
    } else {
        f
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
    let words = l.words();
    let mut bytes = vec![0u8; words * cap * W::BYTES];
    if n == 0 {
        return bytes;
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
            Source::Particles(p, start) => {
                for k in 0..len {
                    let i = start + k;
                    let m = p.material[i];
                    let q = Packed {
                        x: p.x[i],
                        v: p.v[i],
                        c: p.c[i],
                        f: packed_f(p.f[i], fluid[m as usize]),
                        plastic: p.plastic[i],
                        mass: p.mass[i],
                        vol0: p.vol0[i],
                        material: m,
                    };
                    let mut put = |f: usize, v: W| v.put(&mut rows[f][k * W::BYTES..]);
                    for a in 0..3 {
                        put(l.x() + a, W::from_f32(q.x[a]));
                    }
                    let (v, nv) = v_words::<W>(l, q.v);
                    let (c, nc) = c_words::<W>(l, q.c);
                    let (fm, nf) = f_words::<W>(l, q.f);
                    (0..nv).for_each(|e| put(l.v() + e, v[e]));
                    (0..nc).for_each(|e| put(l.c() + e, c[e]));
                    (0..nf).for_each(|e| put(l.f() + e, fm[e]));
                    if let Some(pl) = l.plastic() {
                        put(pl, W::from_f32(q.plastic));
                    }
                    put(l.mass(), W::from_f32(q.mass));
                    put(l.vol0(), W::from_f32(q.vol0));
                    put(l.material(), W::from_id(q.material));
                    put(
                        l.id(),
                        W::from_id(ids.map_or((first + k) as u32, |ids| ids[first + k])),
                    );
                }
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
    bytes
}

/// Tasks of [`write_image`] over particles `0..n` of `p`.
fn particle_tasks(p: &Particles) -> Vec<(Source<'_>, usize)> {
    (0..p.len())
        .step_by(PACK_CHUNK)
        .map(|s| (Source::Particles(p, s), PACK_CHUNK.min(p.len() - s)))
        .collect()
}

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

/// The device image (stride: the particle count, ids `0..n`) of the particles of sampled bodies
/// ([`rtmpm_core::scene::sampling::sample_bodies`]), written straight from their positions:
/// byte for byte what [`pack`] makes of the [`Particles`] that
/// [`rtmpm_core::Scene::sample_particles`] returns, without the host ever holding those (112
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

/// Particles in original order from the device image of `n` particles (stride `cap`).
pub fn unpack(
    bytes: &[u8],
    n: usize,
    cap: usize,
    layout: StateLayout,
    f64: bool,
    out: &mut Particles,
) -> Result<(), String> {
    if f64 {
        unpack_words::<f64>(bytes, n, cap, layout, out)
    } else {
        unpack_words::<f32>(bytes, n, cap, layout, out)
    }
}

fn unpack_words<W: Word>(
    bytes: &[u8],
    n: usize,
    cap: usize,
    l: StateLayout,
    out: &mut Particles,
) -> Result<(), String> {
    if cap < n || bytes.len() < l.words() * cap * W::BYTES {
        return Err(format!("CUDA: state of {} bytes is too short", bytes.len()));
    }
    *out = Particles::default();
    resize_particles(out, n);
    scatter_words(
        |f, i| W::read(&bytes[(f * cap + i) * W::BYTES..]),
        n,
        l,
        out,
    )
}

/// Size every column of `out` for `n` particles (zeros).
pub fn resize_particles(out: &mut Particles, n: usize) {
    out.x.resize(n, Vec3::ZERO);
    out.v.resize(n, Vec3::ZERO);
    out.c.resize(n, Mat3::ZERO);
    out.f.resize(n, Mat3::ZERO);
    out.plastic.resize(n, 0.0);
    out.mass.resize(n, 0.0);
    out.vol0.resize(n, 0.0);
    out.material.resize(n, 0);
}

/// Put the `n` particles of a single-precision state image (SoA with stride `cap`, as stored on
/// one GPU of several) at their original index in `out` (already sized for every particle).
pub fn scatter_f32(
    host: &[f32],
    n: usize,
    cap: usize,
    layout: StateLayout,
    out: &mut Particles,
) -> Result<(), String> {
    if cap < n || host.len() < layout.words() * cap {
        return Err(format!("CUDA: state of {} words is too short", host.len()));
    }
    scatter_words(|f, i| host[f * cap + i], n, layout, out)
}

/// Put `n` particles, read word by word with `g(field, particle)`, at their original index
/// (the id field) in `out`, which is already sized.
fn scatter_words<W: Word>(
    g: impl Fn(usize, usize) -> W,
    n: usize,
    l: StateLayout,
    out: &mut Particles,
) -> Result<(), String> {
    let total = out.x.len();
    let r = |f: usize, i: usize| g(f, i).to_f32();
    for i in 0..n {
        let id = g(l.id(), i).id() as usize;
        if id >= total {
            return Err(format!("CUDA: corrupt particle id {id}"));
        }
        let x = l.x();
        out.x[id] = Vec3::new(r(x, i), r(x + 1, i), r(x + 2, i));
        out.v[id] = read_v(l, |k| g(l.v() + k, i));
        out.c[id] = read_c(l, |k| g(l.c() + k, i));
        out.f[id] = read_f(l, |k| g(l.f() + k, i));
        out.plastic[id] = l.plastic().map_or(0.0, |p| r(p, i));
        out.mass[id] = r(l.mass(), i);
        out.vol0[id] = r(l.vol0(), i);
        out.material[id] = g(l.material(), i).id();
    }
    Ok(())
}

/// Positions and velocities in original order, unrounded (f64 words stay f64): for tests that
/// compare double-precision states.
pub fn unpack_x_v_f64(
    bytes: &[u8],
    n: usize,
    cap: usize,
    layout: StateLayout,
    f64: bool,
) -> Result<Vec<[[f64; 3]; 2]>, String> {
    if f64 {
        x_v_words::<f64>(bytes, n, cap, layout)
    } else {
        x_v_words::<f32>(bytes, n, cap, layout)
    }
}

fn x_v_words<W: Word>(
    bytes: &[u8],
    n: usize,
    cap: usize,
    l: StateLayout,
) -> Result<Vec<[[f64; 3]; 2]>, String> {
    if cap < n || bytes.len() < l.words() * cap * W::BYTES {
        return Err(format!("CUDA: state of {} bytes is too short", bytes.len()));
    }
    let g = |f: usize, i: usize| W::read(&bytes[(f * cap + i) * W::BYTES..]);
    let v3 = |f: usize, i: usize| [g(f, i).to_f64(), g(f + 1, i).to_f64(), g(f + 2, i).to_f64()];
    let mut out = vec![[[0.0; 3]; 2]; n];
    for i in 0..n {
        let id = g(l.id(), i).id() as usize;
        if id >= n {
            return Err(format!("CUDA: corrupt particle id {id}"));
        }
        out[id] = [v3(l.x(), i), read_v_f64(l, |k| g(l.v() + k, i))];
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
