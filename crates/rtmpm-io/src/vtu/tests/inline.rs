use crate::bgeo::symmetric_to_full;
use crate::fields::FrameFields;
use crate::vtu::inline::decode_binary;
use crate::vtu::*;
use base64::Engine;
use base64::engine::general_purpose::STANDARD;
use rtmpm_physics::Particles;
use std::fs;
use std::path::{Path, PathBuf};

/// The inline form of the one writer (the form [`read_vtu`] reads).
fn write_vtu(path: &Path, p: &Particles, fields: &FrameFields) -> std::io::Result<()> {
    write_particles_vtu(path, p, fields, Encoding::Inline)
}
use crate::ply::write_ply;
use crate::testing::TestDir;
use rtmpm_physics::math::Vec3;

fn sample(n: usize) -> Particles {
    let mut p = Particles::default();
    for i in 0..n {
        let f = i as f32;
        p.push(
            Vec3::new(f, 0.5 * f, -f),
            Vec3::new(0.1 * f, -1.0, 3.0),
            1.0 + f,
            1e-6,
            (i % 4) as u32,
            f * 0.01,
        );
    }
    p
}

fn f32s(a: &VtuArray) -> &[f32] {
    match &a.values {
        VtuValues::Float32(v) => v,
        other => panic!("not Float32: {other:?}"),
    }
}

#[test]
fn round_trip_points_and_point_data() {
    let d = TestDir::new("vtu");
    let n = 23;
    let p = sample(n);
    let j: Vec<f32> = (0..n).map(|i| 1.0 - i as f32 * 1e-3).collect();
    let s: Vec<[f32; 6]> = (0..n)
        .map(|i| [i as f32, 1.0, 2.0, 3.0, 4.0, -(i as f32)])
        .collect();
    let fields = FrameFields {
        stress: Some(&s),
        jacobian: Some(&j),
    };
    let path = d.path("out/frame_0001.vtu");
    write_vtu(&path, &p, &fields).unwrap();
    let r = read_vtu(&path).unwrap();
    assert_eq!(r.num_points, n);
    assert_eq!(r.num_cells, n);
    let pts: Vec<[f32; 3]> = p.x.iter().map(|x| x.to_array()).collect();
    assert_eq!(r.points, pts);
    let names: Vec<&str> = r.point_data.iter().map(|a| a.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "velocity", "material", "id", "plastic", "mass", "J", "stress"
        ]
    );

    let vel = r.point_array("velocity").unwrap();
    assert_eq!(vel.num_components, 3);
    let v: Vec<f32> = p.v.iter().flat_map(|v| v.to_array()).collect();
    assert_eq!(f32s(vel), v.as_slice());
    let mats: Vec<i32> = p.material.iter().map(|&m| m as i32).collect();
    assert_eq!(
        r.point_array("material").unwrap().values,
        VtuValues::Int32(mats)
    );
    assert_eq!(
        f32s(r.point_array("plastic").unwrap()),
        p.plastic.as_slice()
    );
    assert_eq!(f32s(r.point_array("mass").unwrap()), p.mass.as_slice());
    assert_eq!(f32s(r.point_array("J").unwrap()), j.as_slice());
    let st = r.point_array("stress").unwrap();
    assert_eq!(st.num_components, 9);
    let flat: Vec<f32> = s.iter().flat_map(|s| symmetric_to_full(*s)).collect();
    assert_eq!(f32s(st), flat.as_slice());

    // Cells: one vertex per particle.
    let types = r.cells.iter().find(|a| a.name == "types").unwrap();
    assert_eq!(types.values, VtuValues::UInt8(vec![1; n]));
    let offsets = r.cells.iter().find(|a| a.name == "offsets").unwrap();
    assert_eq!(offsets.values, VtuValues::Int64((1..=n as i64).collect()));
}

#[test]
fn minimal_fields_and_empty() {
    let d = TestDir::new("vtu-min");
    let path = d.path("a.vtu");
    write_vtu(&path, &sample(2), &FrameFields::default()).unwrap();
    let r = read_vtu(&path).unwrap();
    assert_eq!(r.point_data.len(), 5);
    assert!(r.point_array("stress").is_none());

    write_vtu(&path, &Particles::default(), &FrameFields::default()).unwrap();
    let r = read_vtu(&path).unwrap();
    assert_eq!(r.num_points, 0);
    assert!(r.points.is_empty());
}

#[test]
fn header_encoded_separately() {
    // The base64 header of 8 bytes ends with one '=' and is followed by the data.
    let d = TestDir::new("vtu-hdr");
    let path = d.path("a.vtu");
    write_vtu(&path, &sample(1), &FrameFields::default()).unwrap();
    let text = fs::read_to_string(&path).unwrap();
    // Points: 12 bytes -> header "DAAAAAAAAAA=" (12 as u64 LE).
    assert!(text.contains("DAAAAAAAAAA="), "{text}");
    // Joint encoding is also accepted by the reader.
    let mut joint = 12u64.to_le_bytes().to_vec();
    joint.extend_from_slice(&[0u8; 12]);
    assert_eq!(
        decode_binary(&STANDARD.encode(&joint)).unwrap(),
        vec![0u8; 12]
    );
    assert!(decode_binary("DAAAAAAAAAA=AAAA").is_err());
}

/// Writes a small `.pvd` + `.vtu` sequence. With `RTMPM_IO_EXAMPLE_DIR=dir` the files are
/// written (and kept) there, for checking with `scripts/check_vtu.py dir/particles.pvd`.
#[test]
fn example_sequence_for_external_readers() {
    let tmp = TestDir::new("vtu-example");
    let dir = std::env::var_os("RTMPM_IO_EXAMPLE_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| tmp.0.clone());
    let n = 100;
    let mut p = sample(n);
    let j = vec![1.0f32; n];
    let s = vec![[1.0f32, 2.0, 3.0, 0.1, 0.2, 0.3]; n];
    let mut pvd = PvdWriter::new(dir.join("particles.pvd")).unwrap();
    for frame in 0..3 {
        for x in p.x.iter_mut() {
            x.y -= 0.01;
        }
        let name = format!("frames/frame_{frame:04}.vtu");
        let fields = FrameFields {
            stress: (frame > 0).then_some(s.as_slice()),
            jacobian: Some(&j),
        };
        write_vtu(&dir.join(&name), &p, &fields).unwrap();
        write_ply(
            &dir.join(format!("frames/frame_{frame:04}.ply")),
            &p,
            &fields,
        )
        .unwrap();
        pvd.add(frame as f64 / 24.0, &name).unwrap();
    }
    let r = read_vtu(&dir.join("frames/frame_0002.vtu")).unwrap();
    assert_eq!(r.num_points, n);
    assert_eq!(pvd.entries().len(), 3);
}

#[test]
fn pvd_add_and_resume() {
    let d = TestDir::new("pvd");
    let path = d.path("run/particles.pvd");
    let mut w = PvdWriter::new(&path).unwrap();
    for (i, t) in [0.0, 0.1, 0.2, 0.30000000000000004].into_iter().enumerate() {
        w.add(t, &format!("frames/frame_{i:04}.vtu")).unwrap();
    }
    let text = fs::read_to_string(&path).unwrap();
    assert!(text.contains("timestep=\"0.30000000000000004\""));
    assert_eq!(parse_pvd(&text).unwrap().len(), 4);

    let mut r = PvdWriter::resume(&path, 0.2).unwrap();
    assert_eq!(
        r.entries(),
        [
            (0.0, "frames/frame_0000.vtu".to_string()),
            (0.1, "frames/frame_0001.vtu".to_string())
        ]
    );
    // The file on disk is trimmed at once.
    assert_eq!(
        parse_pvd(&fs::read_to_string(&path).unwrap())
            .unwrap()
            .len(),
        2
    );
    r.add(0.2, "a&b \"q\".vtu").unwrap();
    let back = PvdWriter::resume(&path, f64::INFINITY).unwrap();
    assert_eq!(back.entries()[2], (0.2, "a&b \"q\".vtu".to_string()));

    // Missing file: empty collection.
    let fresh = PvdWriter::resume(d.path("none.pvd"), 1.0).unwrap();
    assert!(fresh.entries().is_empty());
    assert!(d.path("none.pvd").exists());

    // A file that is not a collection is an error.
    fs::write(d.path("bad.pvd"), "hello").unwrap();
    assert!(PvdWriter::resume(d.path("bad.pvd"), 1.0).is_err());
}
