//! The program's source (the kernel files of [`crate::kernels::SOURCES`] and the generated
//! headers of [`crate::contract`]), a small `#include` preprocessor and NVRTC compilation with
//! an on-disk cache of the PTX and the cubin ([`image`]: what the backend loads).

use crate::contract;
use crate::kernels::{SOURCES, UNITS};
use std::borrow::Cow;
use std::collections::HashSet;
use std::path::PathBuf;

pub mod image;

/// Compilation options of the kernels.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct KernelOptions {
    /// Compute capability, e.g. (9, 0).
    pub arch: (i32, i32),
    /// Pass `--use_fast_math`.
    pub fast_math: bool,
    /// Define `RTMPM_F64` (double precision arithmetic in the kernels).
    pub f64: bool,
    /// The material models the program must handle: bit k for kind code k
    /// (`rtmpm_physics::material::Model::code`); `u32::MAX`: every model.
    pub materials: u32,
    /// Index the state arrays in 64 bits (`RTMPM_STATE_64`): needed from 2^32 words on
    /// ([`state_needs_64_bits`]).
    pub state64: bool,
    /// The particle state's layout (`-DRTMPM_STATE_LAYOUT`, left out for the default).
    pub layout: contract::StateLayout,
    /// Many worlds in one set of arrays (`-DRTMPM_BATCH`, [`crate::batch`]); off: the kernels
    /// of one world, unchanged.
    pub batch: bool,
    /// CK-MPM's warp-scatter kernels held to this many blocks of 128 threads a SM
    /// (`-DCK_MIN_BLOCKS`, [`crate::CudaOptions::ck_min_blocks`]; 0: no bound); `None`: left
    /// out, the kernels' default (`kernels/ck.cuh`: `g2p2g_ck` at 5 blocks in f32).
    pub ck_min_blocks: Option<u32>,
    /// The pair addressing of the stencil nodes ([`crate::CudaOptions::stencil_pairs`], the
    /// kernels' default); `false`: `-DRTMPM_G2P_GATHER=1 -DRTMPM_P2G_NODES=1`, the addressing
    /// before it.
    pub stencil_pairs: bool,
    /// The fused kernels' warp loop over warp-uniform values
    /// ([`crate::CudaOptions::uniform_loop`], the kernels' default); `false`:
    /// `-DRTMPM_G2P2G_UNIFORM=0`, the loop before it.
    pub uniform_loop: bool,
    /// `RTMPM_P2G_UNROLL` ([`crate::FusedSwitches::row_unroll`] resolved for the backend's
    /// kernel set, [`crate::RowUnroll::define`]);
    /// 0: left out (the kernels' default, the row loop).
    pub row_unroll: u32,
    /// The fused kernels' instruction cuts ([`crate::FusedSwitches::resolve`] for the backend's
    /// kernel set); default: none.
    pub cuts: crate::options::KernelCuts,
    /// Programmatic dependent launch ([`crate::CudaOptions::pdl`]): `-DRTMPM_PDL`, the wait
    /// and trigger of `kernels/common.cuh`'s `step_kernel_entry`, only for compute capability
    /// 9.0 or newer ([`pdl_supported`]; below it the define is left out whatever this says).
    pub pdl: bool,
}

/// True when a GPU of compute capability `arch` has programmatic dependent launch
/// (`griddepcontrol`, sm_90 and newer).
pub fn pdl_supported(arch: (i32, i32)) -> bool {
    arch.0 >= 9
}

/// True when state arrays of `capacity` particles of `words` words each hold 2^32 words or more:
/// their indices (`field * capacity + slot`) need 64 bits (29 words: a capacity of 148.1M
/// particles or more; 20 words: 214.7M).
pub fn state_needs_64_bits(words: usize, capacity: usize) -> bool {
    (words as u64) * capacity as u64 >= 1 << 32
}

impl KernelOptions {
    /// Every model, fast math, single precision, for `arch`.
    pub fn all_models(arch: (i32, i32), fast_math: bool, f64: bool) -> KernelOptions {
        KernelOptions {
            arch,
            fast_math,
            f64,
            materials: u32::MAX,
            state64: false,
            layout: contract::StateLayout::Full,
            batch: false,
            ck_min_blocks: None,
            stencil_pairs: true,
            uniform_loop: true,
            row_unroll: 0,
            cuts: crate::options::KernelCuts::default(),
            pdl: false,
        }
    }
}

/// A kernel file, or one of the headers generated from the Rust contract.
fn source(name: &str) -> Option<Cow<'static, str>> {
    match name {
        "contract.cuh" => Some(contract::prelude().into()),
        "material/registry.cuh" => Some(contract::material_registry().into()),
        "geometry/registry.cuh" => Some(contract::shape_registry().into()),
        _ => SOURCES
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, s)| Cow::Borrowed(*s)),
    }
}

/// Path of `include` as written in file `from`, relative to the kernels folder ("a/../b" folded).
fn resolve(from: &str, include: &str) -> String {
    let mut parts: Vec<&str> = from.split('/').collect();
    parts.pop();
    for piece in include.split('/') {
        match piece {
            ".." => {
                parts.pop();
            }
            "." => {}
            p => parts.push(p),
        }
    }
    parts.join("/")
}

fn expand(name: &str, seen: &mut HashSet<String>, out: &mut String) -> Result<(), String> {
    let text = source(name).ok_or_else(|| format!("kernel source `{name}` not found"))?;
    expand_text(name, &text, seen, out)
}

fn expand_text(
    name: &str,
    text: &str,
    seen: &mut HashSet<String>,
    out: &mut String,
) -> Result<(), String> {
    out.push_str(&format!("#line 1 \"{name}\"\n"));
    for (n, line) in text.lines().enumerate() {
        let t = line.trim();
        if t == "#pragma once" {
            out.push('\n');
            continue;
        }
        if let Some(rest) = t.strip_prefix("#include \"") {
            let inc = resolve(name, rest.split('"').next().unwrap_or(rest));
            let inc = inc.as_str();
            if seen.insert(inc.to_string()) {
                expand(inc, seen, out)?;
            }
            out.push_str(&format!("#line {} \"{name}\"\n", n + 2));
            continue;
        }
        out.push_str(line);
        out.push('\n');
    }
    Ok(())
}

/// The whole program in precision `f64` (else f32): every unit with its headers inlined once,
/// `#line` directives naming the original files so that NVRTC errors point at
/// `kernels/<file>:<line>`, then the layout checks of the contract.
pub fn program_source(f64: bool) -> Result<String, String> {
    let mut seen = HashSet::new();
    let mut out = String::new();
    if f64 {
        out.push_str("#define RTMPM_F64\n");
    }
    for unit in UNITS {
        seen.insert(unit.to_string());
        expand(unit, &mut seen, &mut out)?;
    }
    out.push_str(&contract::layout_asserts(f64));
    Ok(out)
}

/// NVRTC command line options.
pub fn nvrtc_options(o: &KernelOptions) -> Vec<String> {
    let mut v = vec![
        format!("--gpu-architecture=sm_{}{}", o.arch.0, o.arch.1),
        "-std=c++17".to_string(),
        "--device-as-default-execution-space".to_string(),
    ];
    if o.fast_math {
        v.push("--use_fast_math".into());
    }
    if o.state64 {
        v.push("-DRTMPM_STATE_64".into());
    }
    if o.layout != contract::StateLayout::Full {
        v.push(format!("-DRTMPM_STATE_LAYOUT={}", o.layout.code()));
    }
    if o.materials != u32::MAX {
        v.push(format!("-DRTMPM_MATERIAL_MASK={:#x}u", o.materials));
    }
    if o.batch {
        v.push("-DRTMPM_BATCH".into());
    }
    if let Some(blocks) = o.ck_min_blocks {
        v.push(format!("-DCK_MIN_BLOCKS={blocks}"));
    }
    if !o.stencil_pairs {
        v.push("-DRTMPM_G2P_GATHER=1".into());
        v.push("-DRTMPM_P2G_NODES=1".into());
    }
    if !o.uniform_loop {
        v.push("-DRTMPM_G2P2G_UNIFORM=0".into());
    }
    if o.row_unroll != 0 {
        v.push(format!("-DRTMPM_P2G_UNROLL={}", o.row_unroll));
    }
    v.extend(o.cuts.defines().into_iter().map(String::from));
    if o.pdl && pdl_supported(o.arch) {
        v.push("-DRTMPM_PDL=1".into());
    }
    // Tuning experiments: extra `-DNAME=VALUE` flags, e.g. "-DG2P_MIN_BLOCKS=6" (part of the
    // cache key like every other option).
    if let Ok(defines) = std::env::var("RTMPM_KERNEL_DEFINES") {
        v.extend(
            defines
                .split_whitespace()
                .filter(|d| d.starts_with("-D"))
                .map(String::from),
        );
    }
    v
}

/// Try to load libnvrtc from `RTMPM_NVRTC_LIB` or common install locations, so that cudarc's
/// later `dlopen("libnvrtc.so.13")` finds the already loaded library by its soname.
pub fn preload_nvrtc() {
    use std::sync::OnceLock;
    static LIB: OnceLock<Option<(libloading::Library, Option<libloading::Library>)>> =
        OnceLock::new();
    LIB.get_or_init(|| {
        let mut candidates: Vec<PathBuf> = Vec::new();
        if let Ok(p) = std::env::var("RTMPM_NVRTC_LIB") {
            candidates.push(p.into());
        }
        for p in [
            "/usr/local/cuda/lib64/libnvrtc.so.13",
            "/usr/local/cuda-13.0/lib64/libnvrtc.so.13",
            "/usr/lib/x86_64-linux-gnu/libnvrtc.so.13",
        ] {
            candidates.push(p.into());
        }
        for c in candidates {
            if c.exists() {
                // SAFETY: loading a shared library runs its initialisers; libnvrtc's are benign.
                if let Ok(l) = unsafe { libloading::Library::new(&c) } {
                    // NVRTC dlopens its builtins library by soname too: load the sibling first.
                    let builtins = c.parent().and_then(|d| {
                        let b = d.join("libnvrtc-builtins.so.13.0");
                        // SAFETY: as above.
                        b.exists()
                            .then(|| unsafe { libloading::Library::new(&b) }.ok())
                            .flatten()
                    });
                    return Some((l, builtins));
                }
            }
        }
        None
    });
}

/// True when libnvrtc can be loaded (never panics).
pub fn nvrtc_available() -> bool {
    preload_nvrtc();
    std::panic::catch_unwind(|| unsafe { cudarc::nvrtc::sys::is_culib_present() }).unwrap_or(false)
}

/// NVRTC version (major, minor).
pub fn nvrtc_version() -> Option<(i32, i32)> {
    if !nvrtc_available() {
        return None;
    }
    std::panic::catch_unwind(|| {
        let (mut a, mut b) = (0, 0);
        // SAFETY: plain out-parameters.
        let r = unsafe { cudarc::nvrtc::sys::nvrtcVersion(&mut a, &mut b) };
        (r == cudarc::nvrtc::sys::nvrtcResult::NVRTC_SUCCESS).then_some((a, b))
    })
    .ok()
    .flatten()
}

fn fnv1a(data: &[u8], mut h: u64) -> u64 {
    for b in data {
        h ^= *b as u64;
        h = h.wrapping_mul(0x100_0000_01b3);
    }
    h
}

/// Cache folder: `$RTMPM_CACHE_DIR`, `$XDG_CACHE_HOME/rtmpm/kernels` or `~/.cache/rtmpm/kernels`.
pub fn cache_dir() -> Option<PathBuf> {
    if let Ok(d) = std::env::var("RTMPM_CACHE_DIR") {
        return Some(d.into());
    }
    let base = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    Some(base.join("rtmpm").join("kernels"))
}

/// Compile the pipeline to PTX (or take it from the disk cache). Errors carry the NVRTC log.
/// The backend loads [`compile_image`]'s cubin instead; this PTX is what the tests read.
pub fn compile(o: &KernelOptions) -> Result<String, String> {
    let (src, opts, path) = cache_entry(o, cache_dir())?;
    if let Some(p) = &path
        && let Ok(ptx) = std::fs::read_to_string(p)
    {
        return Ok(ptx);
    }
    Ok(compile_and_keep(&src, opts, path.as_deref())?.ptx)
}

/// The program's source, its NVRTC options and its PTX's path in the cache folder `dir` (named
/// by a hash of the source, the options and NVRTC's version; its cubin beside it,
/// [`cubin_path`]).
fn cache_entry(
    o: &KernelOptions,
    dir: Option<PathBuf>,
) -> Result<(String, Vec<String>, Option<PathBuf>), String> {
    if !nvrtc_available() {
        return Err(NO_NVRTC.into());
    }
    let src = program_source(o.f64)?;
    let opts = nvrtc_options(o);
    let mut h = fnv1a(src.as_bytes(), 0xcbf2_9ce4_8422_2325);
    h = fnv1a(opts.join(" ").as_bytes(), h);
    h = fnv1a(format!("{:?}", nvrtc_version()).as_bytes(), h);
    let path = dir.map(|d| d.join(format!("{h:016x}.ptx")));
    Ok((src, opts, path))
}

/// NVRTC's PTX and cubin of `src`, both written into the cache at `path` (the cubin beside the
/// PTX; best effort, each written atomically through a temporary file).
fn compile_and_keep(
    src: &str,
    opts: Vec<String>,
    path: Option<&std::path::Path>,
) -> Result<Compiled, String> {
    let compiled = nvrtc(src, "rtmpm_pipeline.cu", opts)?;
    if let Some(p) = path {
        if let Some(d) = p.parent() {
            let _ = std::fs::create_dir_all(d);
        }
        keep(p, compiled.ptx.as_bytes());
        if let Some(cubin) = &compiled.cubin {
            keep(&cubin_path(p), cubin);
        }
    }
    Ok(compiled)
}

/// Where the cubin of the PTX cached at `ptx` is kept: beside it, `.cubin` for `.ptx`.
pub fn cubin_path(ptx: &std::path::Path) -> PathBuf {
    ptx.with_extension("cubin")
}

/// `bytes` written to `path` through a temporary file renamed over it (a reader never sees a
/// part); best effort.
fn keep(path: &std::path::Path, bytes: &[u8]) {
    let tmp = path.with_extension(format!("tmp{}", std::process::id()));
    if std::fs::write(&tmp, bytes).is_ok() {
        let _ = std::fs::rename(&tmp, path);
    }
}

const NO_NVRTC: &str = "libnvrtc.so.13 not found (pip install nvidia-cuda-nvrtc==13.0.*, or set RTMPM_NVRTC_LIB / LD_LIBRARY_PATH)";

/// Compile one more translation unit `text` (named `name`) against the kernel headers (its
/// `#include`s resolve in `kernels/` and the generated headers), without the pipeline: the
/// device-side checks of the tests (no cache).
pub fn compile_unit(name: &str, text: &str, o: &KernelOptions) -> Result<String, String> {
    if !nvrtc_available() {
        return Err(NO_NVRTC.into());
    }
    let mut src = String::new();
    if o.f64 {
        src.push_str("#define RTMPM_F64\n");
    }
    expand_text(name, text, &mut HashSet::new(), &mut src)?;
    Ok(nvrtc(&src, name, nvrtc_options(o))?.ptx)
}

/// What NVRTC made of a program: its PTX and, for a real architecture (`sm_XX`, which the
/// pipeline always names), its cubin, the machine code the driver loads as it is.
pub struct Compiled {
    /// The PTX (what the tests read, and what the driver compiles again on load).
    pub ptx: String,
    /// The cubin; `None` where NVRTC gave none.
    pub cubin: Option<Vec<u8>>,
}

/// NVRTC: `src` to PTX (and cubin, where NVRTC made one).
fn nvrtc(src: &str, name: &str, opts: Vec<String>) -> Result<Compiled, String> {
    std::panic::catch_unwind(|| nvrtc_run(src, name, &opts))
        .map_err(|_| "NVRTC panicked (library missing?)".to_string())?
}

/// One NVRTC program: created, compiled with `opts`, its PTX and cubin read, destroyed.
fn nvrtc_run(src: &str, name: &str, opts: &[String]) -> Result<Compiled, String> {
    use cudarc::nvrtc::result;
    let c_src = std::ffi::CString::new(src).map_err(|_| "a NUL byte in the kernel source")?;
    let c_name = std::ffi::CString::new(name).map_err(|_| "a NUL byte in the program name")?;
    let prog =
        result::create_program(&c_src, Some(&c_name)).map_err(|e| format!("NVRTC error: {e:?}"))?;
    // SAFETY: `prog` was just created and is destroyed once, below, after its last use.
    let out = unsafe {
        match result::compile_program(prog, opts) {
            Err(_) => {
                let log = result::get_program_log(prog)
                    .map(|l| {
                        std::ffi::CStr::from_ptr(l.as_ptr())
                            .to_string_lossy()
                            .into_owned()
                    })
                    .unwrap_or_default();
                eprintln!("NVRTC compilation failed (options {opts:?}):\n{log}");
                Err(format!("NVRTC compilation failed:\n{log}"))
            }
            Ok(()) => result::get_ptx(prog)
                .map_err(|e| format!("NVRTC error: {e:?}"))
                .map(|ptx| Compiled {
                    ptx: std::ffi::CStr::from_ptr(ptx.as_ptr())
                        .to_string_lossy()
                        .into_owned(),
                    cubin: cubin_of(prog),
                }),
        }
    };
    // SAFETY: as above; nothing reads `prog` after this.
    let _ = unsafe { result::destroy_program(prog) };
    out
}

/// The cubin NVRTC made of the compiled `prog` (`None` for a virtual architecture).
///
/// # Safety
/// `prog` is a compiled program not yet destroyed.
unsafe fn cubin_of(prog: cudarc::nvrtc::sys::nvrtcProgram) -> Option<Vec<u8>> {
    use cudarc::nvrtc::sys;
    let mut size = 0usize;
    // SAFETY: `prog` compiled (the caller); `size` and the buffer outlive the calls.
    unsafe {
        if sys::nvrtcGetCUBINSize(prog, &mut size) != sys::nvrtcResult::NVRTC_SUCCESS || size == 0 {
            return None;
        }
        let mut cubin = vec![0u8; size];
        (sys::nvrtcGetCUBIN(prog, cubin.as_mut_ptr().cast()) == sys::nvrtcResult::NVRTC_SUCCESS)
            .then_some(cubin)
    }
}

#[cfg(test)]
mod ptx_tests;
