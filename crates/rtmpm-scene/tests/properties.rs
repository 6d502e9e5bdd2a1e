//! Property tests (proptest) of the readers and the scene validator: round trips are exact,
//! and hostile inputs (valid files mutated, truncated, or with one value replaced by a hostile
//! one) give a result or a clear error, never a panic. The coverage-guided counterpart is
//! fuzz/ (scripts/fuzz.sh).

use proptest::prelude::*;
use rtmpm_io::checkpoint::Checkpoint;
use rtmpm_io::{FrameFields, ply, vtu};
use rtmpm_physics::Particles;
use rtmpm_physics::math::{Mat3, Vec3};
use rtmpm_scene::Scene;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};

fn temp_file(tag: &str) -> PathBuf {
    static N: AtomicU64 = AtomicU64::new(0);
    let dir = std::env::temp_dir().join(format!("rtmpm-prop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(format!("{tag}-{}", N.fetch_add(1, Ordering::Relaxed)))
}

/// Particles with any finite values (and positive mass and volume), `n` of them.
fn particles(max: usize) -> impl Strategy<Value = Particles> {
    let f = || -1e6f32..1e6f32;
    let one = (
        (f(), f(), f()),
        (f(), f(), f()),
        prop::array::uniform9(f()),
        prop::array::uniform9(f()),
        f(),
        (1e-9f32..1e3, 1e-12f32..1.0),
        0u32..(i32::MAX as u32),
    );
    prop::collection::vec(one, 0..max).prop_map(|v| {
        let mut p = Particles::default();
        for ((x, y, z), (a, b, c), cm, fm, pl, (m, vol), mat) in v {
            p.push(Vec3::new(x, y, z), Vec3::new(a, b, c), m, vol, mat, pl);
            *p.c.last_mut().unwrap() = Mat3::from_cols_array(&cm);
            *p.f.last_mut().unwrap() = Mat3::from_cols_array(&fm);
        }
        p
    })
}

/// A valid file mutated: truncated at `cut` (fraction), and `flips` bytes changed.
fn mutate(bytes: &[u8], cut: f64, flips: &[(usize, u8)]) -> Vec<u8> {
    let mut b = bytes[..((bytes.len() as f64 * cut) as usize).min(bytes.len())].to_vec();
    for &(at, v) in flips {
        if !b.is_empty() {
            let i = at % b.len();
            b[i] ^= v;
        }
    }
    b
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn ply_round_trip_is_exact(p in particles(40)) {
        let path = temp_file("rt.ply");
        ply::write_ply(&path, &p, &FrameFields::default()).unwrap();
        let d = ply::read_ply(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        prop_assert_eq!(d.count, p.len());
        let xs: Vec<u32> = p.x.iter().map(|x| x.y.to_bits()).collect();
        let back: Vec<u32> = d.f32("y").unwrap().iter().map(|v| v.to_bits()).collect();
        prop_assert_eq!(xs, back);
        let mats: Vec<i64> = p.material.iter().map(|&m| m as i64).collect();
        prop_assert_eq!(d.int("material").unwrap(), mats.as_slice());
    }

    #[test]
    fn ply_mutations_never_panic(
        p in particles(8),
        cut in 0.0f64..1.2,
        flips in prop::collection::vec((any::<usize>(), 1u8..=255), 0..6),
    ) {
        let path = temp_file("m.ply");
        ply::write_ply(&path, &p, &FrameFields::default()).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        if let Ok(d) = ply::parse_ply(&mutate(&bytes, cut, &flips)) {
            prop_assert!(d.columns.iter().all(|(_, c)| c.len() == d.count));
        }
    }

    #[test]
    fn ply_random_bytes_never_panic(
        head in prop::sample::select(vec![
            "ply\nformat binary_little_endian 1.0\n",
            "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n",
            "ply\nformat binary_little_endian 1.0\nelement face 2\nproperty list uchar int v\n",
        ]),
        tail in prop::collection::vec(any::<u8>(), 0..200),
    ) {
        let mut b = head.as_bytes().to_vec();
        b.extend_from_slice(&tail);
        let _ = ply::parse_ply(&b);
    }

    #[test]
    fn checkpoint_round_trip_and_any_corruption_is_refused(
        p in particles(20),
        time in 0.0f64..1e6,
        step in 0u64..1_000_000,
        at in any::<usize>(),
        bit in 0u8..8,
        cut in 0.0f64..1.0,
    ) {
        let ck = Checkpoint {
            scene_toml: "name = \"p\"".into(),
            scene_origin: "p.toml".into(),
            time,
            step,
            frame: step / 2,
            bodies: Vec::new(),
            files: Vec::new(),
            particles: p,
        };
        let path = temp_file("c.ckpt");
        ck.save(&path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        prop_assert_eq!(Checkpoint::from_bytes(&bytes).unwrap(), ck);
        // One flipped bit anywhere, or a truncation: an error, never a panic or a wrong state.
        let mut flipped = bytes.clone();
        let i = at % flipped.len();
        flipped[i] ^= 1 << bit;
        prop_assert!(Checkpoint::from_bytes(&flipped).is_err());
        let short = &bytes[..(bytes.len() as f64 * cut) as usize];
        prop_assert!(Checkpoint::from_bytes(short).is_err());
    }

    #[test]
    fn vtu_round_trip_and_mutations(
        p in particles(10),
        cut in 0.0f64..1.2,
        flips in prop::collection::vec((any::<usize>(), 1u8..=127), 0..6),
    ) {
        let path = temp_file("v.vtu");
        vtu::write_particles_vtu(&path, &p, &FrameFields::default(), vtu::Encoding::Inline)
            .unwrap();
        let text = std::fs::read(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        let d = vtu::parse_vtu(std::str::from_utf8(&text).unwrap()).unwrap();
        let pts: Vec<[f32; 3]> = p.x.iter().map(|x| x.to_array()).collect();
        prop_assert_eq!(d.points, pts);
        let bad = mutate(&text, cut, &flips);
        let _ = vtu::parse_vtu(&String::from_utf8_lossy(&bad));
        let _ = vtu::parse_pvd(&String::from_utf8_lossy(&bad));
    }
}

/// A valid scene; each `{K}` is a slot whose value a property replaces by a hostile one.
const SCENE: &str = r#"name = "prop"
seed = {seed}
gravity = {gravity}
[domain]
min = {dmin}
max = [1.0, 1.0, 1.0]
dx = {dx}
[time]
duration = {duration}
fps = {fps}
cfl = {cfl}
max_dt = {max_dt}
[walls]
thickness = {thickness}
friction = {friction}
[[material]]
name = "jelly"
type = "fixed_corotated"
density = {density}
youngs_modulus = {youngs}
poisson_ratio = {poisson}
[[material]]
name = "water"
type = "fluid"
density = 1000.0
bulk_modulus = {bulk}
[[body]]
material = "jelly"
shape = "box"
min = {bmin}
max = [0.5, 0.5, 0.5]
particles_per_cell = {ppc}
velocity = {velocity}
angular_velocity = {omega}
[[body]]
material = "water"
shape = "sphere"
center = [0.7, 0.5, 0.5]
radius = {radius}
sampling = "random"
count = {count}
[[collider]]
shape = "half_space"
point = [0.0, 0.1, 0.0]
normal = {normal}
[output]
dir = {dir}
[render]
fov = {fov}
width = {width}
"#;

const SLOTS: [(&str, &str); 24] = [
    ("seed", "1"),
    ("gravity", "[0.0, -9.81, 0.0]"),
    ("dmin", "[0.0, 0.0, 0.0]"),
    ("dx", "0.05"),
    ("duration", "0.1"),
    ("fps", "30"),
    ("cfl", "0.4"),
    ("max_dt", "1e-3"),
    ("thickness", "3"),
    ("friction", "0.1"),
    ("density", "1000.0"),
    ("youngs", "1e4"),
    ("poisson", "0.3"),
    ("bulk", "1e5"),
    ("bmin", "[0.2, 0.2, 0.2]"),
    ("ppc", "8"),
    ("velocity", "[0.0, 0.0, 0.0]"),
    ("omega", "[0.0, 1.0, 0.0]"),
    ("radius", "0.1"),
    ("count", "500"),
    ("normal", "[0.0, 1.0, 0.0]"),
    ("dir", "\"out/prop\""),
    ("fov", "40"),
    ("width", "640"),
];

const HOSTILE: [&str; 26] = [
    "nan",
    "inf",
    "-inf",
    "-1",
    "0",
    "-0.0",
    "1e38",
    "3.4e39",
    "1e-45",
    "99999999999999999999",
    "-99999999999999999999",
    "4294967296",
    "18446744073709551615",
    "\"text\"",
    "\"\"",
    "\"../../..\"",
    "[]",
    "[1.0]",
    "[nan, 0, 0]",
    "[1e38, 1e38, 1e38]",
    "[-1e38, 0, 0]",
    "[0, 0, 0]",
    "{ x = 1 }",
    "true",
    "1979-05-27",
    "[[1, 2], 3, 4]",
];

fn fill(replace: &[(usize, usize)]) -> String {
    let mut text = SCENE.to_string();
    for (i, (slot, good)) in SLOTS.iter().enumerate() {
        let value = replace
            .iter()
            .find(|(s, _)| *s % SLOTS.len() == i)
            .map_or(*good, |(_, h)| HOSTILE[*h % HOSTILE.len()]);
        text = text.replace(&format!("{{{slot}}}"), value);
    }
    text
}

#[test]
fn the_scene_template_is_valid() {
    Scene::from_toml(&fill(&[]), "template").unwrap();
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// One to three values of a valid scene replaced by hostile ones: a scene or an error that
    /// names its line or field, quickly, and a valid result has a budget.
    #[test]
    fn hostile_scene_values_give_placed_errors(
        replace in prop::collection::vec((any::<usize>(), any::<usize>()), 1..4)
    ) {
        let text = fill(&replace);
        let t = std::time::Instant::now();
        match Scene::from_toml(&text, "prop") {
            Ok(s) => {
                let b = rtmpm_scene::Budget::estimate(&s, None);
                prop_assert!(b.particles > 0);
            }
            Err(e) => prop_assert!(e.line.is_some() || e.field.is_some(), "{}", e),
        }
        prop_assert!(t.elapsed().as_secs_f64() < 10.0, "slow: {}", text);
    }
}
