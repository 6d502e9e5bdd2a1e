//! The streamed frame writer (`rtmpm_io::stream`) against the whole-frame writers: the
//! same bytes, from the CPU backend's export and from particles on the host.

mod common;

use common::cpu::CpuBackend;
use rtmpm_io::FrameFields;
use rtmpm_io::chunks::{FrameChunk, FrameColumns};
use rtmpm_io::frame::Frame;
use rtmpm_io::stream::{Derived, FrameFiles, StreamFormat};
use rtmpm_io::testing::TestDir;
use rtmpm_scene::Scene;
use rtmpm_sim::{Backend, ChunkSink, Particles, SimError, export_particles};
use std::fs;
use std::path::PathBuf;

/// Collects the chunks in memory, `cap` particles each.
struct VecSink {
    cols: FrameColumns,
    cap: usize,
    chunks: Vec<FrameChunk>,
}

impl ChunkSink for VecSink {
    fn columns(&self) -> FrameColumns {
        self.cols
    }
    fn take(&mut self) -> Result<FrameChunk, SimError> {
        Ok(FrameChunk {
            start: 0,
            len: 0,
            cap: self.cap,
            cols: self.cols,
            buf: Box::new(vec![0u32; self.cap * self.cols.words()]),
        })
    }
    fn put(&mut self, chunk: FrameChunk) -> Result<(), SimError> {
        self.chunks.push(chunk);
        Ok(())
    }
}

const SCENE: &str = r#"
name = "stream"
[domain]
min = [0.0, 0.0, 0.0]
max = [1.0, 1.0, 1.0]
dx = 0.03125
[time]
duration = 0.1
fps = 10
[[material]]
name = "water"
type = "fluid"
density = 1000.0
bulk_modulus = 1e4
[[material]]
name = "sand"
type = "drucker_prager"
density = 1600.0
youngs_modulus = 3.5e5
poisson_ratio = 0.3
friction_angle = 30.0
[[material]]
name = "jelly"
type = "fixed_corotated"
density = 1000.0
youngs_modulus = 1.5e5
poisson_ratio = 0.3
[[body]]
material = "water"
shape = "box"
min = [0.1, 0.1, 0.1]
max = [0.4, 0.5, 0.4]
[[body]]
material = "sand"
shape = "box"
min = [0.55, 0.1, 0.1]
max = [0.8, 0.4, 0.4]
[[body]]
material = "jelly"
shape = "sphere"
center = [0.5, 0.7, 0.6]
radius = 0.12
"#;

/// A CPU backend after some steps: the storage is re-sorted, F, C and the plastic state are
/// not trivial.
fn stepped_backend() -> (Scene, CpuBackend) {
    let scene = Scene::from_toml(SCENE, "stream test").expect("scene");
    let p = scene.sample_particles().expect("particles");
    let mut b = CpuBackend::new(&scene, p, Some(2)).expect("backend");
    for s in 0..30 {
        b.step(5e-4, s as f32 * 5e-4).expect("step");
    }
    (scene, b)
}

/// Every format of the registry that can be streamed (PLY, BGEO and BGEO.gz at least), with
/// a run comment.
fn formats() -> Vec<StreamFormat> {
    let f: Vec<StreamFormat> = rtmpm_io::FRAME_FORMATS
        .iter()
        .filter_map(|f| StreamFormat::new(f, vec![COMMENT.into()]))
        .collect();
    let names: Vec<&str> = f.iter().map(|f| f.format.name).collect();
    for name in ["ply", "bgeo", "bgeo.gz"] {
        assert!(names.contains(&name), "{name} not streamable: {names:?}");
    }
    f
}

const COMMENT: &str = "rtmpm-run test 1234";

/// Write `p` both ways with `derived` and compare the files byte for byte; `chunks` comes
/// from `export`.
fn compare(
    d: &TestDir,
    tag: &str,
    scene: &Scene,
    p: &Particles,
    derived: Derived,
    chunks: &[FrameChunk],
) {
    let stress = derived
        .stress
        .then(|| common::physics32::material::cauchy_stress(p, &scene.materials));
    let jac = derived
        .jacobian
        .then(|| p.f.iter().map(|f| f.determinant()).collect::<Vec<f32>>());
    let fields = FrameFields {
        stress: stress.as_deref(),
        jacobian: jac.as_deref(),
    };
    let models = scene.materials.iter().map(|m| m.model.clone()).collect();
    let formats = formats();
    let files: Vec<(PathBuf, StreamFormat)> = formats
        .iter()
        .map(|f| {
            let name = format!("{tag}_stream.{}", f.format.extension);
            (d.path(&name), f.clone())
        })
        .collect();
    let mut ff = FrameFiles::create(&files, p.len(), derived, models).expect("create");
    for c in chunks {
        ff.write_chunk(c).expect("chunk");
    }
    ff.finish().expect("finish");
    // Each format's whole-frame writer, as the run writes frames without streaming.
    let frame = Frame {
        particles: p,
        fields,
        comments: &[COMMENT],
        bodies: &[],
        compress: true,
    };
    for ((path, _), f) in files.iter().zip(&formats) {
        let ext = f.format.extension;
        let reference = d.path(&format!("{tag}_ref.{ext}"));
        (f.format.write)(&reference, &frame).expect("whole frame");
        let (a, b) = (
            fs::read(path).expect("read"),
            fs::read(&reference).expect("read"),
        );
        assert!(a.len() > 100, "{ext}: {} bytes", a.len());
        assert!(
            a == b,
            "{tag}: {ext} differs ({} vs {} bytes)",
            a.len(),
            b.len()
        );
    }
}

/// The CPU backend's export (gathered from its sorted storage) in chunks of 1000, written
/// streamed, gives the files the whole-frame writers give for `read_particles`.
#[test]
fn cpu_backend_frames_are_byte_identical() {
    let d = TestDir::new("stream-cpu");
    let (scene, mut b) = stepped_backend();
    let mut p = Particles::default();
    b.read_particles(&mut p).expect("read");
    assert!(p.len() > 3000, "{} particles", p.len());
    // Stored order differs from the original order after the steps (the test would prove
    // nothing about the gather otherwise).
    assert!(b.ids.iter().enumerate().any(|(i, &id)| id as usize != i));
    for (tag, derived) in [
        ("plain", Derived::default()),
        (
            "fields",
            Derived {
                jacobian: true,
                stress: true,
            },
        ),
    ] {
        let cols = FrameFiles::columns(&formats(), derived);
        let mut sink = VecSink {
            cols,
            cap: 1000,
            chunks: vec![],
        };
        b.export_frame(&mut sink).expect("export");
        assert_eq!(sink.chunks.len(), p.len().div_ceil(1000));
        compare(&d, tag, &scene, &p, derived, &sink.chunks);
    }
}

/// The default export (from `Particles`) with one chunk and with chunks of one particle.
#[test]
fn host_export_in_any_chunk_size_is_byte_identical() {
    let d = TestDir::new("stream-host");
    let (scene, mut b) = stepped_backend();
    let mut p = Particles::default();
    b.read_particles(&mut p).expect("read");
    p.x.truncate(200);
    p.v.truncate(200);
    p.c.truncate(200);
    p.f.truncate(200);
    p.plastic.truncate(200);
    p.mass.truncate(200);
    p.vol0.truncate(200);
    p.material.truncate(200);
    let derived = Derived {
        jacobian: true,
        stress: false,
    };
    for cap in [1, 7, 200, 4096] {
        let mut sink = VecSink {
            cols: FrameColumns::all(),
            cap,
            chunks: vec![],
        };
        export_particles(&p, &mut sink).expect("export");
        compare(&d, &format!("cap{cap}"), &scene, &p, derived, &sink.chunks);
    }
}

/// A file that cannot be created is an error naming it; an incomplete frame is an error and
/// leaves no file, temporary or final.
#[test]
fn errors_name_the_file_and_leave_nothing() {
    let d = TestDir::new("stream-err");
    let blocker = d.path("not_a_dir");
    fs::write(&blocker, b"x").expect("write");
    let bad = blocker.join("frame_00001.ply");
    let fmt = StreamFormat::new(&rtmpm_io::ply::FORMAT, vec![]).expect("streamable");
    let err = FrameFiles::create(&[(bad.clone(), fmt.clone())], 3, Derived::default(), vec![])
        .err()
        .expect("must fail");
    assert_eq!(err.0, bad);

    let good = d.path("frame_00002.ply");
    let files =
        FrameFiles::create(&[(good.clone(), fmt)], 3, Derived::default(), vec![]).expect("create");
    let err = files.finish().expect_err("incomplete frame must fail");
    assert_eq!(err.0, good);
    assert!(err.1.to_string().contains("0 of 3"), "{}", err.1);
    let left: Vec<_> = fs::read_dir(&d.0)
        .expect("dir")
        .map(|e| e.expect("entry").file_name())
        .collect();
    assert_eq!(left, vec![std::ffi::OsString::from("not_a_dir")]);
}

/// Chunks larger than the encoder's block (several blocks per chunk, a partial last block
/// and chunk): still the same bytes.
#[test]
fn chunks_of_several_encoder_blocks_are_byte_identical() {
    let d = TestDir::new("stream-blocks");
    let (scene, _) = stepped_backend();
    let n = 300_001;
    assert!(200_000 > rtmpm_io::stream::BLOCK && n - 200_000 < rtmpm_io::stream::BLOCK);
    let mut p = Particles::default();
    for i in 0..n {
        let f = i as f32;
        p.push(
            glam::Vec3::new(f * 1e-6, 0.5 - f * 1e-7, 0.25),
            glam::Vec3::new(f, -1.0, 2.0 + f * 1e-3),
            1.0 + f * 1e-6,
            1e-6 * (1.0 + (i % 7) as f32),
            (i % 3) as u32,
            (i % 5) as f32 * 0.1,
        );
    }
    let mut sink = VecSink {
        cols: FrameColumns::all(),
        cap: 200_000,
        chunks: vec![],
    };
    export_particles(&p, &mut sink).expect("export");
    assert_eq!(sink.chunks.len(), 2);
    let derived = Derived {
        jacobian: true,
        stress: false,
    };
    compare(&d, "blocks", &scene, &p, derived, &sink.chunks);
}
