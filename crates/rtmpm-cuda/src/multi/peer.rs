//! Peer access between the GPUs of one process (transport=p2p, Fei, Huang & Gao, "Real-Time Simulation of MPM on Modern GPUs" (GTC 2022): "in-kernel peer-to-peer
//! read/write operations"): whether every pair of GPUs can reach each other's memory
//! (`cuDeviceCanAccessPeer`), and turning it on (`cuCtxEnablePeerAccess`). With unified addressing
//! a device pointer of GPU j is then valid in GPU i's kernels as it is.

use cudarc::driver::sys;

/// The first pair (i, j) of GPUs 0..gpus where GPU i cannot access GPU j's memory, or `None` when
/// every pair can. `Err` when the driver cannot be asked.
pub fn first_pair_without_access(gpus: usize) -> Result<Option<(usize, usize)>, String> {
    first_pair_without(&(0..gpus).collect::<Vec<_>>(), None)
}

/// [`first_pair_without_access`] among the devices `devices` (ordinals; a device named twice
/// needs no peer access to itself).
pub fn first_pair_without_access_among(
    devices: &[usize],
) -> Result<Option<(usize, usize)>, String> {
    first_pair_without(devices, None)
}

/// The first pair (i, j) of `devices` where GPU i has no native atomics on GPU j's memory (the spin barrier
/// adds to a counter in GPU 0's memory), or `None` when every pair has them.
pub fn first_pair_without_atomics(devices: &[usize]) -> Result<Option<(usize, usize)>, String> {
    first_pair_without(
        devices,
        Some(sys::CUdevice_P2PAttribute::CU_DEVICE_P2P_ATTRIBUTE_NATIVE_ATOMIC_SUPPORTED),
    )
}

fn first_pair_without(
    devices: &[usize],
    attribute: Option<sys::CUdevice_P2PAttribute>,
) -> Result<Option<(usize, usize)>, String> {
    // Initialises the driver (cuInit) if no context exists yet.
    let n = cudarc::driver::CudaContext::device_count().map_err(|e| format!("{e:?}"))? as usize;
    if let Some(&d) = devices.iter().find(|&&d| d >= n) {
        return Err(format!("GPU {d} asked, {n} found"));
    }
    let dev = |i: usize| -> Result<sys::CUdevice, String> {
        let mut d: sys::CUdevice = 0;
        // SAFETY: out-parameter; i < device count.
        unsafe { sys::cuDeviceGet(&mut d, i as i32) }
            .result()
            .map_err(|e| format!("cuDeviceGet({i}): {e:?}"))?;
        Ok(d)
    };
    for &i in devices {
        for &j in devices {
            if i == j {
                continue;
            }
            let mut can = 0;
            // SAFETY: out-parameters; both devices exist.
            match attribute {
                None => unsafe { sys::cuDeviceCanAccessPeer(&mut can, dev(i)?, dev(j)?) }
                    .result()
                    .map_err(|e| format!("cuDeviceCanAccessPeer({i}, {j}): {e:?}"))?,
                Some(a) => unsafe { sys::cuDeviceGetP2PAttribute(&mut can, a, dev(i)?, dev(j)?) }
                    .result()
                    .map_err(|e| format!("cuDeviceGetP2PAttribute({i}, {j}): {e:?}"))?,
            }
            if can == 0 {
                return Ok(Some((i, j)));
            }
        }
    }
    Ok(None)
}

/// Let the context current on this thread access the memory of `peer` (a `CUcontext` of another
/// GPU, as an integer); enabling it twice is not an error.
pub fn enable(peer: usize) -> Result<(), String> {
    // SAFETY: `peer` is a live context handle of another GPU of this process.
    let r = unsafe { sys::cuCtxEnablePeerAccess(peer as sys::CUcontext, 0) };
    match r {
        sys::CUresult::CUDA_SUCCESS | sys::CUresult::CUDA_ERROR_PEER_ACCESS_ALREADY_ENABLED => {
            Ok(())
        }
        e => Err(format!("cuCtxEnablePeerAccess: {e:?}")),
    }
}

/// Let the GPUs `peers` (ordinals) read and write every allocation of GPU `own`'s current memory
/// pool, those made before and after. cudarc allocates from the pool (`cuMemAllocAsync`) where the
/// device has pools, and pool memory is not reached through `cuCtxEnablePeerAccess`.
pub fn grant_pool_access(own: usize, peers: &[usize]) -> Result<(), String> {
    let mut dev: sys::CUdevice = 0;
    // SAFETY: out-parameter; `own` is a device of this process.
    unsafe { sys::cuDeviceGet(&mut dev, own as i32) }
        .result()
        .map_err(|e| format!("cuDeviceGet({own}): {e:?}"))?;
    let mut pool: sys::CUmemoryPool = std::ptr::null_mut();
    // SAFETY: out-parameter.
    unsafe { sys::cuDeviceGetMemPool(&mut pool, dev) }
        .result()
        .map_err(|e| format!("cuDeviceGetMemPool({own}): {e:?}"))?;
    let descs: Vec<sys::CUmemAccessDesc> = peers
        .iter()
        .map(|&p| sys::CUmemAccessDesc {
            location: sys::CUmemLocation {
                type_: sys::CUmemLocationType::CU_MEM_LOCATION_TYPE_DEVICE,
                id: p as i32,
            },
            flags: sys::CUmemAccess_flags::CU_MEM_ACCESS_FLAGS_PROT_READWRITE,
        })
        .collect();
    if descs.is_empty() {
        return Ok(());
    }
    // SAFETY: `descs` holds `descs.len()` valid descriptors of other devices.
    unsafe { sys::cuMemPoolSetAccess(pool, descs.as_ptr(), descs.len()) }
        .result()
        .map_err(|e| format!("cuMemPoolSetAccess(GPU {own} -> {peers:?}): {e:?}"))
}
