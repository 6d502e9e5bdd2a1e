//! What the tests of several GPUs (`tests/multi_gpu_*.rs`) share: the ranks' devices
//! (`RTMPM_MULTI_GPU_DEVICES`), their options, the example scenes, and which GPU counts and
//! modes (transports, barriers) can run here.

use rtmpm_cuda::{CudaOptions, MultiGpuBackend, device_count, nccl, peer};
use rtmpm_physics::Particles;
use rtmpm_scene::Scene;
use std::path::{Path, PathBuf};

/// `RTMPM_MULTI_GPU_DEVICES`: the device of each rank, when set.
pub fn env_devices() -> Option<Vec<usize>> {
    let v = std::env::var("RTMPM_MULTI_GPU_DEVICES").ok()?;
    let d: Vec<usize> = v
        .split(',')
        .map(|x| {
            x.trim()
                .parse()
                .expect("RTMPM_MULTI_GPU_DEVICES: ordinals, e.g. 0,0")
        })
        .collect();
    assert!(d.len() >= 2, "RTMPM_MULTI_GPU_DEVICES: at least two ranks");
    Some(d)
}

/// `o` with the ranks of a run of `gpus` on the devices of `RTMPM_MULTI_GPU_DEVICES` (cycled),
/// when set.
pub fn on_devices(gpus: usize, o: CudaOptions) -> CudaOptions {
    match env_devices() {
        Some(d) => CudaOptions {
            devices: Some((0..gpus).map(|i| d[i % d.len()]).collect()),
            ..o
        },
        None => o,
    }
}

/// Options of `text` for a run of `gpus` ranks (see [`on_devices`]).
pub fn options(gpus: usize, text: &str) -> CudaOptions {
    on_devices(gpus, text.parse().expect("CUDA options"))
}

/// True when two ranks share a device (`RTMPM_MULTI_GPU_DEVICES`).
pub fn ranks_share_a_device() -> bool {
    env_devices().is_some_and(|d| (1..d.len()).any(|i| d[..i].contains(&d[i])))
}

/// The example scenes (`scenes/*.toml`), sorted, without the batches of worlds.
pub fn scenes() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .expect("scenes/")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        // A batch of worlds ([batch]) is many scenes, not one: its worlds against separate
        // CUDA runs are the tests/batch_*.rs.
        .filter(|p| !rtmpm_scene::BatchScene::from_file(p).is_ok_and(|b| b.batch.is_some()))
        .collect();
    v.sort();
    v
}

/// True when the devices of a run of `gpus` ranks are here; else says why the test is skipped.
pub fn usable(gpus: usize) -> bool {
    let found = device_count();
    let needed = match env_devices() {
        Some(d) => d.iter().max().map_or(0, |m| m + 1),
        None => gpus,
    };
    if found < needed {
        println!("skipped: {needed} CUDA GPUs needed, {found} found");
        return false;
    }
    true
}

/// Whether `mode` (e.g. "transport=nccl") can run on `gpus` GPUs here; prints why not. Ranks
/// sharing a device: the spin barrier and NCCL must be refused with a clear error (checked
/// here on `scene`), and are not run.
pub fn mode_usable(mode: &str, gpus: usize, scene: &Scene, p: &Particles) -> bool {
    if ranks_share_a_device() && (mode.contains("barrier=spin") || mode.contains("nccl")) {
        let e = MultiGpuBackend::new(scene, p, gpus, options(gpus, mode))
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        let want = if mode.contains("nccl") {
            "NCCL refuses two ranks on one device"
        } else {
            "use barrier=events"
        };
        assert!(
            e.contains(want),
            "{mode} with ranks sharing a device: {e:?}"
        );
        println!("{mode} x{gpus}: refused with ranks sharing a device, as it must be: {e}");
        return false;
    }
    if mode.contains("transport=nccl") {
        if let Err(e) = nccl::library() {
            println!("skipped {mode}: NCCL not usable ({e})");
            return false;
        }
    } else if mode.contains("transport=p2p") {
        let devices = options(gpus, "")
            .devices
            .unwrap_or_else(|| (0..gpus).collect());
        match peer::first_pair_without_access_among(&devices) {
            Ok(None) => {}
            Ok(Some((i, j))) => {
                println!("skipped {mode} x{gpus}: GPU {i} has no peer access to GPU {j}");
                return false;
            }
            Err(e) => {
                println!("skipped {mode} x{gpus}: {e}");
                return false;
            }
        }
    }
    true
}

/// The GPU count of the tests of several ranks: 2, or the ranks of `RTMPM_MULTI_GPU_DEVICES`.
pub fn ranks() -> usize {
    env_devices().map_or(2, |d| d.len())
}

/// The modes those tests compare: the p2p barriers and NCCL (those that cannot share a device
/// are checked to be refused there, [`mode_usable`]).
pub const MODES: [&str; 3] = [
    "transport=p2p,barrier=spin",
    "transport=p2p,barrier=events",
    "transport=nccl",
];
