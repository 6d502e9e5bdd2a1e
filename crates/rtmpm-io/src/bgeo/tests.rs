use super::*;
use crate::testing::TestDir;
use rtmpm_physics::math::Vec3;
use std::fs;

pub(crate) fn sample(n: usize) -> Particles {
    let mut p = Particles::default();
    for i in 0..n {
        let f = i as f32;
        p.push(
            Vec3::new(f * 0.5, -f, f * f * 1e-3),
            Vec3::new(1.0 + f, 2.0, -3.0 * f),
            0.25 + f,
            1e-6 * (1.0 + f),
            (i % 3) as u32,
            0.1 * f,
        );
    }
    p
}

fn fields_for(n: usize) -> (Vec<f32>, Vec<[f32; 6]>) {
    let j = (0..n).map(|i| 1.0 + i as f32 * 0.01).collect();
    let s = (0..n)
        .map(|i| {
            let f = i as f32;
            [f, -f, 2.0 * f, 0.5 + f, -0.5, 1e5 * f]
        })
        .collect();
    (j, s)
}

#[test]
fn round_trip_plain_and_gzip() {
    let d = TestDir::new("bgeo");
    let n = 37;
    let p = sample(n);
    let (j, s) = fields_for(n);
    let fields = FrameFields {
        stress: Some(&s),
        jacobian: Some(&j),
    };
    for (name, gz) in [("f.bgeo", false), ("f.bgeo.gz", true)] {
        let path = d.path(name);
        write_bgeo(&path, &p, &fields, gz).unwrap();
        let bytes = fs::read(&path).unwrap();
        assert_eq!(bytes.starts_with(&[0x1f, 0x8b]), gz);
        let r = read_bgeo(&path).unwrap();
        assert_eq!(r.positions.len(), n);
        let names: Vec<&str> = r.attributes.iter().map(|a| a.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "v", "id", "material", "plastic", "mass", "pscale", "J", "stress"
            ]
        );
        for i in 0..n {
            assert_eq!(r.positions[i], p.x[i].to_array());
        }
        let v: Vec<f32> = p.v.iter().flat_map(|v| v.to_array()).collect();
        assert_eq!(r.floats("v", 3).unwrap(), v.as_slice());
        assert_eq!(r.attribute("v").unwrap().ty, BgeoType::Vector);
        let ids: Vec<i32> = (0..n as i32).collect();
        assert_eq!(r.ints("id").unwrap(), ids.as_slice());
        let mats: Vec<i32> = p.material.iter().map(|&m| m as i32).collect();
        assert_eq!(r.ints("material").unwrap(), mats.as_slice());
        assert_eq!(r.floats("plastic", 1).unwrap(), p.plastic.as_slice());
        assert_eq!(r.floats("mass", 1).unwrap(), p.mass.as_slice());
        let ps: Vec<f32> = p.vol0.iter().map(|v| 0.5 * v.cbrt()).collect();
        assert_eq!(r.floats("pscale", 1).unwrap(), ps.as_slice());
        assert_eq!(r.floats("J", 1).unwrap(), j.as_slice());
        let st = r.floats("stress", 9).unwrap();
        for i in 0..n {
            let [xx, yy, zz, xy, yz, xz] = s[i];
            assert_eq!(&st[9 * i..9 * i + 9], &[xx, xy, xz, xy, yy, yz, xz, yz, zz]);
        }
    }
}

#[test]
fn exact_layout_of_a_tiny_file() {
    // One particle, no optional fields: the bytes the published layout prescribes.
    let d = TestDir::new("bgeo-layout");
    let mut p = Particles::default();
    p.push(
        Vec3::new(1.0, 2.0, 3.0),
        Vec3::new(-1.0, 0.5, 0.0),
        2.0,
        8.0,
        7,
        0.25,
    );
    let path = d.path("one.bgeo");
    write_bgeo(&path, &p, &FrameFields::default(), false).unwrap();
    let b = fs::read(&path).unwrap();
    let mut want: Vec<u8> = b"BgeoV".to_vec();
    for k in [5i32, 1, 0, 0, 0, 6, 0, 0, 0] {
        want.extend_from_slice(&k.to_be_bytes());
    }
    for (name, size, ty) in [
        ("v", 3u16, 5i32),
        ("id", 1, 1),
        ("material", 1, 1),
        ("plastic", 1, 0),
        ("mass", 1, 0),
        ("pscale", 1, 0),
    ] {
        want.extend_from_slice(&(name.len() as u16).to_be_bytes());
        want.extend_from_slice(name.as_bytes());
        want.extend_from_slice(&size.to_be_bytes());
        want.extend_from_slice(&ty.to_be_bytes());
        want.extend(std::iter::repeat_n(0u8, 4 * size as usize));
    }
    for x in [1.0f32, 2.0, 3.0, 1.0, -1.0, 0.5, 0.0] {
        want.extend_from_slice(&x.to_be_bytes());
    }
    want.extend_from_slice(&0i32.to_be_bytes());
    want.extend_from_slice(&7i32.to_be_bytes());
    for x in [0.25f32, 2.0, 1.0] {
        want.extend_from_slice(&x.to_be_bytes());
    }
    want.extend_from_slice(&[0x00, 0xff]);
    assert_eq!(b, want);
}

#[test]
fn empty_frame() {
    let d = TestDir::new("bgeo-empty");
    let path = d.path("e.bgeo");
    write_bgeo(&path, &Particles::default(), &FrameFields::default(), false).unwrap();
    let r = read_bgeo(&path).unwrap();
    assert!(r.positions.is_empty());
    assert_eq!(r.attributes.len(), 6);
}

fn header(n: i32, attrs: &[(&str, u16, i32)]) -> Vec<u8> {
    let mut b = b"BgeoV".to_vec();
    for k in [5i32, n, 0, 0, 0, attrs.len() as i32, 0, 0, 0] {
        b.extend_from_slice(&k.to_be_bytes());
    }
    for (name, size, ty) in attrs {
        b.extend_from_slice(&(name.len() as u16).to_be_bytes());
        b.extend_from_slice(name.as_bytes());
        b.extend_from_slice(&size.to_be_bytes());
        b.extend_from_slice(&ty.to_be_bytes());
        b.extend(std::iter::repeat_n(0u8, 4 * *size as usize));
    }
    b
}

#[test]
fn bad_files_give_errors_not_panics() {
    let err = |b: &[u8]| parse_bgeo(b).unwrap_err().to_string();
    assert!(err(b"").contains("ends inside the header"), "{}", err(b""));
    assert!(err(b"PLY\n and more bytes here").contains("magic"));
    assert!(err(&[0x7f, b'N', b'S', b'J', 1, 2, 3, 4, 5]).contains("JSON"));
    let mut v6 = header(0, &[]);
    v6[8] = 6;
    assert!(err(&v6).contains("version"), "{}", err(&v6));
    // A hostile count: 2^31 - 1 points with nothing behind them; no allocation, an error.
    let e = err(&header(i32::MAX, &[("v", 3, 5)]));
    assert!(e.contains("truncated"), "{e}");
    assert!(err(&header(-4, &[])).contains("negative"));
    // Truncated in the middle of the points.
    let mut t = header(2, &[("id", 1, 1)]);
    t.extend_from_slice(&[0u8; 20 + 7]);
    assert!(err(&t).contains("truncated"));
    // Attribute definitions cut short, string attributes, unknown types, zero sizes.
    let h = header(0, &[("density", 1, 0)]);
    assert!(err(&h[..h.len() - 3]).contains("definition of point attribute 0"));
    assert!(err(&header(0, &[("name", 1, 2)])).contains("string attributes"));
    assert!(err(&header(0, &[("x", 1, 9)])).contains("unknown attribute type 9"));
    assert!(err(&header(0, &[("x", 0, 0)])).contains("0 components"));
    // An indexed-string table longer than the file.
    let mut s = header(0, &[("name", 1, 4)]);
    s.extend_from_slice(&i32::MAX.to_be_bytes());
    assert!(err(&s).contains("string count"));
}

#[test]
fn reads_indexed_strings_and_ignores_trailing_sections() {
    let mut b = header(2, &[]);
    // Patch in one indexed-string attribute by hand (header() has no string table).
    b[4 + 1 + 4 + 4 * 4 + 3] = 1;
    b.extend_from_slice(&4u16.to_be_bytes());
    b.extend_from_slice(b"name");
    b.extend_from_slice(&1u16.to_be_bytes());
    b.extend_from_slice(&4i32.to_be_bytes());
    b.extend_from_slice(&0i32.to_be_bytes());
    b.extend_from_slice(&2i32.to_be_bytes());
    for s in ["water", "sand"] {
        b.extend_from_slice(&(s.len() as u16).to_be_bytes());
        b.extend_from_slice(s.as_bytes());
    }
    for (x, k) in [(1.0f32, 1i32), (2.0, 0)] {
        for c in [x, 0.0, 0.0, 1.0] {
            b.extend_from_slice(&c.to_be_bytes());
        }
        b.extend_from_slice(&k.to_be_bytes());
    }
    b.extend_from_slice(&[0x00, 0xff, 1, 2, 3]);
    let r = parse_bgeo(&b).unwrap();
    assert_eq!(r.positions, [[1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]);
    let a = r.attribute("name").unwrap();
    assert_eq!(a.strings, ["water", "sand"]);
    assert_eq!(a.values, BgeoValues::Int(vec![1, 0]));
}

#[test]
fn damaged_gzip_is_an_error() {
    let d = TestDir::new("bgeo-gz-bad");
    let path = d.path("f.bgeo.gz");
    write_bgeo(&path, &sample(100), &FrameFields::default(), true).unwrap();
    let mut b = fs::read(&path).unwrap();
    b.truncate(b.len() / 2);
    fs::write(&path, &b).unwrap();
    let e = read_bgeo(&path).unwrap_err().to_string();
    assert!(e.contains("gzip") || e.contains("truncated"), "{e}");
}
