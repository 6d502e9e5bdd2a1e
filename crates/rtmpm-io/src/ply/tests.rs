use super::*;
use crate::testing::TestDir;
use rtmpm_physics::math::Vec3;
use std::fs;

pub(crate) fn sample_particles(n: usize) -> Particles {
    let mut p = Particles::default();
    for i in 0..n {
        let f = i as f32;
        p.push(
            Vec3::new(f * 0.5, -f, f * f * 1e-3),
            Vec3::new(1.0 + f, 2.0, -3.0 * f),
            0.25 + f,
            1e-6,
            (i % 3) as u32,
            0.1 * f,
        );
    }
    p
}

#[test]
fn round_trip_with_fields() {
    let d = TestDir::new("ply");
    let p = sample_particles(17);
    let j: Vec<f32> = (0..17).map(|i| 1.0 + i as f32 * 0.01).collect();
    let s: Vec<[f32; 6]> = (0..17)
        .map(|i| {
            let f = i as f32;
            [f, -f, 2.0 * f, 0.5, -0.5, 1e5 * f]
        })
        .collect();
    let fields = FrameFields {
        stress: Some(&s),
        jacobian: Some(&j),
    };
    let path = d.path("frames/f0001.ply");
    write_ply(&path, &p, &fields).unwrap();
    let r = read_ply(&path).unwrap();
    assert_eq!(r.count, 17);
    assert_eq!(
        r.names(),
        [
            "x", "y", "z", "vx", "vy", "vz", "material", "plastic", "J", "sxx", "syy", "szz",
            "sxy", "syz", "sxz"
        ]
    );
    let xs: Vec<f32> = p.x.iter().map(|x| x.x).collect();
    let vzs: Vec<f32> = p.v.iter().map(|v| v.z).collect();
    assert_eq!(r.f32("x").unwrap(), xs.as_slice());
    assert_eq!(r.f32("vz").unwrap(), vzs.as_slice());
    let mats: Vec<i64> = p.material.iter().map(|&m| m as i64).collect();
    assert_eq!(r.int("material").unwrap(), mats.as_slice());
    assert_eq!(r.f32("plastic").unwrap(), p.plastic.as_slice());
    assert_eq!(r.f32("J").unwrap(), j.as_slice());
    let sxz: Vec<f32> = s.iter().map(|s| s[5]).collect();
    assert_eq!(r.f32("sxz").unwrap(), sxz.as_slice());
    assert_eq!(r.comments, ["rtmpm particles"]);
}

#[test]
fn round_trip_without_fields_and_empty() {
    let d = TestDir::new("ply-min");
    let p = sample_particles(3);
    let path = d.path("a.ply");
    write_ply(&path, &p, &FrameFields::default()).unwrap();
    let r = read_ply(&path).unwrap();
    assert_eq!(r.names().len(), 8);
    assert!(r.column("J").is_none());
    // Exact size: header + 3 * 8 * 4 bytes.
    let bytes = fs::read(&path).unwrap();
    let body = bytes.len()
        - (bytes
            .windows(11)
            .position(|w| w == b"end_header\n")
            .unwrap()
            + 11);
    assert_eq!(body, 3 * 32);

    let empty = d.path("empty.ply");
    write_ply(&empty, &Particles::default(), &FrameFields::default()).unwrap();
    assert_eq!(read_ply(&empty).unwrap().count, 0);
}

#[test]
fn field_length_mismatch_is_rejected() {
    let d = TestDir::new("ply-bad");
    let p = sample_particles(3);
    let j = [1.0f32; 2];
    let fields = FrameFields {
        stress: None,
        jacobian: Some(&j),
    };
    let err = write_ply(&d.path("a.ply"), &p, &fields).unwrap_err();
    assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
    assert!(!d.path("a.ply").exists());
}

#[test]
fn other_formats_and_truncation_give_errors() {
    let ascii = b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1.0\n";
    match parse_ply(ascii) {
        Err(PlyError::UnsupportedFormat(f)) => assert_eq!(f, "ascii 1.0"),
        other => panic!("unexpected {other:?}"),
    }
    assert!(matches!(
        parse_ply(b"not a ply"),
        Err(PlyError::Malformed(_))
    ));
    let mut trunc =
        b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nend_header\n"
            .to_vec();
    trunc.extend_from_slice(&1.0f32.to_le_bytes());
    let err = parse_ply(&trunc).unwrap_err();
    assert!(err.to_string().contains("truncated"), "{err}");
}

/// Counts in the header are checked against the file before anything is allocated or
/// looped over (a header claiming 10^12 vertices once aborted on a 4 TB allocation).
#[test]
fn huge_counts_are_refused_at_once() {
    let t = std::time::Instant::now();
    for header in [
        "element vertex 1000000000000\nproperty float x\n",
        "element vertex 18446744073709551615\nproperty double x\n",
        "element vertex 1000000000000\n",
        "element face 1000000000000\nproperty list uchar int v\nelement vertex 1\nproperty float x\n",
        "element face 1000000000000\nelement vertex 1\nproperty float x\n",
        "element vertex 99999999999999999999999\nproperty float x\n",
    ] {
        let text = format!("ply\nformat binary_little_endian 1.0\n{header}end_header\n");
        let mut b = text.into_bytes();
        b.extend_from_slice(&[0u8; 16]);
        match parse_ply(&b) {
            Err(PlyError::Malformed(_)) => {}
            Ok(d) if d.count == 1 => {} // the zero-size face element is skipped
            other => panic!("{header}: unexpected {other:?}"),
        }
    }
    // A list whose length runs past the end of the file.
    let mut b = b"ply\nformat binary_little_endian 1.0\nelement face 1\nproperty list uint int v\nelement vertex 0\nproperty float x\nend_header\n".to_vec();
    b.extend_from_slice(&u32::MAX.to_le_bytes());
    assert!(parse_ply(&b).is_err());
    assert!(t.elapsed().as_secs_f64() < 5.0);
}

#[test]
fn reads_foreign_layout_with_faces_and_doubles() {
    // A face element (with a list) before the vertices, and a double + uchar column.
    let mut b = b"ply\r\nformat binary_little_endian 1.0\r\nelement face 1\r\nproperty list uchar int vertex_indices\r\nelement vertex 2\r\nproperty double x\r\nproperty uchar red\r\nend_header\r\n".to_vec();
    b.push(3);
    for i in [0i32, 1, 0] {
        b.extend_from_slice(&i.to_le_bytes());
    }
    for (x, r) in [(1.5f64, 7u8), (-2.0, 255)] {
        b.extend_from_slice(&x.to_le_bytes());
        b.push(r);
    }
    let r = parse_ply(&b).unwrap();
    assert_eq!(r.count, 2);
    assert_eq!(r.column("x"), Some(&PlyColumn::Double(vec![1.5, -2.0])));
    assert_eq!(r.int("red").unwrap(), &[7, 255]);
}
