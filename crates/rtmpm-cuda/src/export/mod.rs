//! The particle state of a [`CudaBackend`] for other libraries: where it lives on the device
//! (zero-copy export through DLPack / `__cuda_array_interface__` by the Python package), fast
//! reads of single fields, and writes of positions, velocities, C and F between steps.
//!
//! Layout (see [`crate::state`]): one buffer, word `w` of the particle stored at slot `i` at
//! `w * stride + i`, a word being an f32 (an f64 with `precision = "f64"`), each field at the
//! words of the backend's [`StateLayout`] ([`DeviceParticles::layout`]); the material id and the
//! original index are integer bits in the low 32 bits of their word. The slots are in the
//! backend's storage order, which changes at every rebuild (particles are sorted by block and
//! cell); the layout's `id()` word gives each slot's original particle index.

pub mod chunks;
pub mod ordered;

use crate::backend::CudaBackend;
use crate::contract::*;
use crate::error::err;
use crate::waits::WaitReason;
use cudarc::driver::{DevicePtr, PinnedHostSlice};
use rtmpm_sim::{ParticleEdit, SimError};

/// Where the particle state of a [`CudaBackend`] is, for zero-copy views.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeviceParticles {
    /// CUDA device ordinal (the arrays live in its primary context).
    pub device: usize,
    /// Device address of the state buffer (field 0 of slot 0).
    pub ptr: u64,
    /// Number of particles (valid slots `0..n` of every field).
    pub n: usize,
    /// Distance between two fields, in words (the particle capacity, at least `n`).
    pub stride: usize,
    /// Bytes of one word: 4 (f32) or 8 (f64).
    pub word_bytes: usize,
    /// Which words hold which field.
    pub layout: StateLayout,
}

impl DeviceParticles {
    /// Device address of word `field` (a word of [`DeviceParticles::layout`]).
    pub fn field_ptr(&self, field: usize) -> u64 {
        self.ptr + (field * self.stride * self.word_bytes) as u64
    }
}

impl CudaBackend {
    /// Pinned host memory of at least `need` bytes (reused; grown when too small).
    pub(crate) fn pinned(&mut self, need: usize) -> Result<&mut PinnedHostSlice<u8>, SimError> {
        if self.staging.pinned.as_ref().is_none_or(|s| s.len() < need) {
            self.staging.pinned = None;
            // SAFETY: the memory is written by the copies before it is read. Plain page-locked
            // memory (not write-combined: the host reads it).
            let buf = unsafe {
                self.stream
                    .context()
                    .alloc_pinned_with_flags::<u8>(need.max(1), 0)
            }
            .map_err(err("allocate pinned memory"))?;
            self.staging.pinned = Some(buf);
        }
        self.staging
            .pinned
            .as_mut()
            .ok_or_else(|| SimError::Backend("CUDA: no staging memory".into()))
    }
}

impl CudaBackend {
    /// Where the particle state is on the device. Waits for the queued work first, so the
    /// arrays are complete when this returns. The address stays valid for the backend's life
    /// (rebuilds sort the particles in place).
    pub fn device_particles(&mut self) -> Result<DeviceParticles, SimError> {
        self.waits
            .wait(WaitReason::Sync, || self.stream.synchronize())
            .map_err(err("synchronize"))?;
        Ok(DeviceParticles {
            device: self.stream.context().ordinal(),
            ptr: self.buffers.state.device_ptr(&self.stream).0,
            n: self.n,
            stride: self.ctx.cap as usize,
            word_bytes: crate::state::word_bytes(self.options.f64),
            layout: self.layout,
        })
    }

    /// Wait for all work on the device context, this backend's and other libraries' (e.g.
    /// PyTorch reading the arrays of [`CudaBackend::device_particles`] on its own stream), so
    /// that a step does not overwrite arrays still being read.
    pub fn wait_for_device(&self) -> Result<(), SimError> {
        self.waits
            .wait(WaitReason::Sync, || self.stream.context().synchronize())
            .map_err(err("synchronize the context"))
    }

    /// Copy the words `fields` (words of the backend's [`StateLayout`]) of the `n` particles,
    /// in storage order, to pinned host memory and return them as raw little-endian words (`n` words of
    /// [`DeviceParticles::word_bytes`] each, one slice per field). Synchronises.
    pub fn read_fields(&mut self, fields: &[usize]) -> Result<Vec<&[u8]>, SimError> {
        let wb = crate::state::word_bytes(self.options.f64);
        let (n, cap) = (self.n, self.ctx.cap as usize);
        let row = n * wb;
        let need = row * fields.len();
        let words = self.layout.words();
        if fields.iter().any(|&f| f >= words) {
            return Err(SimError::Backend(format!(
                "CUDA: field index out of range (0..{words})"
            )));
        }
        self.pinned(need)?;
        let (stream, state) = (self.stream.clone(), &self.buffers.state);
        let srcs: Vec<_> = fields
            .iter()
            .map(|&f| state.slice(f * cap * wb..f * cap * wb + row))
            .collect();
        let Some(staging) = self.staging.pinned.as_mut() else {
            return Err(SimError::Backend("CUDA: no staging memory".into()));
        };
        let all = staging.as_mut_slice().map_err(err("pinned memory"))?;
        for (k, src) in srcs.iter().enumerate() {
            stream
                .memcpy_dtoh(src, &mut all[k * row..(k + 1) * row])
                .map_err(err("read particle fields"))?;
        }
        // The copies into pinned memory are asynchronous: wait for them before the host reads.
        self.waits
            .wait(WaitReason::Read, || stream.synchronize())
            .map_err(err("synchronize"))?;
        let all: &[u8] = all;
        Ok((0..fields.len())
            .map(|k| &all[k * row..(k + 1) * row])
            .collect())
    }

    /// Overwrite the columns `edit` gives (positions, velocities, APIC's C, F; original order,
    /// f32, widened exactly in f64; C rounded to the compact format in a compact layout, a
    /// fluid's F kept as J^(1/3) I) of every particle, keeping the rest of each particle's
    /// state; the next step rebuilds the mapping (and, with G2P2G, redoes its P2G) from them.
    /// Synchronises.
    pub fn write_fields(&mut self, edit: &ParticleEdit) -> Result<(), SimError> {
        let n = self.n;
        edit.check_lengths(n)?;
        if edit.is_empty() {
            return Ok(());
        }
        let wb = crate::state::word_bytes(self.options.f64);
        let l = self.layout;
        let (ids, material): (Vec<usize>, Vec<u32>) = {
            let rows = self.read_fields(&[l.id(), l.material()])?;
            let word = |row: &[u8], i: usize| {
                u32::from_le_bytes(row[i * wb..i * wb + 4].try_into().unwrap_or([0; 4]))
            };
            (0..n)
                .map(|i| (word(rows[0], i) as usize, word(rows[1], i)))
                .unzip()
        };
        let fluid = crate::state::fluid_materials(&self.scene);
        let rows = crate::state::edit_rows(edit, &ids, &material, &fluid, l, self.options.f64)
            .map_err(SimError::Backend)?;
        let cap = self.ctx.cap as usize;
        for (word, row) in &rows {
            let at = word * cap * wb;
            let mut dst = self.buffers.state.slice_mut(at..at + n * wb);
            self.stream
                .memcpy_htod(row.as_slice(), &mut dst)
                .map_err(err("write particle fields"))?;
        }
        self.set_ctl_word(CTL_NEED_REBUILD, 1)?;
        if self.g2p2g() {
            self.set_ctl_word(CTL_P2G_PENDING, 1)?;
        }
        if let Some(v) = edit.v {
            let max = v.iter().map(|v| v.length()).fold(0.0f32, f32::max);
            self.set_ctl_word(CTL_MAX_SPEED, max.to_bits())?;
        }
        self.stream.synchronize().map_err(err("synchronize"))
    }
}
