//! Our BGEO files read by an independent reader, splashsurf_lib's (cargo feature `interop`,
//! on in CI's interop step): every value compared.
//!
//! splashsurf's reader reads one value per point for float attributes whatever their size, so
//! it cannot read the 9-float `stress` as Houdini declares it (float, size 9); the stress
//! bytes are checked by declaring the same bytes a 9-component vector, which it reads.
//! With `RTMPM_INTEROP_DIR=DIR`, every `frame_*.bgeo(.gz)` in DIR (a run's output) is read too
//! and compared with the run's PLY of the same frame.

use super::bgeo::tests::sample;
use super::bgeo::{symmetric_to_full, write_bgeo};
use super::ply::read_ply;
use crate::fields::FrameFields;
use crate::testing::TestDir;
use splashsurf_lib::io::bgeo_format::{AttributeStorage, BgeoFile, load_bgeo_file};
use std::path::Path;

fn floats<'a>(f: &'a BgeoFile, name: &str) -> &'a [f32] {
    match f.attribute_data.iter().find(|(n, _)| n == name) {
        Some((_, AttributeStorage::Float(v))) | Some((_, AttributeStorage::Vector(_, v))) => v,
        other => panic!("{name}: {other:?}"),
    }
}

fn ints<'a>(f: &'a BgeoFile, name: &str) -> &'a [i32] {
    match f.attribute_data.iter().find(|(n, _)| n == name) {
        Some((_, AttributeStorage::Int(v))) => v,
        other => panic!("{name}: {other:?}"),
    }
}

fn positions(f: &BgeoFile) -> &[f32] {
    match &f.positions {
        AttributeStorage::Vector(3, v) => v,
        other => panic!("positions: {other:?}"),
    }
}

/// Declare the `stress` attribute (float, size 9) a vector of 9; false when there is none.
fn patch_stress(b: &mut [u8]) -> bool {
    let Some(at) = b.windows(8).position(|w| w == b"\0\x06stress") else {
        return false;
    };
    let def = at + 8;
    assert_eq!(&b[def..def + 6], &[0, 9, 0, 0, 0, 0], "size 9, type float");
    b[def + 5] = 5;
    true
}

#[test]
fn splashsurf_reads_every_value() {
    let d = TestDir::new("interop-bgeo");
    let n = 321;
    let p = sample(n);
    let j: Vec<f32> = (0..n).map(|i| 1.0 - i as f32 * 1e-3).collect();
    for gz in [false, true] {
        let path = d.path(if gz { "a.bgeo.gz" } else { "a.bgeo" });
        let fields = FrameFields {
            stress: None,
            jacobian: Some(&j),
        };
        write_bgeo(&path, &p, &fields, gz).unwrap();
        let f = load_bgeo_file(&path).unwrap();
        assert_eq!(f.header.num_points as usize, n);
        let x: Vec<f32> = p.x.iter().flat_map(|x| x.to_array()).collect();
        assert_eq!(positions(&f), x.as_slice());
        assert!(matches!(&f.weights, AttributeStorage::Float(w) if w.iter().all(|&w| w == 1.0)));
        let names: Vec<&str> = f
            .attribute_definitions
            .iter()
            .map(|a| a.name.as_str())
            .collect();
        assert_eq!(
            names,
            ["v", "id", "material", "plastic", "mass", "pscale", "J"]
        );
        let v: Vec<f32> = p.v.iter().flat_map(|v| v.to_array()).collect();
        assert_eq!(floats(&f, "v"), v.as_slice());
        assert_eq!(ints(&f, "id"), (0..n as i32).collect::<Vec<_>>().as_slice());
        let m: Vec<i32> = p.material.iter().map(|&m| m as i32).collect();
        assert_eq!(ints(&f, "material"), m.as_slice());
        assert_eq!(floats(&f, "plastic"), p.plastic.as_slice());
        assert_eq!(floats(&f, "mass"), p.mass.as_slice());
        let ps: Vec<f32> = p.vol0.iter().map(|v| 0.5 * v.cbrt()).collect();
        assert_eq!(floats(&f, "pscale"), ps.as_slice());
        assert_eq!(floats(&f, "J"), j.as_slice());
    }
    // The stress: the same file with the attribute's type code 0 (float) patched to 5
    // (vector), which splashsurf reads component by component.
    let s: Vec<[f32; 6]> = (0..n)
        .map(|i| [i as f32, -2.0, 3.5, 1e4 * i as f32, -0.25, 7.0])
        .collect();
    let path = d.path("s.bgeo");
    let fields = FrameFields {
        stress: Some(&s),
        jacobian: None,
    };
    write_bgeo(&path, &p, &fields, false).unwrap();
    let mut b = std::fs::read(&path).unwrap();
    assert!(patch_stress(&mut b));
    std::fs::write(&path, &b).unwrap();
    let f = load_bgeo_file(&path).unwrap();
    let full: Vec<f32> = s.iter().flat_map(|s| symmetric_to_full(*s)).collect();
    assert_eq!(floats(&f, "stress"), full.as_slice());
    assert_eq!(floats(&f, "v").len(), 3 * n);
}

/// A run's BGEO frames against its PLY frames (both written by `rtmpm run`).
#[test]
fn run_output_bgeo_matches_its_ply() {
    let Some(dir) = std::env::var_os("RTMPM_INTEROP_DIR") else {
        return;
    };
    let tmp = TestDir::new("interop-run");
    let mut checked = 0;
    for e in std::fs::read_dir(&dir).unwrap() {
        let path = e.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let Some(stem) = name
            .strip_suffix(".bgeo.gz")
            .or_else(|| name.strip_suffix(".bgeo"))
        else {
            continue;
        };
        let ply = read_ply(&Path::new(&dir).join(format!("{stem}.ply"))).unwrap();
        // splashsurf reads `stress` only declared as a vector (see the module doc): a patched
        // copy (gzip decompressed here with flate2; the gzip container itself
        // is checked by check_formats.py) is read when the frame has one.
        let mut bytes = std::fs::read(&path).unwrap();
        if name.ends_with(".gz") {
            let mut out = Vec::new();
            std::io::Read::read_to_end(&mut flate2::read::GzDecoder::new(&bytes[..]), &mut out)
                .unwrap();
            bytes = out;
        }
        let has_stress = patch_stress(&mut bytes);
        let copy = tmp.path(&format!("{name}.bgeo"));
        std::fs::write(&copy, &bytes).unwrap();
        let f = load_bgeo_file(&copy).unwrap();
        if has_stress {
            let st = floats(&f, "stress");
            for (k, c) in ["sxx", "syy", "szz", "sxy", "syz", "sxz"]
                .into_iter()
                .enumerate()
            {
                let (r, col) = [(0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2)][k];
                let want = ply.f32(c).unwrap();
                for i in 0..ply.count {
                    assert_eq!(st[9 * i + 3 * r + col], want[i], "{name} {c}");
                    assert_eq!(st[9 * i + 3 * col + r], want[i], "{name} {c} (symmetric)");
                }
            }
        }
        let xyz = positions(&f);
        for (k, c) in ["x", "y", "z"].into_iter().enumerate() {
            let col = ply.f32(c).unwrap();
            assert!(
                col.iter().enumerate().all(|(i, &v)| xyz[3 * i + k] == v),
                "{name} {c}"
            );
        }
        let v = floats(&f, "v");
        for (k, c) in ["vx", "vy", "vz"].into_iter().enumerate() {
            let col = ply.f32(c).unwrap();
            assert!(
                col.iter().enumerate().all(|(i, &x)| v[3 * i + k] == x),
                "{name} {c}"
            );
        }
        let m: Vec<i64> = ints(&f, "material").iter().map(|&m| m as i64).collect();
        assert_eq!(ply.int("material").unwrap(), m.as_slice());
        assert_eq!(ply.f32("plastic").unwrap(), floats(&f, "plastic"));
        if let Some(j) = ply.f32("J") {
            assert_eq!(j, floats(&f, "J"));
        }
        println!("interop ok {}: {} points", path.display(), ply.count);
        checked += 1;
    }
    assert!(checked > 0, "no .bgeo files in {}", dir.to_string_lossy());
}
