//! The switch of a batch's uploads back to pageable memory ([`pageable_puts`]); the page-locked
//! ring they go through is [`crate::staging::StagingRing`].

/// Puts go to the device from pageable memory, as before the page-locked upload
/// (`RTMPM_BATCH_PAGEABLE_PUT=1`; for comparing the two: bench/python_batch_gpu.py). Read once.
pub(super) fn pageable_puts() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| std::env::var("RTMPM_BATCH_PAGEABLE_PUT").is_ok_and(|v| v.trim() == "1"))
}
