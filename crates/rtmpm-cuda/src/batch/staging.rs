//! The switches of a batch's puts: its uploads back to pageable memory ([`pageable_puts`]), its
//! resets back to packing and uploading the initial particles ([`old_resets`]); the page-locked
//! ring the uploads go through is [`crate::staging::StagingRing`].

/// Puts go to the device from pageable memory, as before the page-locked upload
/// (`RTMPM_BATCH_PAGEABLE_PUT=1`; for comparing the two: bench/python_batch_gpu.py). Read once.
pub(super) fn pageable_puts() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| std::env::var("RTMPM_BATCH_PAGEABLE_PUT").is_ok_and(|v| v.trim() == "1"))
}

/// `RTMPM_BATCH_RESET=old`: resets to the initial state pack and upload the worlds' particles
/// as before the image kept on the device ([`super::CudaBatch::keep_initial`] keeps nothing);
/// for comparing the two in one binary (bench/python_batch_gpu.py). Read once.
pub fn old_resets() -> bool {
    static OLD: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *OLD.get_or_init(|| std::env::var("RTMPM_BATCH_RESET").is_ok_and(|v| v.trim() == "old"))
}
