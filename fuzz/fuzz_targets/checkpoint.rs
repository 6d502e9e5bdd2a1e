//! Checkpoint reader. The input becomes a checkpoint's payload wrapped in a valid header and
//! checksum (random bytes would almost never pass the checksum), so the fuzzer explores the
//! decoding and the value checks behind it: when the first byte is even, the input is the
//! payload as is (lengths and counts fuzzed too); when odd, the rest fills a payload of the
//! current format (version 3) whose lengths and counts are made consistent: time, step, frame,
//! 0 to 3 rigid-body poses, 0 to 2 file hashes (field, path, hash) and the particles. Whatever
//! decodes is checked against a scene, and must then be safe to simulate: finite, positive
//! mass, materials in range, inside the domain.
#![no_main]
use libfuzzer_sys::fuzz_target;
use rtmpm_io::checkpoint::{Checkpoint, Fnv1a64, MAGIC, VERSION};
use rtmpm_scene::Scene;
use std::sync::OnceLock;

fn scene() -> &'static Scene {
    static S: OnceLock<Scene> = OnceLock::new();
    S.get_or_init(|| {
        Scene::from_toml(
            "[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ndx = 0.1\n[time]\nduration = 1\n\
             [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000\nbulk_modulus = 1e5\n",
            "<fuzz>",
        )
        .expect("fuzz scene")
    })
}

/// A version-3 payload from `rest`: its first byte picks the counts of bodies (0 to 3) and file
/// hashes (0 to 2); then 24 bytes of time, step and frame, 52 bytes per body pose (13 f32), 8
/// bytes per file hash, and whole particles of 112 bytes from what is left.
fn structured_payload(rest: &[u8]) -> Vec<u8> {
    let (&counts, rest) = rest.split_first().unwrap_or((&0, &[]));
    let (bodies, files) = (usize::from(counts % 4), usize::from((counts / 4) % 3));
    let mut input = rest.iter().copied();
    let mut take = |n: usize| -> Vec<u8> { (0..n).map(|_| input.next().unwrap_or(0)).collect() };
    let mut p = Vec::with_capacity(rest.len() + 128);
    p.extend_from_slice(&0u64.to_le_bytes()); // scene_toml: empty
    p.extend_from_slice(&0u64.to_le_bytes()); // scene_origin: empty
    p.extend_from_slice(&take(24)); // time, step, frame
    p.extend_from_slice(&(bodies as u64).to_le_bytes());
    for _ in 0..bodies {
        p.extend_from_slice(&take(52));
    }
    p.extend_from_slice(&(files as u64).to_le_bytes());
    for (field, path) in [("body[0].file", "m.obj"), ("collider[0].file", "../x.ply")]
        .into_iter()
        .take(files)
    {
        for text in [field, path] {
            p.extend_from_slice(&(text.len() as u64).to_le_bytes());
            p.extend_from_slice(text.as_bytes());
        }
        p.extend_from_slice(&take(8));
    }
    let particles = take(rest.len().saturating_sub(24 + 52 * bodies + 8 * files));
    let n = particles.len() / 112;
    p.extend_from_slice(&(n as u64).to_le_bytes());
    p.extend_from_slice(&particles[..n * 112]);
    p
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let structured;
    let payload = if mode % 2 == 0 {
        rest
    } else {
        structured = structured_payload(rest);
        &structured
    };
    let mut bytes = Vec::with_capacity(payload.len() + 32);
    bytes.extend_from_slice(&MAGIC);
    bytes.extend_from_slice(&VERSION.to_le_bytes());
    bytes.extend_from_slice(&0u32.to_le_bytes());
    bytes.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    bytes.extend_from_slice(payload);
    let mut h = Fnv1a64::default();
    h.update(&bytes);
    bytes.extend_from_slice(&h.finish().to_le_bytes());
    let Ok(ck) = Checkpoint::from_bytes(&bytes) else {
        return;
    };
    assert!(ck.time.is_finite() && ck.time >= 0.0);
    if scene().check_checkpoint(&ck).is_ok() {
        let p = &ck.particles;
        for i in 0..p.len() {
            assert!(p.mass[i] > 0.0 && p.vol0[i] > 0.0 && p.x[i].is_finite());
            assert!((p.material[i] as usize) < scene().materials.len());
        }
    }
});
