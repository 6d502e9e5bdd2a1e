//! The kernels of the program, from one list: `build.rs` reads the `kernels/` folder and writes
//! [`SOURCES`], [`UNITS`] and the [`Kernel`] enum (every `extern "C" __global__` function);
//! [`Kernels`] loads every one of them by name, and launch code indexes it by [`Kernel`]. The
//! module's `__constant__` symbols ([`CONSTANT_SYMBOLS`]) are written by [`write_symbol`].

use crate::contract::Ctx;
use cudarc::driver::{
    CudaFunction, CudaModule, CudaStream, DriverError, LaunchConfig, PushKernelArg, sys,
};
use rtmpm_sim::SimError;
use std::ffi::c_void;
use std::sync::Arc;

include!(concat!(env!("OUT_DIR"), "/kernel_list.rs"));

/// The kernels [`Kernels::launch_step`] may launch with programmatic dependent launch: the
/// step's kernels after its first, each beginning with `step_kernel_entry()`
/// (`kernels/common.cuh`), the wait for the kernel before it. `rb_fused`, the step's first
/// kernel, has the entry too (its trigger only) but is launched without the attribute.
pub const PDL_KERNELS: [Kernel; 11] = [
    Kernel::P2g,
    Kernel::P2gMpm,
    Kernel::P2gCk,
    Kernel::P2gCkWarp,
    Kernel::GridUpdate,
    Kernel::G2p,
    Kernel::G2pMpm,
    Kernel::G2pCk,
    Kernel::G2p2g,
    Kernel::G2p2gFluid,
    Kernel::G2p2gCk,
];

/// Every kernel of the loaded module, and the launch sizes of the device.
pub struct Kernels {
    functions: Vec<CudaFunction>,
    /// Threads of one full wave of the device (SMs x 2048): kernels with grid-stride loops launch
    /// at most this many.
    pub wave_threads: usize,
    /// The fused rebuild's grid (blocks of 1024 threads that fit on the device at once, for its
    /// cooperative launch); `None`: the rebuild runs as separate kernels (`rebuild=kernels`).
    pub rb_fused_grid: Option<u32>,
    /// Blocks of 128 threads of the fused G2P2G kernels (`g2p2g`, `g2p2g_fluid`) that are
    /// resident on the device at once: their grid (every block loops over the warp list until
    /// it ends: no partly filled last round of blocks when the blocks per SM do not divide the
    /// wave), the default in f32 (`RTMPM_G2P2G_GRID=resident` asks for it in f64, whose
    /// register bounds it was not timed with); `None`: one wave of threads ([`Kernels::wave`]),
    /// in f64 or with `RTMPM_G2P2G_GRID=wave`.
    pub g2p2g_resident: Option<[u32; 2]>,
    /// Blocks of 128 threads of CK-MPM's fused kernel `g2p2g_ck` resident at once, its grid
    /// in f32 or with `ck_grid=resident` ([`crate::CudaOptions::ck_resident_grid`]); `None`:
    /// one wave of threads, in f64 or with `ck_grid=wave`.
    pub g2p2g_ck_resident: Option<u32>,
    /// Fields of the rebuild's sort scratch
    /// ([`crate::options::CudaOptions::sort_scratch_fields`]): the state is permuted that many
    /// fields per pass.
    pub sort_fields: u32,
    /// The fields the sort permutes (bit f: field f; [`crate::step::rebuild::sorted_fields`]).
    pub sort_mask: u32,
    /// Programmatic dependent launch ([`crate::CudaOptions::pdl`] on a GPU that has it, the
    /// module compiled with `-DRTMPM_PDL`): [`Kernels::launch_step`] launches with the
    /// attribute. Off: every launch as before.
    pub pdl: bool,
}

impl Kernels {
    /// Load every kernel of `module`; `sm_count` sizes the waves; from the options `o`:
    /// `fused_rebuild` asks for the persistent rebuild kernel's grid, `sort_scratch_fields` is
    /// the sort scratch's fields (at most the `layout`'s words), `f64` says the module is double
    /// precision (its fused kernels keep one wave of threads unless asked:
    /// [`Kernels::g2p2g_resident`]) and `ck_resident_grid` asks for the resident grid of
    /// `g2p2g_ck`.
    pub(crate) fn load(
        module: &Arc<CudaModule>,
        sm_count: i32,
        o: &crate::options::CudaOptions,
        layout: crate::contract::StateLayout,
    ) -> Result<Kernels, SimError> {
        let functions = Kernel::ALL
            .iter()
            .map(|k| {
                module
                    .load_function(k.name())
                    .map_err(|e| SimError::Backend(format!("CUDA: kernel {}: {e:?}", k.name())))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let mut k = Kernels {
            functions,
            wave_threads: sm_count.max(1) as usize * 2048,
            rb_fused_grid: None,
            g2p2g_resident: None,
            g2p2g_ck_resident: None,
            sort_fields: o.sort_scratch_fields.clamp(1, layout.words()) as u32,
            sort_mask: layout.all_words(),
            pdl: false,
        };
        if o.fused_rebuild {
            // A cooperative launch needs every block resident, so its grid barrier cannot deadlock.
            let per_sm = k[Kernel::RbFused]
                .occupancy_max_active_blocks_per_multiprocessor(1024, 0, None)
                .map_err(|e| SimError::Backend(format!("CUDA: occupancy of rb_fused: {e:?}")))?;
            k.rb_fused_grid = Some(per_sm * sm_count.max(1) as u32).filter(|&g| g > 0);
        }
        let resident = |k: &Kernels, f: Kernel| {
            k[f].occupancy_max_active_blocks_per_multiprocessor(128, 0, None)
                .map(|per_sm| per_sm * sm_count.max(1) as u32)
                .map_err(|e| SimError::Backend(format!("CUDA: occupancy of {}: {e:?}", f.name())))
        };
        let grid = std::env::var("RTMPM_G2P2G_GRID").unwrap_or_default();
        if grid.trim() == "resident" || (grid.trim() != "wave" && !o.f64) {
            let general = resident(&k, Kernel::G2p2g)?;
            let fluid = resident(&k, Kernel::G2p2gFluid)?;
            k.g2p2g_resident = Some([general, fluid]);
        }
        if o.ck_resident_grid.unwrap_or(!o.f64) {
            k.g2p2g_ck_resident = Some(resident(&k, Kernel::G2p2gCk)?);
        }
        Ok(k)
    }

    /// Launch `f`, a kernel of the step after its first whose arguments are the context `c`
    /// and, for some, the `part` of the blocks, on `s` with `cfg`: with [`Kernels::pdl`] as a
    /// programmatic dependent launch (`cuLaunchKernelEx` with
    /// `CU_LAUNCH_ATTRIBUTE_PROGRAMMATIC_STREAM_SERIALIZATION`: its blocks may be scheduled
    /// before the kernel before it on `s` completes; stream capture makes that a programmatic
    /// edge of the graph), else as every other launch. Only for kernels that begin with
    /// `step_kernel_entry()` (`kernels/common.cuh`), which waits for the kernel before.
    ///
    /// # Safety
    /// As [`cudarc::driver::LaunchArgs::launch`]: `f` takes `(Ctx)` (`part` `None`) or
    /// `(Ctx, unsigned)`, and bounds-checks what it reads and writes against `c`.
    pub(crate) unsafe fn launch_step(
        &self,
        s: &CudaStream,
        f: Kernel,
        cfg: LaunchConfig,
        c: &Ctx,
        part: Option<u32>,
    ) -> Result<(), DriverError> {
        debug_assert!(
            PDL_KERNELS.contains(&f),
            "{} has no step_kernel_entry",
            f.name()
        );
        if !self.pdl {
            let mut b = s.launch_builder(&self[f]);
            b.arg(c);
            if let Some(p) = &part {
                b.arg(p);
            }
            // SAFETY: the caller's.
            unsafe { b.launch(cfg)? };
            return Ok(());
        }
        let mut args: Vec<*mut c_void> = vec![c as *const Ctx as *mut c_void];
        if let Some(p) = &part {
            args.push(p as *const u32 as *mut c_void);
        }
        // SAFETY: the caller's; `args` points at `c` and `part`, which outlive the call (the
        // driver copies the arguments at the launch).
        unsafe { launch_programmatic(s, &self[f], cfg, &mut args) }
    }

    /// Launch configuration for `n` threads in blocks of `block`, at most one wave (the kernels
    /// loop over their items, grid-stride).
    pub(crate) fn wave(&self, n: usize, block: u32) -> LaunchConfig {
        cfg(n.min(self.wave_threads.max(block as usize)), block)
    }
}

impl std::ops::Index<Kernel> for Kernels {
    type Output = CudaFunction;
    fn index(&self, k: Kernel) -> &CudaFunction {
        &self.functions[k as usize]
    }
}

/// `cuLaunchKernelEx` of `f` on `s` with `cfg` and the argument pointers `args`, with the one
/// attribute `CU_LAUNCH_ATTRIBUTE_PROGRAMMATIC_STREAM_SERIALIZATION` (cudarc's launch builder
/// takes no launch attributes).
///
/// # Safety
/// `args` match `f`'s parameters and point at live values; `f` waits (`griddepcontrol.wait`)
/// before it touches memory that the work before it on `s` writes or reads.
unsafe fn launch_programmatic(
    s: &CudaStream,
    f: &CudaFunction,
    cfg: LaunchConfig,
    args: &mut [*mut c_void],
) -> Result<(), DriverError> {
    s.context().bind_to_thread()?;
    // SAFETY: a plain C struct of integers and a union of them; all zero is a valid value.
    let mut attr: sys::CUlaunchAttribute = unsafe { std::mem::zeroed() };
    attr.id = sys::CUlaunchAttributeID::CU_LAUNCH_ATTRIBUTE_PROGRAMMATIC_STREAM_SERIALIZATION;
    attr.value.programmaticStreamSerializationAllowed = 1;
    let config = sys::CUlaunchConfig {
        gridDimX: cfg.grid_dim.0,
        gridDimY: cfg.grid_dim.1,
        gridDimZ: cfg.grid_dim.2,
        blockDimX: cfg.block_dim.0,
        blockDimY: cfg.block_dim.1,
        blockDimZ: cfg.block_dim.2,
        sharedMemBytes: cfg.shared_mem_bytes,
        hStream: s.cu_stream(),
        attrs: &mut attr,
        numAttrs: 1,
    };
    // SAFETY: `config` and `attr` live through the call; the rest is the caller's.
    unsafe {
        sys::cuLaunchKernelEx(
            &config,
            f.cu_function(),
            args.as_mut_ptr(),
            std::ptr::null_mut(),
        )
    }
    .result()
}

/// Launch configuration covering `n` threads in blocks of `block`.
pub(crate) fn cfg(n: usize, block: u32) -> LaunchConfig {
    LaunchConfig {
        grid_dim: ((n.max(1)).div_ceil(block as usize) as u32, 1, 1),
        block_dim: (block, 1, 1),
        shared_mem_bytes: 0,
    }
}

/// The `__constant__` symbols the host writes (`kernels/common.cuh`).
pub const CONSTANT_SYMBOLS: [&str; 7] = [
    "c_scalars",
    "c_step",
    "c_poses",
    "c_materials",
    "c_colliders",
    "c_bodies",
    "c_tool",
];

/// Write `bytes` to the `__constant__` symbol `name` of the module (async on the stream).
pub(crate) fn write_symbol(
    module: &Arc<CudaModule>,
    stream: &Arc<CudaStream>,
    name: &str,
    bytes: &[u8],
) -> Result<(), SimError> {
    if bytes.is_empty() {
        return Ok(());
    }
    let mut sym = module
        .get_global(name, stream)
        .map_err(|e| SimError::Backend(format!("CUDA: constant symbol {name}: {e:?}")))?;
    let len = bytes.len().min(sym.len());
    let mut view = sym.slice_mut(..len);
    stream
        .memcpy_htod(&bytes[..len], &mut view)
        .map_err(|e| SimError::Backend(format!("CUDA: write constant {name}: {e:?}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_list_holds_every_stage_kernel_once() {
        for name in [
            "rb_fused",
            "p2g",
            "grid_update",
            "g2p",
            "g2p2g",
            "g2p2g_fluid",
            "sb_sum_peers",
        ] {
            assert_eq!(
                Kernel::ALL.iter().filter(|k| k.name() == name).count(),
                1,
                "{name}"
            );
        }
        assert!(UNITS.contains(&"p2g/scatter.cu"));
        assert!(SOURCES.iter().any(|(n, _)| *n == "material/hencky.cuh"));
        for (i, k) in Kernel::ALL.iter().enumerate() {
            assert_eq!(*k as usize, i);
        }
    }
}
