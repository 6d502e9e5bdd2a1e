//! Tests of the device fill's host side (`setup/fill`): the table, the pieces, the gathering, and a
//! word-for-word emulation of `fill_body` (`kernels/fill.cu`) against the host packing.

use super::*;
use crate::kernels::SOURCES;
use rtmpm_physics::math::Mat3;
use rtmpm_scene::Scene;
use rtmpm_scene::sampling::sample_bodies;

const SCENE: &str = r#"
name = "fill"
seed = 3
[domain]
min = [0.0, 0.0, 0.0]
max = [1.0, 1.0, 1.0]
dx = 0.03125
[time]
duration = 0.1
fps = 30
cfl = 0.4
[[material]]
name = "water"
type = "fluid"
density = 1000.0
bulk_modulus = 4.0e4
gamma = 7.15
[[material]]
name = "jelly"
type = "neo_hookean"
density = 1100.0
youngs_modulus = 2.0e4
poisson_ratio = 0.3
[[body]]
material = "water"
shape = "box"
min = [0.1, 0.1, 0.1]
max = [0.6, 0.5, 0.7]
particles_per_cell = 8
sampling = "regular"
velocity = [1.0, -0.0, 0.5]
angular_velocity = [2.0, 0.0, -5.0]
[[body]]
material = "jelly"
shape = "sphere"
center = [0.7, 0.6, 0.5]
radius = 0.2
particles_per_cell = 8
sampling = "jittered"
velocity = [-2.0, 1.5, 0.0]
angular_velocity = [0.5, 7.0, 1.0e-3]
[[body]]
material = "jelly"
shape = "cylinder"
center = [0.5, 0.3, 0.5]
radius = 0.1
height = 0.3
particles_per_cell = 4
sampling = "random"
"#;

fn bodies() -> (Scene, Vec<SampledBody>) {
    let scene = Scene::from_toml(SCENE, "fill test").expect("scene");
    let bodies = sample_bodies(&scene, &|_| {}).expect("sample");
    (scene, bodies)
}

const FLUID: [bool; 2] = [true, false];

/// The table rows hold each body's range and velocity field, and with the kernel's own words
/// (x, v unless constant, id) the constants cover every word of the layout once.
#[test]
fn the_table_holds_ranges_and_every_word_once() {
    let (_, bodies) = bodies();
    for (layout, f64) in [
        (StateLayout::Full, false),
        (StateLayout::Full, true),
        (StateLayout::Compact, false),
    ] {
        let rows = table(&bodies, &FLUID, layout, f64).expect("table");
        assert_eq!(rows.len(), FILL_WORDS * bodies.len());
        let mut start = 0u64;
        for (body, row) in bodies.iter().zip(rows.chunks_exact(FILL_WORDS)) {
            let SampledBody::Shape(b) = body else {
                panic!("a shape")
            };
            let word64 = |at: usize| row[at] as u64 | (row[at + 1] as u64) << 32;
            assert_eq!(word64(FT_START), start);
            assert_eq!(word64(FT_COUNT), b.count as u64);
            for a in 0..3 {
                assert_eq!(row[FT_V0 + a], b.velocity[a].to_bits());
                assert_eq!(row[FT_W + a], b.angular_velocity[a].to_bits());
                assert_eq!(row[FT_CENTRE + a], b.centre[a].to_bits());
            }
            let mut seen = vec![0; layout.words()];
            for a in 0..3 {
                seen[layout.x() + a] += 1;
            }
            (0..3).for_each(|a| seen[layout.v() + a] += 1);
            seen[layout.id()] += 1;
            for k in 0..row[FT_NCONST] as usize {
                let w = row[FT_CONST + 3 * k] as usize;
                seen[w] += 1;
                if !f64 {
                    assert_eq!(row[FT_CONST + 3 * k + 2], 0, "high bits of an f32 word");
                }
            }
            assert!(seen.iter().all(|&c| c == 1), "{layout:?}: {seen:?}");
            start += b.count as u64;
        }
        assert!(start > 1000, "{start} particles");
    }
    // A material out of range: the packing's error.
    let e = table(&bodies, &[true], StateLayout::Full, false).expect_err("material 1 of 1");
    assert!(e.contains("material 1 out of range"), "{e}");
}

/// The pieces cover every body of a shape in order, contiguous, none longer than `max`.
#[test]
fn the_pieces_cover_each_body_in_order() {
    let (_, bodies) = bodies();
    for max in [1usize, 7, 1000, 1 << 22] {
        let ps = pieces(&bodies, max);
        for (i, body) in bodies.iter().enumerate() {
            let mine: Vec<_> = ps.iter().filter(|p| p.body == i).collect();
            let mut at = 0;
            for p in &mine {
                assert_eq!(p.offset, at, "max {max}");
                assert!(p.len >= 1 && p.len <= max, "max {max}: {p:?}");
                at += p.len;
            }
            assert_eq!(at, body.len(), "max {max}, body {i}");
            // All but the last are full.
            assert!(mine.iter().rev().skip(1).all(|p| p.len == max));
        }
        assert!(ps.windows(2).all(|w| w[0].body <= w[1].body));
    }
}

/// Gathering any range of a body gives its positions in walk order, across chunk borders.
#[test]
fn gather_copies_a_range_across_chunks() {
    // Chunks of uneven lengths, an empty one among them (as a walk may leave).
    let mut k = 0.0f32;
    let mut chunk = |len: usize| -> Vec<Vec3> {
        (0..len)
            .map(|_| {
                k += 1.0;
                Vec3::new(k, -k, 0.5 * k)
            })
            .collect()
    };
    let chunks = vec![chunk(300), chunk(0), chunk(17), chunk(1000), chunk(1)];
    let count = chunks.iter().map(|c| c.len()).sum();
    let b = &BodyPositions {
        chunks,
        count,
        vol0: 1.0,
        mass: 1.0,
        plastic: 0.0,
        material: 0,
        velocity: Vec3::ZERO,
        angular_velocity: Vec3::ZERO,
        centre: Vec3::ZERO,
        c: Mat3::ZERO,
    };
    let all: Vec<Vec3> = b.chunks.iter().flatten().copied().collect();
    for (offset, len) in [
        (0, all.len()),
        (1, 5),
        (b.chunks[0].len() - 3, 700),
        (all.len() - 1, 1),
    ] {
        let len = len.min(all.len() - offset);
        let mut out = vec![f32::NAN; 3 * len + 6];
        gather(b, offset, len, &mut out);
        for k in 0..len {
            assert_eq!(&out[3 * k..3 * k + 3], &all[offset + k].to_array());
        }
        assert!(
            out[3 * len..].iter().all(|v| v.is_nan()),
            "wrote past the range"
        );
    }
}

/// `fill_body` as written in `kernels/fill.cu`, operation for operation (f32, each rounded on
/// its own, as the inline PTX does), into an image of `layout` with stride `cap`.
fn emulate<W: FromF32>(
    rows: &[u32],
    bodies: &[SampledBody],
    layout: StateLayout,
    cap: usize,
) -> Vec<W> {
    let mut s = vec![W::zero(); layout.words() * cap];
    for p in pieces(bodies, 1000) {
        let SampledBody::Shape(b) = &bodies[p.body] else {
            continue;
        };
        let mut xs = vec![0f32; 3 * p.len];
        gather(b, p.offset, p.len, &mut xs);
        let t = &rows[p.body * FILL_WORDS..(p.body + 1) * FILL_WORDS];
        let start = t[FT_START] as u64 | (t[FT_START + 1] as u64) << 32;
        let g = |w: usize| f32::from_bits(t[w]);
        let (v0, w, c) = (
            [0, 1, 2].map(|a| g(FT_V0 + a)),
            [0, 1, 2].map(|a| g(FT_W + a)),
            [0, 1, 2].map(|a| g(FT_CENTRE + a)),
        );
        for k in 0..p.len {
            let i = (start + (p.offset + k) as u64) as usize;
            let x = [xs[3 * k], xs[3 * k + 1], xs[3 * k + 2]];
            let mut put = |f: usize, v: W| s[f * cap + i] = v;
            for (a, &xa) in x.iter().enumerate() {
                put(layout.x() + a, W::from(xa));
            }
            let d = [x[0] - c[0], x[1] - c[1], x[2] - c[2]];
            let r = [
                w[1] * d[2] - d[1] * w[2],
                w[2] * d[0] - d[2] * w[0],
                w[0] * d[1] - d[0] * w[1],
            ];
            for a in 0..3 {
                put(layout.v() + a, W::from(v0[a] + r[a]));
            }
            for e in 0..t[FT_NCONST] as usize {
                let q = &t[FT_CONST + 3 * e..FT_CONST + 3 * e + 3];
                put(q[0] as usize, W::raw(q[1], q[2]));
            }
            put(layout.id(), W::bits(i as u32));
        }
    }
    s
}

/// A state word of the emulation.
trait FromF32: Copy {
    fn zero() -> Self;
    fn from(x: f32) -> Self;
    fn bits(b: u32) -> Self;
    fn raw(lo: u32, hi: u32) -> Self;
    fn bytes(v: &[Self]) -> Vec<u8>;
}

impl FromF32 for f32 {
    fn zero() -> Self {
        0.0
    }
    fn from(x: f32) -> Self {
        x
    }
    fn bits(b: u32) -> Self {
        f32::from_bits(b)
    }
    fn raw(lo: u32, _hi: u32) -> Self {
        f32::from_bits(lo)
    }
    fn bytes(v: &[Self]) -> Vec<u8> {
        v.iter().flat_map(|w| w.to_le_bytes()).collect()
    }
}

impl FromF32 for f64 {
    fn zero() -> Self {
        0.0
    }
    fn from(x: f32) -> Self {
        x as f64
    }
    fn bits(b: u32) -> Self {
        f64::from_bits(b as u64)
    }
    fn raw(lo: u32, hi: u32) -> Self {
        f64::from_bits(lo as u64 | (hi as u64) << 32)
    }
    fn bytes(v: &[Self]) -> Vec<u8> {
        v.iter().flat_map(|w| w.to_le_bytes()).collect()
    }
}

/// The kernel's arithmetic on the table and the positions gives the host's image word for word
/// in every state layout, f32 and (where the layout allows it) f64, for bodies with velocity and
/// spin (the fluid layouts: water only). The GPU test `tests/fill.rs` checks the kernel itself.
#[test]
fn the_fill_arithmetic_is_the_host_packing() {
    let (_, mixed) = bodies();
    let water = {
        let text = SCENE.replace("material = \"jelly\"", "material = \"water\"");
        let scene = Scene::from_toml(&text, "fill test").expect("scene");
        sample_bodies(&scene, &|_| {}).expect("sample")
    };
    for layout in StateLayout::ALL {
        let (bodies, fluid): (&[SampledBody], &[bool]) = if layout.fluid() {
            (&water, &[true, true])
        } else {
            (&mixed, &FLUID)
        };
        let n: usize = bodies.iter().map(|b| b.len()).sum();
        for f64 in [false, true] {
            if f64 && layout.compact() {
                continue;
            }
            let rows = table(bodies, fluid, layout, f64).expect("table");
            let host = crate::state::pack_bodies(bodies, fluid, layout, f64).expect("pack");
            let got = if f64 {
                FromF32::bytes(&emulate::<f64>(&rows, bodies, layout, n))
            } else {
                FromF32::bytes(&emulate::<f32>(&rows, bodies, layout, n))
            };
            assert!(got == host, "{layout:?}, f64 = {f64}");
        }
    }
}

/// The kernel reads the table through the `FT_*` names of the generated header, and rounds every
/// operation of the velocity on its own (no fma contraction, no flush to zero).
#[test]
fn the_kernel_uses_the_contract_and_unfused_arithmetic() {
    let (_, src) = SOURCES
        .iter()
        .find(|(n, _)| *n == "fill.cu")
        .expect("fill.cu");
    for name in [
        "FT_START",
        "FT_V0",
        "FT_W",
        "FT_CENTRE",
        "FT_NCONST",
        "FT_CONST",
        "FILL_WORDS",
    ] {
        assert!(src.contains(name), "{name}");
    }
    for op in ["add.rn.f32", "sub.rn.f32", "mul.rn.f32", "cvt.f64.f32"] {
        assert!(src.contains(op), "{op}");
    }
    assert!(!src.contains(".ftz"), "flushes subnormals");
    let prelude = crate::contract::prelude();
    assert!(prelude.contains(&format!("#define FILL_WORDS {FILL_WORDS}")));
    assert!(prelude.contains(&format!("#define FT_CONST {FT_CONST}")));
    const { assert!(FT_NCONST < FT_CONST) };
}

/// The set-up line names every phase, and what no phase accounts for as "other".
#[test]
fn the_setup_phases_read_as_a_line() {
    let p = crate::setup::SetupPhases {
        probe: 0.1,
        layout: 0.2,
        kernels: 0.4,
        pack: 0.0,
        allocate: 0.3,
        fill: 0.8,
        fill_gather: 0.5,
        fill_count: 0.01,
        total: 2.0,
    };
    let line = p.to_string();
    for part in [
        "probe 0.10 s",
        "layout 0.20 s",
        "kernels 0.40 s",
        "pack 0.00 s",
        "allocate+upload 0.30 s",
        "device fill 0.80 s (gather 0.50 s, rows counted 0.01 s)",
        "other 0.20 s",
    ] {
        assert!(line.contains(part), "{part} in {line}");
    }
}
