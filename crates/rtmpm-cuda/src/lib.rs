//! rtmpm CUDA backend.
