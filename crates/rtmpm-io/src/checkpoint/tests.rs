//! Tests of the checkpoint format.

use super::*;
use crate::testing::TestDir;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::fs;

/// A scene of one material in a 2 km box of 10 m cells, without rigid bodies.
const SCENE: ResumedScene = ResumedScene {
    domain_min: Vec3::splat(-1000.0),
    domain_max: Vec3::splat(1000.0),
    dx: 10.0,
    materials: 1,
    rigid_bodies: Vec::new(),
};

fn random_checkpoint(n: usize, seed: u64) -> Checkpoint {
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut r = || rng.random_range(-1e3f32..1e3);
    let mut p = Particles::default();
    for _ in 0..n {
        p.x.push(Vec3::new(r(), r(), r()));
        p.v.push(Vec3::new(r(), r(), r()));
        let mut m = [0f32; 9];
        m.iter_mut().for_each(|a| *a = r());
        p.c.push(Mat3::from_cols_array(&m));
        m.iter_mut().for_each(|a| *a = r());
        p.f.push(Mat3::from_cols_array(&m));
        p.plastic.push(r());
        p.mass.push(r().abs() + 1e-30);
        p.vol0.push(r().abs() * 1e-9);
        p.material.push((r().abs() * 1e6) as u32);
    }
    // A few special values that must survive bit-exactly.
    if n > 2 {
        p.x[0].x = -0.0;
        p.v[1].y = f32::MIN_POSITIVE / 4.0; // subnormal
        p.plastic[2] = f32::MAX;
        p.material[2] = u32::MAX;
    }
    let bodies = (0..n.min(3))
        .map(|i| BodyPose {
            position: Vec3::new(r(), r(), r()),
            rotation: glam::Quat::from_scaled_axis(Vec3::new(r(), r(), r()) * 1e-3),
            velocity: Vec3::new(r(), r(), r()),
            angular_velocity: Vec3::new(r(), r(), i as f32),
        })
        .collect();
    Checkpoint {
        scene_toml: "[sim]\ndt = 1e-4 # é ünïcode\n".into(),
        scene_origin: "/scenes/snow.toml".into(),
        time: 0.1 + 0.2,
        step: 123_456_789_012,
        frame: 42,
        bodies,
        files: Vec::new(),
        particles: p,
    }
}

#[test]
fn round_trip_bit_identical() {
    let d = TestDir::new("ckpt");
    let ck = random_checkpoint(1000, 7);
    let path = d.path("ckpt/state.ckpt");
    ck.save(&path).unwrap();
    let back = Checkpoint::load(&path).unwrap();
    assert_eq!(back, ck);
    assert_eq!(back.time.to_bits(), ck.time.to_bits());
    assert_eq!(back.particles.x[0].x.to_bits(), (-0.0f32).to_bits());
    let bits = |p: &Particles| -> Vec<u32> {
        p.c.iter()
            .chain(&p.f)
            .flat_map(|m| m.to_cols_array())
            .map(f32::to_bits)
            .collect()
    };
    assert_eq!(bits(&back.particles), bits(&ck.particles));
    let size = fs::metadata(&path).unwrap().len();
    assert_eq!(size, 32 + ck.payload_len());
}

#[test]
fn empty_round_trip() {
    let d = TestDir::new("ckpt-empty");
    let ck = Checkpoint {
        scene_toml: String::new(),
        scene_origin: String::new(),
        time: 0.0,
        step: 0,
        frame: 0,
        bodies: Vec::new(),
        files: Vec::new(),
        particles: Particles::default(),
    };
    let path = d.path("e.ckpt");
    ck.save(&path).unwrap();
    assert_eq!(Checkpoint::load(&path).unwrap(), ck);
}

/// Files of versions 1 (no rigid bodies) and 2 (no file hashes) are still read.
#[test]
fn version_1_and_2_files_are_read() {
    let mut ck = random_checkpoint(30, 4);
    ck.bodies.clear();
    let d = TestDir::new("ckpt-v1");
    let path = d.path("v3.ckpt");
    ck.save(&path).unwrap();
    let v3 = fs::read(&path).unwrap();
    // After the frame: the body count (0) then the file count (0) of version 3.
    let at = HEADER_LEN + 16 + ck.scene_toml.len() + ck.scene_origin.len() + 24;
    assert_eq!(v3[at..at + 16], [0u8; 16]);
    // Version 1: without both counts; version 2: without the file count; each with its own
    // checksum.
    for (version, cut) in [(1u32, at..at + 16), (2, at + 8..at + 16)] {
        let mut old = [&v3[..cut.start], &v3[cut.end..v3.len() - CHECKSUM_LEN]].concat();
        old[8..12].copy_from_slice(&version.to_le_bytes());
        let len = (old.len() - HEADER_LEN) as u64;
        old[16..24].copy_from_slice(&len.to_le_bytes());
        let mut h = Fnv1a64::default();
        h.update(&old);
        old.extend_from_slice(&h.finish().to_le_bytes());
        assert_eq!(
            Checkpoint::from_bytes(&old).unwrap(),
            ck,
            "version {version}"
        );
    }
}

/// The hashes of the scene's files survive the round trip; a count the bytes cannot hold is
/// refused.
#[test]
fn file_hashes_round_trip() {
    let mut ck = random_checkpoint(5, 7);
    ck.files = vec![
        FileHash {
            field: "collider[0].file".into(),
            path: "meshes/bowl.obj".into(),
            hash: 0x0123_4567_89ab_cdef,
        },
        FileHash {
            field: "body[1].file".into(),
            path: String::new(),
            hash: u64::MAX,
        },
    ];
    let d = TestDir::new("ckpt-files");
    let path = d.path("f.ckpt");
    ck.save(&path).unwrap();
    assert_eq!(Checkpoint::load(&path).unwrap(), ck);
    // The file count patched to 2^40, the checksum made valid again: refused, no allocation.
    let mut bytes = fs::read(&path).unwrap();
    let at = HEADER_LEN
        + 16
        + ck.scene_toml.len()
        + ck.scene_origin.len()
        + 24
        + 8
        + 4 * 13 * ck.bodies.len();
    assert_eq!(bytes[at..at + 8], 2u64.to_le_bytes());
    bytes[at..at + 8].copy_from_slice(&(1u64 << 40).to_le_bytes());
    let body = bytes.len() - CHECKSUM_LEN;
    let mut h = Fnv1a64::default();
    h.update(&bytes[..body]);
    let sum = h.finish().to_le_bytes();
    bytes[body..].copy_from_slice(&sum);
    let e = Checkpoint::from_bytes(&bytes).unwrap_err().to_string();
    assert!(e.contains("file hashes do not fit"), "{e}");
}

/// Bodies survive bit for bit; a count that the bytes cannot hold, or a pose that is not
/// finite, is refused.
#[test]
fn rigid_bodies_round_trip_and_bad_ones_are_refused() {
    let ck = random_checkpoint(10, 9);
    assert_eq!(ck.bodies.len(), 3);
    let d = TestDir::new("ckpt-bodies");
    let path = d.path("b.ckpt");
    ck.save(&path).unwrap();
    let back = Checkpoint::load(&path).unwrap();
    let bits = |c: &Checkpoint| -> Vec<u32> {
        c.bodies
            .iter()
            .flat_map(super::body_words)
            .map(f32::to_bits)
            .collect()
    };
    assert_eq!(bits(&back), bits(&ck));
    let mut bad = ck.clone();
    bad.bodies[1].velocity.y = f32::NAN;
    let e = bad.save(&d.path("nan.ckpt")).unwrap_err();
    assert!(e.to_string().contains("rigid body 1"), "{e}");
    let mut bad = ck.clone();
    bad.bodies[2].rotation = glam::Quat::from_xyzw(0.0, 0.0, 0.0, 2.0);
    assert!(bad.save(&d.path("q.ckpt")).is_err());
    // A scene with another number of bodies is refused at resume.
    let scene = SCENE;
    let e = back.check_fits(&scene).unwrap_err();
    assert!(e.to_string().contains("3 rigid bodies"), "{e}");
}

#[test]
fn truncated_file_is_an_error() {
    let d = TestDir::new("ckpt-trunc");
    let path = d.path("t.ckpt");
    random_checkpoint(50, 1).save(&path).unwrap();
    let bytes = fs::read(&path).unwrap();
    for len in [0, 4, 8, 20, 24, 100, bytes.len() / 2, bytes.len() - 1] {
        let err = Checkpoint::from_bytes(&bytes[..len]).unwrap_err();
        match (len, &err) {
            (0..8, CheckpointError::BadMagic) => {}
            (8.., CheckpointError::Truncated { found, .. }) => {
                assert_eq!(*found, len as u64)
            }
            _ => panic!("len {len}: unexpected {err:?}"),
        }
    }
    fs::write(&path, &bytes[..bytes.len() - 9]).unwrap();
    let err = Checkpoint::load(&path).unwrap_err();
    assert!(err.to_string().contains("truncated"), "{err}");
}

#[test]
fn corrupt_and_foreign_files_are_errors() {
    let d = TestDir::new("ckpt-bad");
    let path = d.path("c.ckpt");
    random_checkpoint(20, 2).save(&path).unwrap();
    let bytes = fs::read(&path).unwrap();

    // Flip one bit anywhere in the payload.
    for at in [HEADER_LEN, HEADER_LEN + 50, bytes.len() - 20] {
        let mut b = bytes.clone();
        b[at] ^= 0x10;
        assert!(matches!(
            Checkpoint::from_bytes(&b),
            Err(CheckpointError::ChecksumMismatch { .. })
        ));
    }

    let mut b = bytes.clone();
    b[..8].copy_from_slice(b"PLYPLYPL");
    let err = Checkpoint::from_bytes(&b).unwrap_err();
    assert!(matches!(err, CheckpointError::BadMagic));
    assert!(err.to_string().contains("not an rtmpm checkpoint"));

    let mut b = bytes.clone();
    b[8..12].copy_from_slice(&99u32.to_le_bytes());
    assert!(matches!(
        Checkpoint::from_bytes(&b),
        Err(CheckpointError::UnsupportedVersion { found: 99, .. })
    ));

    let mut b = bytes.clone();
    b.push(0);
    assert!(matches!(
        Checkpoint::from_bytes(&b),
        Err(CheckpointError::Truncated { .. })
    ));

    // A huge announced payload length must not allocate or panic.
    let mut b = bytes.clone();
    b[16..24].copy_from_slice(&u64::MAX.to_le_bytes());
    assert!(matches!(
        Checkpoint::from_bytes(&b),
        Err(CheckpointError::Truncated { .. })
    ));

    assert!(matches!(
        Checkpoint::load(&d.path("missing.ckpt")),
        Err(CheckpointError::Io(_))
    ));
}

/// Intact bytes (a valid checksum) around values that cannot be simulated are refused
/// with the particle and the value, never run.
#[test]
fn valid_checksum_bad_values_are_refused() {
    let mut good = random_checkpoint(5, 3);
    good.particles.material.iter_mut().for_each(|m| *m = 0);
    good.bodies.clear();
    good.particles.plastic[2] = 0.0;
    let scene = SCENE;
    let round = |ck: &Checkpoint| {
        let d = TestDir::new("ckpt-values");
        let path = d.path("v.ckpt");
        ck.save(&path).unwrap();
        Checkpoint::load(&path)
    };
    let back = round(&good).unwrap();
    back.check_fits(&scene).unwrap();

    type Edit = fn(&mut Checkpoint);
    let cases: [(Edit, &str); 7] = [
        (|c| c.particles.mass[1] = f32::NAN, "mass NaN"),
        (|c| c.particles.mass[3] = -2.0, "mass -2"),
        (
            |c| c.particles.vol0[0] = f32::INFINITY,
            "initial volume inf",
        ),
        (|c| c.particles.v[4].x = f32::NAN, "velocity"),
        (|c| c.time = -1.0, "time -1"),
        (|c| c.time = f64::INFINITY, "time inf"),
        (|c| c.frame = c.step + 1, "frame"),
    ];
    for (edit, expect) in cases {
        let mut ck = good.clone();
        edit(&mut ck);
        let e = round(&ck).unwrap_err();
        assert!(matches!(e, CheckpointError::BadValue(_)), "{e:?}");
        assert!(e.to_string().contains(expect), "{e} (expected {expect})");
    }
    // Scene-dependent values: checked by check_fits.
    let mut ck = good.clone();
    ck.particles.material[2] = 7;
    let e = round(&ck).unwrap().check_fits(&scene).unwrap_err();
    assert!(
        e.to_string().contains("particle 2: material index 7"),
        "{e}"
    );
    let mut ck = good.clone();
    ck.particles.x[1].y = 1e9;
    let e = round(&ck).unwrap().check_fits(&scene).unwrap_err();
    assert!(e.to_string().contains("particle 1: position"), "{e}");
}

#[test]
fn fnv1a_reference_values() {
    let h = |s: &[u8]| {
        let mut f = Fnv1a64::default();
        f.update(s);
        f.finish()
    };
    assert_eq!(h(b""), 0xcbf29ce484222325);
    assert_eq!(h(b"a"), 0xaf63dc4c8601ec8c);
    assert_eq!(h(b"foobar"), 0x85944171f73967e8);
}
