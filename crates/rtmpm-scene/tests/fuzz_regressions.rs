//! Every input that once made a fuzz target (fuzz/, scripts/fuzz.sh) fail, replayed through the
//! same checks: `tests/fuzz_regressions/<target>/<name>`, one file each. They must now give a
//! result or a clear error; a panic fails the test.

use rtmpm_io::checkpoint::{Checkpoint, Fnv1a64, MAGIC, VERSION};
use rtmpm_io::{ply, vtu};
use rtmpm_scene::Scene;
use std::path::Path;

fn inputs(target: &str) -> Vec<(String, Vec<u8>)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fuzz_regressions")
        .join(target);
    let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(&dir)
        .map(|d| {
            d.map(|e| {
                let p = e.unwrap().path();
                (p.display().to_string(), std::fs::read(&p).unwrap())
            })
            .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

#[test]
fn scene_inputs() {
    for (name, bytes) in inputs("scene") {
        if let Ok(text) = std::str::from_utf8(&bytes)
            && let Err(e) = Scene::from_toml(text, &name)
        {
            assert!(e.line.is_some() || e.field.is_some(), "{name}: {e}");
        }
    }
}

#[test]
fn ply_inputs() {
    for (name, bytes) in inputs("ply") {
        if let Ok(d) = ply::parse_ply(&bytes) {
            assert!(d.columns.iter().all(|(_, c)| c.len() == d.count), "{name}");
        }
    }
}

#[test]
fn vtu_inputs() {
    let all = inputs("vtu");
    assert!(!all.is_empty());
    for (name, bytes) in all {
        let text = String::from_utf8_lossy(&bytes);
        if let Ok(d) = vtu::parse_vtu(&text) {
            assert_eq!(d.points.len(), d.num_points, "{name}");
        }
        let _ = vtu::parse_pvd(&text);
    }
}

/// The payload the checkpoint fuzz target builds from its input (fuzz/fuzz_targets/checkpoint.rs).
fn checkpoint_payload(data: &[u8]) -> Option<Vec<u8>> {
    let (&mode, rest) = data.split_first()?;
    if mode % 2 == 0 {
        return Some(rest.to_vec());
    }
    let (head, particles) = rest.split_at(rest.len().min(24));
    let n = particles.len() / 112;
    let mut p = vec![0u8; 16];
    let mut h = [0u8; 24];
    h[..head.len()].copy_from_slice(head);
    p.extend_from_slice(&h);
    p.extend_from_slice(&(n as u64).to_le_bytes());
    p.extend_from_slice(&particles[..n * 112]);
    Some(p)
}

#[test]
fn checkpoint_inputs() {
    let scene = Scene::from_toml(
        "[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ndx = 0.1\n[time]\nduration = 1\n\
         [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000\nbulk_modulus = 1e5\n",
        "<fuzz>",
    )
    .unwrap();
    for (name, data) in inputs("checkpoint") {
        let Some(payload) = checkpoint_payload(&data) else {
            continue;
        };
        let mut b = MAGIC.to_vec();
        b.extend_from_slice(&VERSION.to_le_bytes());
        b.extend_from_slice(&0u32.to_le_bytes());
        b.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        b.extend_from_slice(&payload);
        let mut h = Fnv1a64::default();
        h.update(&b);
        b.extend_from_slice(&h.finish().to_le_bytes());
        if let Ok(ck) = Checkpoint::from_bytes(&b) {
            assert!(ck.time.is_finite() && ck.time >= 0.0, "{name}");
            let _ = scene.check_checkpoint(&ck);
        }
    }
}
