use crate::bgeo::symmetric_to_full;
use crate::bgeo::tests::sample;
use crate::fields::FrameFields;
use crate::testing::TestDir;
use crate::vtu::appended::parse_appended;
use crate::vtu::*;
use crate::vtu::{VtuArray, VtuValues};
use rtmpm_physics::Particles;
use std::fs;

fn f32s(a: &VtuArray) -> &[f32] {
    match &a.values {
        VtuValues::Float32(v) => v,
        other => panic!("not Float32: {other:?}"),
    }
}

#[test]
fn particle_frame_round_trip_compressed_and_raw() {
    let d = TestDir::new("vtk-app");
    // Enough particles for several 32 KiB blocks per array.
    let n = 5000;
    let p = sample(n);
    let j: Vec<f32> = (0..n).map(|i| 1.0 + i as f32 * 1e-4).collect();
    let s: Vec<[f32; 6]> = (0..n)
        .map(|i| [i as f32, 1.0, 2.0, 3.0, 4.0, -(i as f32)])
        .collect();
    let fields = FrameFields {
        stress: Some(&s),
        jacobian: Some(&j),
    };
    for compress in [true, false] {
        let path = d.path(&format!("f{compress}.vtu"));
        write_particles_vtu(&path, &p, &fields, Encoding::appended(compress)).unwrap();
        let text = fs::read(&path).unwrap();
        let head = String::from_utf8_lossy(&text[..2000.min(text.len())]).into_owned();
        assert_eq!(head.contains("vtkZLibDataCompressor"), compress);
        assert!(head.contains("Tensors=\"stress\"") && head.contains("Vectors=\"velocity\""));
        let r = read_any_vtu(&path).unwrap();
        assert_eq!((r.num_points, r.num_cells), (n, n));
        let pts: Vec<[f32; 3]> = p.x.iter().map(|x| x.to_array()).collect();
        assert_eq!(r.points, pts);
        let names: Vec<&str> = r.point_data.iter().map(|a| a.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "velocity", "material", "id", "plastic", "mass", "J", "stress"
            ]
        );
        let v: Vec<f32> = p.v.iter().flat_map(|v| v.to_array()).collect();
        assert_eq!(f32s(r.point_array("velocity").unwrap()), v.as_slice());
        let mats: Vec<i32> = p.material.iter().map(|&m| m as i32).collect();
        assert_eq!(
            r.point_array("material").unwrap().values,
            VtuValues::Int32(mats)
        );
        assert_eq!(
            r.point_array("id").unwrap().values,
            VtuValues::Int32((0..n as i32).collect())
        );
        assert_eq!(
            f32s(r.point_array("plastic").unwrap()),
            p.plastic.as_slice()
        );
        assert_eq!(f32s(r.point_array("mass").unwrap()), p.mass.as_slice());
        assert_eq!(f32s(r.point_array("J").unwrap()), j.as_slice());
        let st = r.point_array("stress").unwrap();
        assert_eq!(st.num_components, 9);
        let full: Vec<f32> = s.iter().flat_map(|s| symmetric_to_full(*s)).collect();
        assert_eq!(f32s(st), full.as_slice());
        let types = r.cells.iter().find(|a| a.name == "types").unwrap();
        assert_eq!(types.values, VtuValues::UInt8(vec![1; n]));
    }
    // Compression pays: the compressed file is smaller.
    let (a, b) = (
        fs::metadata(d.path("ftrue.vtu")).unwrap().len(),
        fs::metadata(d.path("ffalse.vtu")).unwrap().len(),
    );
    assert!(a < b, "{a} vs {b}");
}

#[test]
fn empty_frame_and_triangles() {
    let d = TestDir::new("vtk-app-tri");
    let path = d.path("e.vtu");
    write_particles_vtu(
        &path,
        &Particles::default(),
        &FrameFields::default(),
        Encoding::Zlib,
    )
    .unwrap();
    let r = read_any_vtu(&path).unwrap();
    assert_eq!(r.num_points, 0);
    let path = d.path("t.vtu");
    let pts = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let tris = [[0, 2, 1], [0, 1, 3]];
    // Every encoding of the one writer reads back the same.
    for encoding in [Encoding::Zlib, Encoding::Raw, Encoding::Inline] {
        let normals = OutArray::f32("Normals", 3, (0..12).map(|i| i as f32));
        write_unstructured(
            &path,
            &pts,
            CellKind::Triangles,
            &tris,
            &[normals],
            &[("Normals", "Normals")],
            encoding,
        )
        .unwrap();
        let r = read_any_vtu(&path).unwrap();
        assert_eq!((r.num_points, r.num_cells), (4, 2), "{encoding:?}");
        assert_eq!(r.points, pts, "{encoding:?}");
        let conn = r.cells.iter().find(|a| a.name == "connectivity").unwrap();
        assert_eq!(conn.values, VtuValues::Int64(vec![0, 2, 1, 0, 1, 3]));
        let off = r.cells.iter().find(|a| a.name == "offsets").unwrap();
        assert_eq!(off.values, VtuValues::Int64(vec![3, 6]));
        let normals = r.point_array("Normals").unwrap();
        assert_eq!(f32s(normals), (0..12).map(|i| i as f32).collect::<Vec<_>>());
    }
    // A wrong array length is refused before anything is written.
    let short = OutArray::f32("x", 1, [1.0].into_iter());
    assert!(
        write_unstructured(
            &d.path("bad.vtu"),
            &pts,
            CellKind::Vertices,
            &[],
            &[short],
            &[],
            Encoding::Raw
        )
        .is_err()
    );
    assert!(!d.path("bad.vtu").exists());
}

#[test]
fn corrupt_files_give_errors() {
    let d = TestDir::new("vtk-app-bad");
    let path = d.path("f.vtu");
    write_particles_vtu(
        &path,
        &sample(3000),
        &FrameFields::default(),
        Encoding::Zlib,
    )
    .unwrap();
    let good = fs::read(&path).unwrap();
    let err = |b: &[u8]| parse_appended(b).unwrap_err().to_string();
    // Truncated anywhere in the binary part.
    let app = good
        .windows(13)
        .position(|w| w == b"<AppendedData")
        .unwrap();
    let us = app + good[app..].iter().position(|&c| c == b'_').unwrap() + 1;
    for cut in [us, us + 30, good.len() / 2, good.len() - 40] {
        let e = err(&good[..cut]);
        assert!(e.contains("truncated") || e.contains("zlib"), "{e}");
    }
    // A hostile block count / size in the first array's header.
    let mut h = good.clone();
    h[us..us + 8].copy_from_slice(&u64::MAX.to_le_bytes());
    assert!(err(&h).contains("past the end"), "{}", err(&h));
    let mut h = good.clone();
    h[us + 8..us + 16].copy_from_slice(&(1u64 << 40).to_le_bytes());
    h[us + 16..us + 24].copy_from_slice(&(1u64 << 40).to_le_bytes());
    assert!(err(&h).contains("corrupt header"), "{}", err(&h));
    // Damaged zlib data.
    let mut z = good.clone();
    let nblocks = u64::from_le_bytes(good[us..us + 8].try_into().unwrap()) as usize;
    assert_eq!(nblocks, 2); // 3000 x 12 bytes of points.
    let first_block = us + 8 * (3 + nblocks);
    for b in &mut z[first_block..first_block + 16] {
        *b ^= 0x5a;
    }
    assert!(
        err(&z).contains("zlib") || err(&z).contains("holds"),
        "{}",
        err(&z)
    );
    // Not appended at all / other encodings / compressors.
    assert!(err(b"<VTKFile type=\"UnstructuredGrid\">").contains("AppendedData"));
    let b64 = String::from_utf8_lossy(&good).replace("encoding=\"raw\"", "encoding=\"base64\"");
    assert!(err(b64.as_bytes()).contains("base64"));
    let lz4 = String::from_utf8_lossy(&good[..us])
        .replace("vtkZLibDataCompressor", "vtkLZ4DataCompressor");
    let e = err(lz4.as_bytes());
    assert!(e.contains("vtkLZ4DataCompressor"), "{e}");
}
