//! The switches of a batch of worlds (`crate::batch`).

/// When the poses given to a body of a batch's worlds go into their rapier worlds
/// (`--cuda-options body_poses=...`). The worlds go through the same setter calls in the same
/// order either way: the same state bit for bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BodyPoses {
    /// `deferred` (the default): kept until the next step's upload (or a read that needs them),
    /// which puts them in on every core.
    Deferred,
    /// `deferred_serial`: kept as with `Deferred`, put in on one thread (for comparison).
    DeferredSerial,
    /// `eager`: put in at once, on the caller's thread (as before the kept poses; for
    /// comparison).
    Eager,
}
