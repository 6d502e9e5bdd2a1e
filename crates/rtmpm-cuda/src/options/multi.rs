//! The switches of several GPUs: the transport of the shared-block reduction, the barrier, the
//! exchange's kernels and the partition of the particles.

/// Several GPUs of one process: how the shared blocks are summed across GPUs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transport {
    /// Each GPU's kernel reads the peers' packed shared blocks through peer pointers (Fei et al.).
    P2p,
    /// NCCL all-reduce.
    Nccl,
}

/// Several GPUs with `transport=p2p`: the inter-GPU synchronisation of a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BarrierKind {
    /// The spin-lock barrier of Fei, Huang & Gao (GTC 2022): a one-block kernel with
    /// system-scope atomics.
    Spin,
    /// Events: every GPU's stream waits on the peers' events (no CUDA graph).
    Events,
}

/// Several GPUs of one process with `transport=p2p` and the spin barrier: how the shared
/// blocks are listed and summed in a step (`exchange=`; docs/multi-gpu.md, "exchange=").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ExchangeMode {
    /// Separate kernels (the only mode of NCCL, the events barrier and one process per GPU):
    /// eight launches for the shared list (seven return at once in a step without a rebuild),
    /// then pack, barrier and the sum of peer reads.
    #[default]
    Kernels,
    /// The shared list in one cooperative kernel with the inter-GPU barrier inside it; the sum
    /// as `Kernels`.
    Fused,
    /// `Fused`, and the sum pushed: each GPU writes its nodes of the shared blocks it holds
    /// into the inboxes of the other GPUs that hold them (16-byte remote stores), arrives at
    /// their counters, waits on its own and sums its inbox (two launches, no peer reads). The
    /// default with transport=p2p and the spin barrier.
    Push,
    /// `Push`, with the inbox summed inside the grid update (`push_update`): the push, then
    /// one kernel that updates the pblocks no other GPU holds, waits on its own counter and
    /// sums and updates the shared ones (one launch and one pass over the shared nodes less
    /// than `Push`, no second stream). Runs without the overlap (its kernel overlaps the wait
    /// with the unshared pblocks itself).
    PushUpdate,
    /// `PushUpdate`, with the shared list and the push in one cooperative kernel after the
    /// step's P2G (`list_push_update`; without the overlap P2G needs no list): one launch less
    /// than `PushUpdate`.
    ListPushUpdate,
}

impl ExchangeMode {
    /// True for the modes that push the shared nodes into the holders' inboxes (`push`,
    /// `push_update`): they need the holders of every shared block and an inbox per GPU.
    pub fn pushes(self) -> bool {
        matches!(
            self,
            ExchangeMode::Push | ExchangeMode::PushUpdate | ExchangeMode::ListPushUpdate
        )
    }

    /// True for the modes that sum the inbox inside the grid update (`push_update`,
    /// `list_push_update`): no second stream, no overlap.
    pub fn sums_in_update(self) -> bool {
        matches!(
            self,
            ExchangeMode::PushUpdate | ExchangeMode::ListPushUpdate
        )
    }
}

/// Several GPUs: how the particles are split between them (`partition=`;
/// `crate::multi::partition`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PartitionKind {
    /// Slabs of equal count along the longest axis of the particles' bounding box.
    #[default]
    Slabs,
    /// Boxes of equal count cut along up to three axes: of every way to factor the GPU count
    /// into pieces per axis, the one whose worst piece shares the least cut area (the same as
    /// `Slabs` at 2 GPUs; at 4, 2 x 2 where a middle slab would share two whole faces).
    Boxes,
}
