//! Frames streamed from the GPU in chunks (`Backend::export_frame`) against the whole-frame path:
//! the same PLY, BGEO and BGEO.gz bytes for the same device state (needs a GPU; skips with a
//! message otherwise): `cargo test --release -p rtmpm-cuda --test frames -- --include-ignored
//! --nocapture`.

use rtmpm_cuda::{CudaBackend, CudaOptions, probe};
use rtmpm_driver::Simulation;
use rtmpm_io::chunks::{FrameChunk, FrameColumns};
use rtmpm_io::stream::{Derived, FrameFiles, StreamFormat};
use rtmpm_io::{FrameFields, bgeo, ply};
use rtmpm_physics::Particles;
use rtmpm_physics::material::cauchy_stress;
use rtmpm_scene::{Precision, Scene};
use rtmpm_sim::{Backend, ChunkSink, SimError};
use std::path::{Path, PathBuf};

/// Chunks of `cap` particles in the backend's own (page-locked) chunk memory, kept in order.
struct Keep {
    cols: FrameColumns,
    cap: usize,
    free: Vec<FrameChunk>,
    chunks: Vec<FrameChunk>,
}

impl ChunkSink for Keep {
    fn columns(&self) -> FrameColumns {
        self.cols
    }
    fn take(&mut self) -> Result<FrameChunk, SimError> {
        self.free
            .pop()
            .ok_or_else(|| SimError::Backend("test: out of chunks".into()))
    }
    fn put(&mut self, chunk: FrameChunk) -> Result<(), SimError> {
        assert_eq!(chunk.cap, self.cap);
        self.chunks.push(chunk);
        Ok(())
    }
}

fn formats() -> Vec<(&'static str, StreamFormat)> {
    ["ply", "bgeo", "bgeo.gz"]
        .into_iter()
        .map(|name| {
            let format = rtmpm_io::frame_format(name).expect("a registered format");
            let comments = vec!["rtmpm-run gpu test".into()];
            (
                name,
                StreamFormat::new(format, comments).expect("streamable"),
            )
        })
        .collect()
}

/// Export `b`'s state in chunks of `cap` and write it streamed; write `read_particles` whole;
/// the files must be equal byte for byte.
fn compare(dir: &Path, tag: &str, scene: &Scene, b: &mut CudaBackend, cap: usize) {
    let derived = Derived {
        jacobian: true,
        stress: true,
    };
    let fmts: Vec<StreamFormat> = formats().into_iter().map(|f| f.1).collect();
    let cols = FrameFiles::columns(&fmts, derived);
    let n = b.num_particles();
    let mut sink = Keep {
        cols,
        cap,
        free: (0..n.div_ceil(cap))
            .map(|_| FrameChunk {
                start: 0,
                len: 0,
                cap,
                cols,
                buf: b.chunk_memory(cap * cols.words()).expect("pinned"),
            })
            .collect(),
        chunks: vec![],
    };
    b.export_frame(&mut sink).expect("export");
    assert_eq!(sink.chunks.len(), n.div_ceil(cap));
    let files: Vec<(PathBuf, StreamFormat)> = formats()
        .into_iter()
        .map(|(ext, f)| (dir.join(format!("{tag}_stream.{ext}")), f))
        .collect();
    let models = scene.materials.iter().map(|m| m.model.clone()).collect();
    let mut ff = FrameFiles::create(&files, n, derived, models).expect("create");
    for c in &sink.chunks {
        ff.write_chunk(c).expect("chunk");
    }
    ff.finish().expect("finish");

    let mut p = Particles::default();
    b.read_particles(&mut p).expect("read");
    let stress = cauchy_stress(&p, &scene.materials);
    let jac: Vec<f32> = p.f.iter().map(|f| f.determinant()).collect();
    let fields = FrameFields {
        stress: Some(&stress),
        jacobian: Some(&jac),
    };
    let whole = |ext: &str| dir.join(format!("{tag}_whole.{ext}"));
    ply::write_ply_with_comments(&whole("ply"), &p, &fields, &["rtmpm-run gpu test"]).expect("ply");
    bgeo::write_bgeo(&whole("bgeo"), &p, &fields, false).expect("bgeo");
    bgeo::write_bgeo(&whole("bgeo.gz"), &p, &fields, true).expect("bgeo.gz");
    for (ext, _) in formats() {
        let a = std::fs::read(dir.join(format!("{tag}_stream.{ext}"))).expect("a");
        let w = std::fs::read(whole(ext)).expect("b");
        assert!(a.len() > 1000);
        assert!(
            a == w,
            "{tag}, chunks of {cap}: {ext} differs from the whole-frame file"
        );
    }
    println!("{tag}: {n} particles, chunks of {cap}: identical");
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn gpu_frames_streamed_in_chunks_are_byte_identical() {
    if let Err(e) = probe() {
        println!("skipped: no usable CUDA GPU ({e})");
        return;
    }
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("gpu-frames");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("dir");
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/mixed.toml");
    for precision in [Precision::F32, Precision::F64] {
        let mut scene = Scene::from_file(&path).unwrap_or_else(|e| panic!("{e}"));
        scene.precision = precision;
        let p0 = scene.sample_particles().expect("particles");
        let gpu = CudaBackend::new(&scene, &p0, CudaOptions::default()).expect("cuda");
        let mut sim = Simulation::with_backend(scene.clone(), Box::new(gpu));
        // After some steps the slots are sorted (not in original order), F, C and the plastic
        // state are not trivial.
        sim.advance_frame().expect("frame");
        let b = sim.backend.as_mut();
        let n = b.num_particles();
        for cap in [1000, 4099, n] {
            compare(&dir, &format!("{precision:?}_{cap}"), &scene, b, cap);
        }
    }
}

/// The read of every particle onto the host (`read_particles`: each state word's `n` words
/// into pooled page-locked memory, unpacked by every core) on the fluid dam of 2M particles
/// after a frame (slots sorted): its time, the first read (the pinned memory allocated) apart.
/// Prints the figure; the files of `gpu_frames_streamed_in_chunks_are_byte_identical` check
/// its values (the whole-frame files are written from it).
#[test]
#[ignore = "needs a CUDA GPU"]
fn gpu_read_particles_time() {
    if let Err(e) = probe() {
        println!("skipped: no usable CUDA GPU ({e})");
        return;
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../bench/fluid_dam_2m.toml");
    let scene = Scene::from_file(&path).unwrap_or_else(|e| panic!("{e}"));
    let p0 = scene.sample_particles().expect("particles");
    let gpu = CudaBackend::new(&scene, &p0, CudaOptions::default()).expect("cuda");
    let mut sim = Simulation::with_backend(scene, Box::new(gpu));
    sim.advance_frame().expect("frame");
    let b = sim.backend.as_mut();
    let n = b.num_particles();
    let state = b.device_particles().expect("state");
    let bytes = (n * state.layout.words() * state.word_bytes) as f64;
    let mut p = Particles::default();
    let t = std::time::Instant::now();
    b.read_particles(&mut p).expect("read");
    let first = t.elapsed().as_secs_f64();
    let reps = 5;
    let t = std::time::Instant::now();
    for _ in 0..reps {
        b.read_particles(&mut p).expect("read");
    }
    let each = t.elapsed().as_secs_f64() / reps as f64;
    assert_eq!(p.len(), n);
    assert!(p.x.iter().all(|x| x.is_finite()));
    assert_eq!(p.mass.iter().filter(|&&m| m > 0.0).count(), n);
    println!(
        "read_particles: {n} particles ({:.0} MB of state) in {:.1} ms ({:.2} GB/s; the first \
         read, allocating the pinned memory, {:.1} ms), {} threads",
        bytes / 1e6,
        each * 1e3,
        bytes / each / 1e9,
        first * 1e3,
        rayon::current_num_threads()
    );
}
