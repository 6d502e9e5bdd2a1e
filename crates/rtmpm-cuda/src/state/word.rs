//! One word of the device state in either precision: an f32, or an f64 (kernels compiled with
//! `RTMPM_F64`), read and written as little-endian bytes; integer fields (the material, the
//! original index) are the bits of the low 32 bits of their word.

/// One word of the device state.
pub(super) trait Word: Copy + Default {
    const BYTES: usize;
    fn from_f32(x: f32) -> Self;
    fn from_id(bits: u32) -> Self;
    fn read(bytes: &[u8]) -> Self;
    /// Write the word's little-endian bytes at the start of `out`.
    fn put(self, out: &mut [u8]);
    fn to_f32(self) -> f32;
    fn to_f64(self) -> f64;
    fn id(self) -> u32;
}

impl Word for f32 {
    const BYTES: usize = 4;
    fn from_f32(x: f32) -> Self {
        x
    }
    fn from_id(bits: u32) -> Self {
        f32::from_bits(bits)
    }
    fn read(b: &[u8]) -> Self {
        f32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }
    fn put(self, out: &mut [u8]) {
        out[..Self::BYTES].copy_from_slice(&self.to_le_bytes());
    }
    fn to_f32(self) -> f32 {
        self
    }
    fn to_f64(self) -> f64 {
        self as f64
    }
    fn id(self) -> u32 {
        self.to_bits()
    }
}

impl Word for f64 {
    const BYTES: usize = 8;
    fn from_f32(x: f32) -> Self {
        x as f64
    }
    fn from_id(bits: u32) -> Self {
        f64::from_bits(bits as u64)
    }
    fn read(b: &[u8]) -> Self {
        f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]])
    }
    fn put(self, out: &mut [u8]) {
        out[..Self::BYTES].copy_from_slice(&self.to_le_bytes());
    }
    fn to_f32(self) -> f32 {
        self as f32
    }
    fn to_f64(self) -> f64 {
        self
    }
    fn id(self) -> u32 {
        self.to_bits() as u32
    }
}
