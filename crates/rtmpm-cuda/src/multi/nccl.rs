//! NCCL, loaded at run time (like the driver and NVRTC): the default build needs no NCCL, and
//! [`library`] says why NCCL is unusable instead of panicking.
//!
//! Only the calls the multi-GPU backend needs: unique id, communicator per rank, all-reduce,
//! all-gather. The library is searched in `RTMPM_NCCL_LIB`, then by soname (`libnccl.so.2`,
//! through `LD_LIBRARY_PATH` and the system paths), then in the `nvidia-nccl-cu13` Python wheel
//! (`site-packages/nvidia/nccl/lib`).

use std::ffi::{c_char, c_int, c_void};
use std::path::PathBuf;
use std::sync::OnceLock;

/// `ncclUniqueId`: 128 opaque bytes made by rank 0 and sent to every other rank.
#[repr(C)]
#[derive(Clone, Copy)]
pub struct UniqueId {
    /// The bytes.
    pub internal: [c_char; 128],
}

impl UniqueId {
    /// As bytes (to send through a rendezvous).
    pub fn to_bytes(&self) -> [u8; 128] {
        self.internal.map(|c| c as u8)
    }
    /// From bytes received through a rendezvous.
    pub fn from_bytes(b: &[u8; 128]) -> UniqueId {
        UniqueId {
            internal: b.map(|c| c as c_char),
        }
    }
}

type Comm = *mut c_void;
type Stream = *mut c_void;

/// `ncclDataType_t` values used here.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(i32)]
pub enum DataType {
    /// ncclUint8.
    U8 = 1,
    /// ncclUint32.
    U32 = 3,
    /// ncclFloat32.
    F32 = 7,
    /// ncclFloat64.
    F64 = 8,
}

/// `ncclRedOp_t` values used here.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(i32)]
pub enum RedOp {
    /// ncclSum.
    Sum = 0,
    /// ncclMax.
    Max = 2,
}

/// The loaded library: function pointers of the NCCL C API.
pub struct Nccl {
    _lib: libloading::Library,
    /// Where it was loaded from.
    pub path: String,
    /// `ncclGetVersion` result, e.g. 22807 for 2.28.7.
    pub version: i32,
    get_unique_id: unsafe extern "C" fn(*mut UniqueId) -> c_int,
    comm_init_rank: unsafe extern "C" fn(*mut Comm, c_int, UniqueId, c_int) -> c_int,
    comm_destroy: unsafe extern "C" fn(Comm) -> c_int,
    all_reduce: unsafe extern "C" fn(
        *const c_void,
        *mut c_void,
        usize,
        c_int,
        c_int,
        Comm,
        Stream,
    ) -> c_int,
    all_gather:
        unsafe extern "C" fn(*const c_void, *mut c_void, usize, c_int, Comm, Stream) -> c_int,
    error_string: unsafe extern "C" fn(c_int) -> *const c_char,
}

fn candidates() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = Vec::new();
    if let Ok(p) = std::env::var("RTMPM_NCCL_LIB") {
        v.push(p.into());
    }
    v.push("libnccl.so.2".into());
    v.push("libnccl.so".into());
    // The nvidia-nccl-cu13 / -cu12 Python wheels (PyTorch's NCCL).
    for root in [
        "/opt/torch/.venv/lib",
        "/usr/local/lib",
        "/usr/lib",
        "/opt/conda/lib",
    ] {
        let Ok(dir) = std::fs::read_dir(root) else {
            continue;
        };
        for e in dir.flatten() {
            let name = e.file_name().to_string_lossy().to_string();
            if !name.starts_with("python3") {
                continue;
            }
            for sp in ["site-packages", "dist-packages"] {
                let p = e.path().join(sp).join("nvidia/nccl/lib/libnccl.so.2");
                if p.exists() {
                    v.push(p);
                }
            }
        }
    }
    v
}

fn load() -> Result<Nccl, String> {
    let mut tried = Vec::new();
    for c in candidates() {
        // SAFETY: loading libnccl runs its initialisers, which only set up NCCL's own state.
        let lib = match unsafe { libloading::Library::new(&c) } {
            Ok(l) => l,
            Err(_) => {
                tried.push(c.display().to_string());
                continue;
            }
        };
        let path = c.display().to_string();
        // SAFETY: the symbols have the C signatures of nccl.h (NCCL 2.x).
        unsafe {
            macro_rules! sym {
                ($name:literal) => {
                    *lib.get($name)
                        .map_err(|e| format!("{path}: missing symbol: {e}"))?
                };
            }
            let get_version: unsafe extern "C" fn(*mut c_int) -> c_int = sym!(b"ncclGetVersion\0");
            let mut version = 0;
            get_version(&mut version);
            if version < 21800 {
                return Err(format!(
                    "{path}: NCCL {version} is too old (need 2.18 or newer)"
                ));
            }
            let n = Nccl {
                get_unique_id: sym!(b"ncclGetUniqueId\0"),
                comm_init_rank: sym!(b"ncclCommInitRank\0"),
                comm_destroy: sym!(b"ncclCommDestroy\0"),
                all_reduce: sym!(b"ncclAllReduce\0"),
                all_gather: sym!(b"ncclAllGather\0"),
                error_string: sym!(b"ncclGetErrorString\0"),
                version,
                path,
                _lib: lib,
            };
            return Ok(n);
        }
    }
    Err(format!(
        "NCCL not found (tried {}): install NCCL 2.18+ (e.g. pip install nvidia-nccl-cu13) and set \
         RTMPM_NCCL_LIB=/path/to/libnccl.so.2 or LD_LIBRARY_PATH",
        tried.join(", ")
    ))
}

/// The NCCL library, loaded once; `Err` says why it cannot be used. Never panics.
pub fn library() -> Result<&'static Nccl, String> {
    static LIB: OnceLock<Result<Nccl, String>> = OnceLock::new();
    LIB.get_or_init(load).as_ref().map_err(Clone::clone)
}

impl Nccl {
    fn check(&self, what: &str, r: c_int) -> Result<(), String> {
        if r == 0 {
            return Ok(());
        }
        // SAFETY: ncclGetErrorString returns a static C string.
        let msg = unsafe {
            let p = (self.error_string)(r);
            if p.is_null() {
                String::new()
            } else {
                std::ffi::CStr::from_ptr(p).to_string_lossy().to_string()
            }
        };
        Err(format!("NCCL {what} failed: {msg} (code {r})"))
    }

    /// A new unique id (rank 0 makes it, every rank needs it).
    pub fn unique_id(&self) -> Result<UniqueId, String> {
        let mut id = UniqueId { internal: [0; 128] };
        // SAFETY: out-parameter of the right size.
        let r = unsafe { (self.get_unique_id)(&mut id) };
        self.check("ncclGetUniqueId", r)?;
        Ok(id)
    }
}

/// One rank's communicator (`ncclComm_t`), destroyed on drop. The CUDA context of the rank's GPU
/// must be current on the calling thread for every call.
pub struct Communicator {
    nccl: &'static Nccl,
    comm: Comm,
    /// This rank.
    pub rank: usize,
    /// Number of ranks.
    pub ranks: usize,
}

// SAFETY: an NCCL communicator may be used from any thread, one call at a time (we own it).
unsafe impl Send for Communicator {}

impl Communicator {
    /// `ncclCommInitRank`: blocks until every rank has called it with the same id.
    pub fn init(id: &UniqueId, rank: usize, ranks: usize) -> Result<Communicator, String> {
        let nccl = library()?;
        let mut comm: Comm = std::ptr::null_mut();
        // SAFETY: out-parameter; the id is passed by value as in nccl.h.
        let r = unsafe { (nccl.comm_init_rank)(&mut comm, ranks as c_int, *id, rank as c_int) };
        nccl.check("ncclCommInitRank", r)?;
        Ok(Communicator {
            nccl,
            comm,
            rank,
            ranks,
        })
    }

    /// Enqueue an all-reduce of `count` elements on `stream` (in place when `send == recv`).
    ///
    /// # Safety
    /// `send` and `recv` must be device pointers of this rank's GPU holding `count` elements of
    /// `dtype`, valid until the stream has run the operation.
    pub unsafe fn all_reduce(
        &self,
        send: u64,
        recv: u64,
        count: usize,
        dtype: DataType,
        op: RedOp,
        stream: cudarc::driver::sys::CUstream,
    ) -> Result<(), String> {
        // SAFETY: see the function's contract.
        let r = unsafe {
            (self.nccl.all_reduce)(
                send as *const c_void,
                recv as *mut c_void,
                count,
                dtype as c_int,
                op as c_int,
                self.comm,
                stream as Stream,
            )
        };
        self.nccl.check("ncclAllReduce", r)
    }

    /// Enqueue an all-gather: every rank sends `count` elements, receives `ranks * count`.
    ///
    /// # Safety
    /// As [`Communicator::all_reduce`], with `recv` holding `ranks * count` elements.
    pub unsafe fn all_gather(
        &self,
        send: u64,
        recv: u64,
        count: usize,
        dtype: DataType,
        stream: cudarc::driver::sys::CUstream,
    ) -> Result<(), String> {
        // SAFETY: see the function's contract.
        let r = unsafe {
            (self.nccl.all_gather)(
                send as *const c_void,
                recv as *mut c_void,
                count,
                dtype as c_int,
                self.comm,
                stream as Stream,
            )
        };
        self.nccl.check("ncclAllGather", r)
    }
}

impl Drop for Communicator {
    fn drop(&mut self) {
        // SAFETY: the communicator is ours and no longer used.
        unsafe { (self.nccl.comm_destroy)(self.comm) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loading_nccl_never_panics() {
        match library() {
            Ok(n) => println!("NCCL {} from {}", n.version, n.path),
            Err(e) => {
                assert!(e.contains("RTMPM_NCCL_LIB"), "{e}");
                println!("NCCL unavailable: {e}");
            }
        }
    }

    #[test]
    fn unique_id_bytes_round_trip() {
        let mut b = [0u8; 128];
        for (i, x) in b.iter_mut().enumerate() {
            *x = (i * 7 + 200) as u8;
        }
        assert_eq!(UniqueId::from_bytes(&b).to_bytes(), b);
    }
}
