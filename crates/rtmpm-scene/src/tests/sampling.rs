//! The parallel sampler against the one-thread sampler it replaced (kept here, verbatim in its
//! arithmetic, as the reference): the same particles bit for bit, for every shape and sampling,
//! on 1, 2 and 7 threads; and against stored hashes of the one-thread sampler's output.

use crate::Scene;
use crate::sampling::{self, Sampling, per_axis};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rtmpm_geometry::Shape;
use rtmpm_physics::Particles;
use rtmpm_physics::math::{Mat3, Vec3};

/// The one-thread sampler of before (positions of body `index`, the volume of one particle).
fn reference_positions(scene: &Scene, index: usize) -> (Vec<Vec3>, f32) {
    let body = &scene.bodies[index];
    let dx = scene.dx;
    let shape = &body.shape;
    let (lo, hi) = shape.bounds();
    let seed = scene.seed ^ (index as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut out = Vec::new();
    match body.sampling {
        Sampling::Regular | Sampling::Jittered => {
            let n = per_axis(body.particles_per_cell);
            let h = dx / n as f32;
            let first = ((lo - scene.domain_min) / h).floor();
            let last = ((hi - scene.domain_min) / h).ceil();
            let (i0, j0, k0) = (first.x as i64, first.y as i64, first.z as i64);
            let (i1, j1, k1) = (last.x as i64, last.y as i64, last.z as i64);
            let jitter = body.sampling == Sampling::Jittered;
            for k in k0..=k1 {
                for j in j0..=j1 {
                    for i in i0..=i1 {
                        let mut x = scene.domain_min
                            + Vec3::new(i as f32 + 0.5, j as f32 + 0.5, k as f32 + 0.5) * h;
                        if jitter {
                            let r = Vec3::new(
                                rng.random::<f32>() - 0.5,
                                rng.random::<f32>() - 0.5,
                                rng.random::<f32>() - 0.5,
                            );
                            x += r * h;
                        }
                        if shape.contains(x) {
                            out.push(x);
                        }
                    }
                }
            }
            (out, h * h * h)
        }
        Sampling::Random => {
            let volume = shape.volume();
            let count = sampling::estimate_body(scene, index);
            while (out.len() as u64) < count {
                let r = Vec3::new(
                    rng.random::<f32>(),
                    rng.random::<f32>(),
                    rng.random::<f32>(),
                );
                let x = lo + r * (hi - lo);
                if shape.contains(x) {
                    out.push(x);
                }
            }
            (out, volume / count as f32)
        }
    }
}

/// The one-thread scene sampler of before: bodies one by one, particle by particle.
fn reference_scene(scene: &Scene) -> Particles {
    let mut all = Particles::default();
    for (index, body) in scene.bodies.iter().enumerate() {
        let material = &scene.materials[body.material as usize];
        let (positions, vol0) = reference_positions(scene, index);
        let plastic = material.model.initial_plastic();
        let n = positions.len().max(1) as f32;
        let centre = positions.iter().fold(Vec3::ZERO, |a, b| a + *b) / n;
        let mass = material.density * vol0;
        let w = body.angular_velocity;
        let c = Mat3::from_cols(
            Vec3::new(0.0, w.z, -w.y),
            Vec3::new(-w.z, 0.0, w.x),
            Vec3::new(w.y, -w.x, 0.0),
        );
        for x in positions {
            let v = body.velocity + body.angular_velocity.cross(x - centre);
            all.push(x, v, mass, vol0, body.material, plastic);
            if let Some(last) = all.c.last_mut() {
                *last = c;
            }
        }
    }
    all
}

/// FNV-1a over every bit of every column.
fn hash(p: &Particles) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |bits: u32| {
        for b in bits.to_le_bytes() {
            h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
        }
    };
    for i in 0..p.len() {
        for a in p.x[i].to_array().into_iter().chain(p.v[i].to_array()) {
            eat(a.to_bits());
        }
        for a in p.c[i]
            .to_cols_array()
            .into_iter()
            .chain(p.f[i].to_cols_array())
        {
            eat(a.to_bits());
        }
        for a in [p.plastic[i], p.mass[i], p.vol0[i]] {
            eat(a.to_bits());
        }
        eat(p.material[i]);
    }
    h
}

/// A scene with one body of `shape` (TOML lines) sampled by `sampling`, moving and spinning.
fn scene(shape: &str, sampling: &str, spin: bool) -> Scene {
    let w = if spin {
        "[0.5, -2.0, 3.0]"
    } else {
        "[0, 0, 0]"
    };
    let text = format!(
        "seed = 11\n[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ndx = 0.02\n[time]\nduration = 1\n\
         [[material]]\nname = \"j\"\ntype = \"neo_hookean\"\ndensity = 1000\n\
         youngs_modulus = 1e5\npoisson_ratio = 0.3\n\
         [[body]]\nmaterial = \"j\"\n{shape}\nparticles_per_cell = 8\nsampling = \"{sampling}\"\n\
         velocity = [1.0, -0.0, 0.5]\nangular_velocity = {w}\n\
         [[body]]\nmaterial = \"j\"\nshape = \"box\"\nmin = [0.61, 0.1, 0.1]\n\
         max = [0.8, 0.33, 0.47]\nsampling = \"{sampling}\"\n"
    );
    Scene::from_toml(&text, "sampling test").expect("scene")
}

const SHAPES: [&str; 3] = [
    "shape = \"box\"\nmin = [0.1, 0.13, 0.1]\nmax = [0.43, 0.5, 0.37]",
    "shape = \"sphere\"\ncenter = [0.3, 0.4, 0.5]\nradius = 0.21",
    "shape = \"cylinder\"\ncenter = [0.3, 0.5, 0.4]\naxis = [0.3, 1.0, 0.2]\nradius = 0.15\n\
     height = 0.4",
];

fn on_threads<T: Send>(n: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .expect("pool")
        .install(f)
}

#[test]
fn the_parallel_sampler_gives_the_one_thread_samplers_particles_bit_for_bit() {
    for shape in SHAPES {
        for sampling in ["regular", "jittered", "random"] {
            for spin in [false, true] {
                let s = scene(shape, sampling, spin);
                let want = reference_scene(&s);
                assert!(want.len() > 10_000, "{}", want.len());
                for threads in [1, 2, 7] {
                    let got = on_threads(threads, || s.sample_particles().expect("sample"));
                    assert!(
                        hash(&got) == hash(&want) && got == want,
                        "{shape} {sampling} spin {spin}, {threads} threads: {} vs {} particles",
                        got.len(),
                        want.len()
                    );
                }
                for (i, _) in s.bodies.iter().enumerate() {
                    let n = reference_positions(&s, i).0.len() as u64;
                    assert_eq!(sampling::count_body(&s, i).expect("count"), n);
                    assert_eq!(sampling::body_is_empty(&s, i).expect("empty"), n == 0);
                    assert_eq!(sampling::sample_body(&s, i).expect("body").len() as u64, n);
                }
            }
        }
    }
}

/// Hashes of the one-thread sampler's output (main at 36298c1, before the parallel sampler):
/// the reference above has not drifted from what it replaced.
#[test]
fn the_reference_matches_the_stored_hashes() {
    let mut got = Vec::new();
    for shape in SHAPES {
        for sampling in ["regular", "jittered", "random"] {
            let s = scene(shape, sampling, true);
            let p = on_threads(2, || s.sample_particles().expect("sample"));
            got.push((p.len(), hash(&p)));
        }
    }
    let want: [(usize, u64); 9] = STORED;
    assert_eq!(got, want);
}

const STORED: [(usize, u64); 9] = [
    (49136, 10091338641063624639),
    (49136, 576231085575795456),
    (49136, 13191513338965221350),
    (55193, 16152241255797691243),
    (54940, 18323441868365053623),
    (54961, 17586232703280911219),
    (44503, 4248318399991717759),
    (44462, 5168870596611180682),
    (44443, 545559334193050534),
];

/// A body far larger than the 50M particles a body was once limited to is sampled, and counted
/// without storing it (a lattice of 2.1e8 points walked, nothing kept).
#[test]
fn a_body_past_the_old_per_body_limit_is_counted() {
    let text = "[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ndx = 0.0025\n[time]\nduration = 1\n\
                [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000\nbulk_modulus = 1e5\n\
                [[body]]\nmaterial = \"w\"\nshape = \"sphere\"\ncenter = [0.5, 0.5, 0.5]\n\
                radius = 0.49\nparticles_per_cell = 27\nsampling = \"regular\"\n";
    let s = Scene::from_toml(text, "big").expect("scene");
    let est = sampling::estimate_body(&s, 0);
    assert!(est > 50_000_000, "{est}");
    let n = sampling::count_body(&s, 0).expect("count");
    assert!((n as f64 / est as f64 - 1.0).abs() < 1e-3, "{n} vs {est}");
    assert!(matches!(s.bodies[0].shape, Shape::Sphere(_)));
}
