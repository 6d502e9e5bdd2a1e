//! Resume with rigid bodies: a checkpoint's bytes and the output folder's `bodies.csv`, through
//! the checks `rtmpm run --resume` makes before the folder changes (the checkpoint decoded and
//! checked against the scene, then the rows of `bodies.csv` up to the checkpoint's frame,
//! `KeptRows::read`). Never a panic, a hang or a huge allocation, whatever the frame number.
//!
//! Input: a mode byte, the length of the `bodies.csv` text (u16, little endian), that text,
//! then the checkpoint. Mode even: the rest is the checkpoint's payload as is (wrapped in a
//! valid header and checksum, as the checkpoint target does); odd: the rest is the time, step
//! and frame (24 bytes), the two bodies' poses (2 x 52 bytes) and the particle bytes of a
//! payload whose counts are made consistent, so most inputs reach `bodies.csv`.
#![no_main]
use libfuzzer_sys::fuzz_target;
use rtmpm_driver::bodies_csv::KeptRows;
use rtmpm_io::checkpoint::{Checkpoint, Fnv1a64, MAGIC, VERSION};
use rtmpm_scene::Scene;
use std::path::PathBuf;
use std::sync::OnceLock;

fn scene() -> &'static Scene {
    static S: OnceLock<Scene> = OnceLock::new();
    S.get_or_init(|| {
        Scene::from_toml(
            "[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ndx = 0.05\n[time]\nduration = 1\n\
             [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000\nbulk_modulus = 1e5\n\
             [[rigid_body]]\nname = \"a\"\nshape = \"sphere\"\ncenter = [0.3, 0.5, 0.5]\n\
             radius = 0.1\ndensity = 500\n\
             [[rigid_body]]\nname = \"b\"\nshape = \"box\"\nmin = [0.6, 0.4, 0.4]\n\
             max = [0.8, 0.6, 0.6]\ndensity = 500\n",
            "<fuzz>",
        )
        .expect("fuzz scene")
    })
}

fn csv_path() -> &'static PathBuf {
    static P: OnceLock<PathBuf> = OnceLock::new();
    P.get_or_init(|| std::env::temp_dir().join(format!("rtmpm-fuzz-{}-bodies.csv", std::process::id())))
}

/// A payload of the current version from the structured mode's bytes.
fn structured(rest: &[u8]) -> Vec<u8> {
    let (head, rest) = rest.split_at(rest.len().min(24));
    let (poses, particles) = rest.split_at(rest.len().min(2 * 52));
    let n = particles.len() / 112;
    let mut p = Vec::with_capacity(rest.len() + 64);
    p.extend_from_slice(&0u64.to_le_bytes()); // scene_toml: empty
    p.extend_from_slice(&0u64.to_le_bytes()); // scene_origin: empty
    let mut h = [0u8; 24];
    h[..head.len()].copy_from_slice(head);
    p.extend_from_slice(&h); // time, step, frame
    p.extend_from_slice(&2u64.to_le_bytes()); // the scene's two bodies
    let mut b = [0u8; 2 * 52];
    b[..poses.len()].copy_from_slice(poses);
    p.extend_from_slice(&b);
    p.extend_from_slice(&0u64.to_le_bytes()); // no file hashes
    p.extend_from_slice(&(n as u64).to_le_bytes());
    p.extend_from_slice(&particles[..n * 112]);
    p
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let Some((len, rest)) = rest.split_first_chunk::<2>() else {
        return;
    };
    let (csv, rest) = rest.split_at(rest.len().min(u16::from_le_bytes(*len) as usize));
    let built;
    let payload = if mode % 2 == 0 {
        rest
    } else {
        built = structured(rest);
        &built
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
    if scene().check_checkpoint(&ck).is_err() {
        return;
    }
    assert_eq!(ck.bodies.len(), 2);
    std::fs::write(csv_path(), csv).expect("write bodies.csv");
    if let Ok(kept) = KeptRows::read(csv_path(), scene(), ck.frame) {
        assert_eq!(kept.frame, ck.frame);
        for row in &kept.rows {
            let frame: u64 = row.split(',').next().and_then(|f| f.parse().ok()).expect("frame");
            assert!(frame <= ck.frame, "a row of frame {frame} after {}", ck.frame);
            assert!(!(kept.rewrite && frame == ck.frame), "a row of the frame to rewrite kept");
        }
    }
});
