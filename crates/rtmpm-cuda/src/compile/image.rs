//! What the backend loads of the compiled pipeline: NVRTC's cubin for the GPU's architecture,
//! kept in the cache beside the PTX, rather than the PTX, which the driver compiles again to
//! machine code every time a process loads it (unless the driver's own cache holds it): 15 and
//! 30 s for the two kernel sets of a batch benchmark on an H200 with that cache off
//! (`CUDA_CACHE_DISABLE=1`, bench/logs/h200x2-2026-11-30-session15/call2.sh), on top of
//! NVRTC's own compile, which already made the same machine code.
//! `RTMPM_KERNEL_IMAGE=ptx` loads the PTX as before (for comparisons in one binary).

use super::{KernelOptions, cache_dir, cache_entry, compile, compile_and_keep, cubin_path};
use std::path::PathBuf;

/// The compiled pipeline as the driver loads it.
pub enum Image {
    /// NVRTC's machine code for the GPU's architecture: loaded as it is.
    Cubin(Vec<u8>),
    /// PTX: compiled again by the driver on load.
    Ptx(String),
}

impl Image {
    /// The image for [`cudarc::driver::CudaContext::load_module`].
    pub fn into_module_source(self) -> cudarc::nvrtc::Ptx {
        match self {
            Image::Cubin(bytes) => cudarc::nvrtc::Ptx::from_binary(bytes),
            Image::Ptx(text) => cudarc::nvrtc::Ptx::from_src(text),
        }
    }

    /// `"cubin"` or `"PTX"` (for messages).
    pub fn kind(&self) -> &'static str {
        match self {
            Image::Cubin(_) => "cubin",
            Image::Ptx(_) => "PTX",
        }
    }
}

/// `RTMPM_KERNEL_IMAGE=ptx`: the backend loads the PTX (the driver compiles it on load), as
/// before the cubin was kept. Read once.
pub fn ptx_switch() -> bool {
    static PTX: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *PTX.get_or_init(|| std::env::var("RTMPM_KERNEL_IMAGE").is_ok_and(|v| v.trim() == "ptx"))
}

/// A cubin as NVRTC writes one: an ELF file (its magic number; a file cut short or not a cubin
/// is compiled again rather than given to the driver).
fn looks_like_cubin(bytes: &[u8]) -> bool {
    bytes.len() > 64 && bytes.starts_with(b"\x7fELF")
}

/// The pipeline compiled for `o` as the backend loads it: the cubin from the cache, or compiled
/// (PTX and cubin then both kept in the cache); the PTX with `RTMPM_KERNEL_IMAGE=ptx` or where
/// NVRTC made no cubin. Errors carry the NVRTC log.
pub fn compile_image(o: &KernelOptions) -> Result<Image, String> {
    if ptx_switch() {
        return compile(o).map(Image::Ptx);
    }
    compile_image_in(o, cache_dir())
}

/// [`compile_image`] with the cache in `dir` (none: no cache).
fn compile_image_in(o: &KernelOptions, dir: Option<PathBuf>) -> Result<Image, String> {
    let (src, opts, path) = cache_entry(o, dir)?;
    if let Some(p) = &path
        && let Ok(bytes) = std::fs::read(cubin_path(p))
        && looks_like_cubin(&bytes)
    {
        return Ok(Image::Cubin(bytes));
    }
    let compiled = compile_and_keep(&src, opts, path.as_deref())?;
    Ok(match compiled.cubin {
        Some(c) if looks_like_cubin(&c) => Image::Cubin(c),
        _ => Image::Ptx(compiled.ptx),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// NVRTC gives a cubin for the pipeline (an ELF file, for sm_90 as the backend asks), both
    /// it and the PTX land in the cache, and a second call reads the cubin from there, byte
    /// for byte (the compile is not run again: the cached file is what comes back, shown by
    /// altering it); a damaged cubin in the cache is compiled again, not handed to the driver.
    /// The pipeline of one material model (a smaller program than every model's: the same
    /// path through NVRTC and the cache in less compile time).
    fn o() -> KernelOptions {
        KernelOptions {
            materials: 1,
            ..KernelOptions::all_models((9, 0), true, false)
        }
    }

    #[test]
    fn the_cubin_is_compiled_kept_and_read_back() {
        if !crate::compile::nvrtc_available() {
            println!("skipped: libnvrtc.so.13 not found");
            return;
        }
        let dir = std::env::temp_dir().join(format!("rtmpm-cubin-test-{}", std::process::id()));
        let cached = || compile_image_in(&o(), Some(dir.clone()));
        let first = cached().expect("compile");
        let Image::Cubin(cubin) = first else {
            panic!("NVRTC gave no cubin for sm_90");
        };
        assert!(looks_like_cubin(&cubin));
        let (_, _, path) = cache_entry(&o(), Some(dir.clone())).expect("entry");
        let ptx_path = path.expect("a cache folder");
        assert!(ptx_path.exists(), "the PTX kept");
        let kept = std::fs::read(cubin_path(&ptx_path)).expect("the cubin kept");
        assert_eq!(kept, cubin);
        // Mark the kept cubin (past its header): a second call returns the file.
        let mut marked = kept.clone();
        let last = marked.len() - 1;
        marked[last] ^= 0xff;
        std::fs::write(cubin_path(&ptx_path), &marked).expect("write");
        match cached().expect("from the cache") {
            Image::Cubin(c) => assert_eq!(c, marked, "not read from the cache"),
            Image::Ptx(_) => panic!("PTX instead of the kept cubin"),
        }
        // A file cut short is compiled again (and kept whole).
        std::fs::write(cubin_path(&ptx_path), &kept[..16]).expect("write");
        match cached().expect("compiled again") {
            Image::Cubin(c) => assert_eq!(c, cubin),
            Image::Ptx(_) => panic!("PTX instead of a fresh cubin"),
        }
        assert_eq!(std::fs::read(cubin_path(&ptx_path)).expect("kept"), cubin);
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A program NVRTC refuses comes back as an error with NVRTC's log (the line and what is
    /// wrong), not a panic or an empty image.
    #[test]
    fn a_program_nvrtc_refuses_comes_back_with_its_log() {
        if !crate::compile::nvrtc_available() {
            println!("skipped: libnvrtc.so.13 not found");
            return;
        }
        let r = crate::compile::compile_unit(
            "broken.cu",
            "int f() { return undeclared_name; }\n",
            &o(),
        );
        let Err(e) = r else {
            panic!("NVRTC compiled a program with an undeclared name");
        };
        assert!(e.contains("NVRTC compilation failed"), "{e}");
        assert!(
            e.contains("undeclared_name"),
            "the log names what is wrong: {e}"
        );
    }
}
