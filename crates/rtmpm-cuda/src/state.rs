//! The particle state on the device, in the backend's precision: host upload and download.
//!
//! Structure of arrays of [`NFIELDS`] words per particle, field `f` of particle `i` at word
//! `f * cap + i` (`cap`: the particle capacity, at least `n`). A word is an f32 (`real` = float) or an f64 (kernels compiled with `RTMPM_F64`);
//! the material id and the original index are stored as integer bits in the low 32 bits of
//! their word (`state_bits` in `kernels/common.cuh`). The [`Particles`] interface is f32: the
//! upload widens exactly, the download rounds to nearest.

use crate::contract::*;
use rayon::prelude::*;
use rtmpm_core::Particles;
use rtmpm_core::math::{Mat3, Vec3};
use rtmpm_core::scene::sampling::{BodyPositions, SampledBody};

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

/// Bytes of one state word.
pub fn word_bytes(f64: bool) -> usize {
    if f64 { 8 } else { 4 }
}

/// The device image of `particles` (f64 words when `f64`), SoA with stride `cap` (at least the
/// particle count; the words past the particles are zero); `fluid` has one entry per material
/// (true for a fluid) and materials must be below its length. `ids`: the original index of each
/// particle (one GPU of several), else 0..n. A fluid particle's F is written as J^(1/3) I with
/// J = det F: the form the fluid's projection keeps it in (the same J, so the same stress), which
/// the kernels rely on to read and write only its diagonal (`load_deformation` in common.cuh).
pub fn pack(
    particles: &Particles,
    fluid: &[bool],
    f64: bool,
    cap: usize,
    ids: Option<&[u32]>,
) -> Result<Vec<u8>, String> {
    if f64 {
        pack_words::<f64>(particles, fluid, cap, ids)
    } else {
        pack_words::<f32>(particles, fluid, cap, ids)
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

/// A fluid particle's F in its packed form, J^(1/3) I; a solid's as it is.
fn packed_f(f: Mat3, fluid: bool) -> Mat3 {
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
    ids: Option<&[u32]>,
) -> Vec<u8> {
    let mut bytes = vec![0u8; NFIELDS * cap * W::BYTES];
    if n == 0 {
        return bytes;
    }
    // Each task's piece of each field's row.
    let mut pieces: Vec<Vec<&mut [u8]>> =
        tasks.iter().map(|_| Vec::with_capacity(NFIELDS)).collect();
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
        .for_each(|(((source, len), mut rows), first)| {
            let mut write = |k: usize, q: Packed| {
                let mut put = |f: usize, v: W| v.put(&mut rows[f][k * W::BYTES..]);
                for a in 0..3 {
                    put(F_X + a, W::from_f32(q.x[a]));
                    put(F_V + a, W::from_f32(q.v[a]));
                }
                let (c, fm) = (q.c.to_cols_array(), q.f.to_cols_array());
                for e in 0..9 {
                    put(F_C + e, W::from_f32(c[e]));
                    put(F_F + e, W::from_f32(fm[e]));
                }
                put(F_PLASTIC, W::from_f32(q.plastic));
                put(F_MASS, W::from_f32(q.mass));
                put(F_VOL0, W::from_f32(q.vol0));
                put(F_MAT, W::from_id(q.material));
                let i = first + k;
                put(F_ID, W::from_id(ids.map_or(i as u32, |ids| ids[i])));
            };
            match source {
                Source::Particles(p, start) => {
                    for k in 0..len {
                        let i = start + k;
                        let m = p.material[i];
                        write(
                            k,
                            Packed {
                                x: p.x[i],
                                v: p.v[i],
                                c: p.c[i],
                                f: packed_f(p.f[i], fluid[m as usize]),
                                plastic: p.plastic[i],
                                mass: p.mass[i],
                                vol0: p.vol0[i],
                                material: m,
                            },
                        );
                    }
                }
                Source::Shape(b, xs) => {
                    let f = packed_f(Mat3::IDENTITY, fluid[b.material as usize]);
                    for (k, &x) in xs.iter().enumerate() {
                        write(
                            k,
                            Packed {
                                x,
                                v: b.velocity_at(x),
                                c: b.c,
                                f,
                                plastic: b.plastic,
                                mass: b.mass,
                                vol0: b.vol0,
                                material: b.material,
                            },
                        );
                    }
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
    Ok(write_image::<W>(particle_tasks(p), n, cap, fluid, ids))
}

/// The device image (stride: the particle count, ids `0..n`) of the particles of sampled bodies
/// ([`rtmpm_core::scene::sampling::sample_bodies`]), written straight from their positions:
/// byte for byte what [`pack`] makes of the [`Particles`] that
/// [`rtmpm_core::Scene::sample_particles`] returns, without the host ever holding those (112
/// bytes a particle): a backend built from it needs the image (116 bytes a particle in f32) and
/// the positions (12) only.
pub fn pack_bodies(bodies: &[SampledBody], fluid: &[bool], f64: bool) -> Result<Vec<u8>, String> {
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
        }
        n += body.len();
    }
    Ok(if f64 {
        write_image::<f64>(tasks, n, n, fluid, None)
    } else {
        write_image::<f32>(tasks, n, n, fluid, None)
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
    f64: bool,
    out: &mut Particles,
) -> Result<(), String> {
    if f64 {
        unpack_words::<f64>(bytes, n, cap, out)
    } else {
        unpack_words::<f32>(bytes, n, cap, out)
    }
}

fn unpack_words<W: Word>(
    bytes: &[u8],
    n: usize,
    cap: usize,
    out: &mut Particles,
) -> Result<(), String> {
    if cap < n || bytes.len() < NFIELDS * cap * W::BYTES {
        return Err(format!("CUDA: state of {} bytes is too short", bytes.len()));
    }
    *out = Particles::default();
    resize_particles(out, n);
    scatter_words(|f, i| W::read(&bytes[(f * cap + i) * W::BYTES..]), n, out)
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
pub fn scatter_f32(host: &[f32], n: usize, cap: usize, out: &mut Particles) -> Result<(), String> {
    if cap < n || host.len() < NFIELDS * cap {
        return Err(format!("CUDA: state of {} words is too short", host.len()));
    }
    scatter_words(|f, i| host[f * cap + i], n, out)
}

/// Put `n` particles, read word by word with `g(field, particle)`, at their original index
/// (the id field) in `out`, which is already sized.
fn scatter_words<W: Word>(
    g: impl Fn(usize, usize) -> W,
    n: usize,
    out: &mut Particles,
) -> Result<(), String> {
    let total = out.x.len();
    let r = |f: usize, i: usize| g(f, i).to_f32();
    for i in 0..n {
        let id = g(F_ID, i).id() as usize;
        if id >= total {
            return Err(format!("CUDA: corrupt particle id {id}"));
        }
        out.x[id] = Vec3::new(r(F_X, i), r(F_X + 1, i), r(F_X + 2, i));
        out.v[id] = Vec3::new(r(F_V, i), r(F_V + 1, i), r(F_V + 2, i));
        out.c[id] = Mat3::from_cols_array(&std::array::from_fn(|e| r(F_C + e, i)));
        out.f[id] = Mat3::from_cols_array(&std::array::from_fn(|e| r(F_F + e, i)));
        out.plastic[id] = r(F_PLASTIC, i);
        out.mass[id] = r(F_MASS, i);
        out.vol0[id] = r(F_VOL0, i);
        out.material[id] = g(F_MAT, i).id();
    }
    Ok(())
}

/// Positions and velocities in original order, unrounded (f64 words stay f64): for tests that
/// compare double-precision states.
pub fn unpack_x_v_f64(
    bytes: &[u8],
    n: usize,
    cap: usize,
    f64: bool,
) -> Result<Vec<[[f64; 3]; 2]>, String> {
    if f64 {
        x_v_words::<f64>(bytes, n, cap)
    } else {
        x_v_words::<f32>(bytes, n, cap)
    }
}

fn x_v_words<W: Word>(bytes: &[u8], n: usize, cap: usize) -> Result<Vec<[[f64; 3]; 2]>, String> {
    if cap < n || bytes.len() < NFIELDS * cap * W::BYTES {
        return Err(format!("CUDA: state of {} bytes is too short", bytes.len()));
    }
    let g = |f: usize, i: usize| W::read(&bytes[(f * cap + i) * W::BYTES..]);
    let v3 = |f: usize, i: usize| [g(f, i).to_f64(), g(f + 1, i).to_f64(), g(f + 2, i).to_f64()];
    let mut out = vec![[[0.0; 3]; 2]; n];
    for i in 0..n {
        let id = g(F_ID, i).id() as usize;
        if id >= n {
            return Err(format!("CUDA: corrupt particle id {id}"));
        }
        out[id] = [v3(F_X, i), v3(F_V, i)];
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The one-thread packing of before: word by word into a vector, then to bytes.
    fn reference_pack<W: Word>(p: &Particles, fluid: &[bool], cap: usize, ids: &[u32]) -> Vec<u8> {
        let mut host = vec![W::default(); NFIELDS * cap];
        for i in 0..p.len() {
            let mut put = |f: usize, v: W| host[f * cap + i] = v;
            for a in 0..3 {
                put(F_X + a, W::from_f32(p.x[i][a]));
                put(F_V + a, W::from_f32(p.v[i][a]));
            }
            let m = p.material[i];
            let f = if fluid[m as usize] {
                Mat3::from_diagonal(Vec3::splat(p.f[i].determinant().cbrt()))
            } else {
                p.f[i]
            };
            let (c, fm) = (p.c[i].to_cols_array(), f.to_cols_array());
            for e in 0..9 {
                put(F_C + e, W::from_f32(c[e]));
                put(F_F + e, W::from_f32(fm[e]));
            }
            put(F_PLASTIC, W::from_f32(p.plastic[i]));
            put(F_MASS, W::from_f32(p.mass[i]));
            put(F_VOL0, W::from_f32(p.vol0[i]));
            put(F_MAT, W::from_id(m));
            put(F_ID, W::from_id(ids[i]));
        }
        let mut bytes = vec![0u8; host.len() * W::BYTES];
        for (w, out) in host.into_iter().zip(bytes.chunks_mut(W::BYTES)) {
            w.put(out);
        }
        bytes
    }

    /// Several tasks' worth of particles (a partial last one), fluid and solid, a capacity past
    /// the count and ids: the parallel image is the one-thread image byte for byte.
    #[test]
    fn the_parallel_pack_is_the_one_thread_pack() {
        let n = 2 * PACK_CHUNK + 1234;
        let mut p = Particles::default();
        let mut ids = Vec::with_capacity(n);
        for i in 0..n {
            let t = i as f32;
            p.push(
                Vec3::new(t.sin(), t.cos(), 1e-3 * t),
                Vec3::new(0.5 - t.cos(), 2.0, -t.sin()),
                1e-3 + 1e-6 * t,
                1e-6 * (1.0 + t.sin().abs()),
                (i % 3) as u32,
                0.25 * t.cos(),
            );
            p.f[i] = Mat3::from_cols_array(&[
                1.0 + 1e-4 * t.sin(),
                0.1,
                0.0,
                -0.1,
                0.9,
                0.3,
                0.0,
                0.0,
                1.05,
            ]);
            p.c[i] = Mat3::from_cols_array(&std::array::from_fn(|e| (t + e as f32).sin()));
            ids.push((n - 1 - i) as u32);
        }
        let fluid = [true, false, true];
        for cap in [n, n + 77] {
            let got = pack(&p, &fluid, false, cap, Some(&ids)).expect("pack");
            assert!(
                got == reference_pack::<f32>(&p, &fluid, cap, &ids),
                "f32, cap {cap}"
            );
            let got = pack(&p, &fluid, true, cap, Some(&ids)).expect("pack");
            assert!(
                got == reference_pack::<f64>(&p, &fluid, cap, &ids),
                "f64, cap {cap}"
            );
        }
        // The first particle of a bad material is named, as before.
        p.material[PACK_CHUNK + 5] = 7;
        p.material[PACK_CHUNK + 9] = 9;
        let e = pack(&p, &fluid, false, n, None).unwrap_err();
        assert!(
            e.contains(&format!("particle {} has material 7", PACK_CHUNK + 5)),
            "{e}"
        );
        assert_eq!(
            pack(&Particles::default(), &fluid, false, 3, None)
                .expect("empty")
                .len(),
            NFIELDS * 3 * 4
        );
    }

    /// Packing the sampled bodies gives the image of packing the sampled particles, byte for
    /// byte: shapes and samplings of every kind, fluid and solid, spinning, and a points body.
    #[test]
    fn packing_the_sampled_bodies_is_packing_their_particles() {
        let dir = std::env::temp_dir().join(format!("rtmpm-pack-bodies-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let mut ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n\
                        property float x\nproperty float y\nproperty float z\nend_header\n"
            .to_vec();
        for v in [0.2f32, 0.2, 0.2, 0.25, 0.2, 0.2, 0.2, 0.3, 0.25] {
            ply.extend_from_slice(&v.to_le_bytes());
        }
        std::fs::write(dir.join("pts.ply"), ply).expect("ply");
        let text = "seed = 3\n[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ndx = 0.02\n\
            [time]\nduration = 1\n\
            [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000\nbulk_modulus = 1e5\n\
            [[material]]\nname = \"s\"\ntype = \"snow\"\ndensity = 400\n\
            youngs_modulus = 1.4e5\npoisson_ratio = 0.2\n\
            [[body]]\nmaterial = \"s\"\nshape = \"sphere\"\ncenter = [0.3, 0.5, 0.5]\n\
            radius = 0.2\nsampling = \"jittered\"\nangular_velocity = [0, 3, 1]\n\
            [[body]]\nmaterial = \"w\"\nshape = \"box\"\nmin = [0.6, 0.1, 0.1]\n\
            max = [0.9, 0.4, 0.5]\nsampling = \"regular\"\nvelocity = [0, -1, 0]\n\
            [[body]]\nmaterial = \"w\"\nshape = \"particles\"\nfile = \"pts.ply\"\n\
            [[body]]\nmaterial = \"s\"\nshape = \"cylinder\"\ncenter = [0.7, 0.7, 0.6]\n\
            axis = [0, 1, 0]\nradius = 0.1\nheight = 0.2\nsampling = \"random\"\n";
        let scene = rtmpm_core::Scene::from_toml_in(text, "pack", &dir).expect("scene");
        let _ = std::fs::remove_dir_all(&dir);
        let p = scene.sample_particles().expect("particles");
        assert!(p.len() > 2 * PACK_CHUNK, "{}", p.len());
        let bodies = rtmpm_core::scene::sampling::sample_bodies(&scene, &|_| {}).expect("bodies");
        let fluid = [true, false];
        for f64 in [false, true] {
            let want = pack(&p, &fluid, f64, p.len(), None).expect("pack");
            let got = pack_bodies(&bodies, &fluid, f64).expect("pack bodies");
            assert!(got == want, "f64 = {f64}: the images differ");
        }
        // What the backend takes from the particles besides the image, from the bodies.
        assert_eq!(
            map_positions(&bodies, |x| x),
            p.x,
            "positions in the particles' order"
        );
        let want = crate::capacity::bases(&scene, &p);
        let (dx, origin) = (scene.dx, scene.domain_min - 4.0 * scene.dx);
        let got = map_positions(&bodies, |x| ((x - origin) / dx - 0.5).floor().as_ivec3());
        assert_eq!(got, want);
        let speed = p.v.iter().map(|v| v.length()).fold(0.0, f32::max);
        assert!(speed > 0.5, "{speed}");
        assert_eq!(max_speed(&bodies).to_bits(), speed.to_bits());
        let e = pack_bodies(&bodies, &[true], false).unwrap_err();
        assert!(e.contains("particle 0 has material 1"), "{e}");
    }

    #[test]
    fn pack_unpack_round_trip_both_precisions() {
        let mut p = Particles::default();
        for i in 0..5 {
            let x = Vec3::new(0.1 * i as f32, 0.3, 1.0 / 3.0);
            p.push(x, Vec3::new(1.5, -2.25, 0.1), 0.01, 1e-6, i % 2, 0.5);
        }
        p.f[3] = Mat3::from_cols_array(&[1.1, 0.2, 0.0, -0.1, 0.9, 0.3, 0.0, 0.0, 1.05]);
        for f64 in [false, true] {
            for cap in [5, 8] {
                let bytes = pack(&p, &[false, false], f64, cap, None).expect("pack");
                assert_eq!(bytes.len(), NFIELDS * cap * word_bytes(f64));
                let mut q = Particles::default();
                unpack(&bytes, 5, cap, f64, &mut q).expect("unpack");
                assert_eq!(p, q, "f64 = {f64}, cap = {cap}");
            }
        }
        assert!(pack(&p, &[false], true, 5, None).is_err());
        assert!(pack(&p, &[false, false], false, 5, Some(&[0, 1])).is_err());
        // Ids put each particle at its original index (reversed here).
        let bytes = pack(&p, &[false, false], false, 6, Some(&[4, 3, 2, 1, 0])).expect("pack");
        let mut q = Particles::default();
        unpack(&bytes, 5, 6, false, &mut q).expect("unpack");
        assert_eq!(q.x[0], p.x[4]);
        assert_eq!(q.f[1], p.f[3]);
    }

    #[test]
    fn a_fluid_particle_is_packed_as_j_to_the_third_times_identity() {
        let mut p = Particles::default();
        p.push(Vec3::ZERO, Vec3::ZERO, 0.01, 1e-6, 0, 0.0);
        p.push(Vec3::ONE, Vec3::ZERO, 0.01, 1e-6, 1, 0.0);
        let sheared = Mat3::from_cols_array(&[1.1, 0.2, 0.0, -0.1, 0.9, 0.3, 0.0, 0.0, 1.05]);
        p.f[0] = sheared;
        p.f[1] = sheared;
        let bytes = pack(&p, &[true, false], false, 2, None).expect("pack");
        let mut q = Particles::default();
        unpack(&bytes, 2, 2, false, &mut q).expect("unpack");
        let s = sheared.determinant().cbrt();
        assert_eq!(q.f[0], Mat3::from_diagonal(Vec3::splat(s)));
        assert!((q.f[0].determinant() - sheared.determinant()).abs() < 1e-6);
        assert_eq!(q.f[1], sheared, "a solid keeps its F");
    }
}
