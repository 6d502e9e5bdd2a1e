//! Checkpoint reader. The input becomes a checkpoint's payload wrapped in a valid header and
//! checksum (random bytes would almost never pass the checksum), so the fuzzer explores the
//! decoding and the value checks behind it: when the first byte is even, the input is the
//! payload as is (lengths and counts fuzzed too); when odd, the rest is the time, step, frame
//! and particle bytes of a payload whose strings and count are made consistent. Whatever decodes is checked against a
//! scene, and must then be safe to simulate: finite, positive mass, materials in range, inside
//! the domain.
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

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let structured;
    let payload = if mode % 2 == 0 {
        rest
    } else {
        let (head, particles) = rest.split_at(rest.len().min(24));
        let n = particles.len() / 112;
        let mut p = Vec::with_capacity(rest.len() + 24);
        p.extend_from_slice(&0u64.to_le_bytes()); // scene_toml: empty
        p.extend_from_slice(&0u64.to_le_bytes()); // scene_origin: empty
        let mut h = [0u8; 24];
        h[..head.len()].copy_from_slice(head);
        p.extend_from_slice(&h); // time, step, frame
        p.extend_from_slice(&(n as u64).to_le_bytes());
        p.extend_from_slice(&particles[..n * 112]);
        structured = p;
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
