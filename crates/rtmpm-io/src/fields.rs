//! The fields derived from the particle state that output frames carry next to it.

/// Optional per-particle fields written next to the particle state in output frames. They are
/// computed by the caller (e.g. from the material model); each slice, when present, must have
/// one entry per particle.
#[derive(Clone, Copy, Debug, Default)]
pub struct FrameFields<'a> {
    /// Cauchy stress per particle, symmetric, stored as `[xx, yy, zz, xy, yz, xz]` (Pa).
    pub stress: Option<&'a [[f32; 6]]>,
    /// Volume ratio `J = det F` per particle.
    pub jacobian: Option<&'a [f32]>,
}

impl FrameFields<'_> {
    /// Check that every present field has `n` entries.
    pub(crate) fn check_len(&self, n: usize) -> std::io::Result<()> {
        let bad = |what: &str, len: usize| {
            Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!("{what} has {len} entries, expected {n} (one per particle)"),
            ))
        };
        match self.stress {
            Some(s) if s.len() != n => return bad("stress", s.len()),
            _ => {}
        }
        match self.jacobian {
            Some(j) if j.len() != n => return bad("jacobian", j.len()),
            _ => {}
        }
        Ok(())
    }
}
