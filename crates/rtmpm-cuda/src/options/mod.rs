//! The switches of the CUDA backend (`--cuda-options`, parsed by [`CudaOptions`]'s `FromStr`): the
//! ablation switches of the principles of Fei, Huang & Gao's "Real-Time Simulation of MPM on Modern
//! GPUs" (GTC 2022), the P2G strategy, capacities, the kernels' instruction switches, several GPUs
//! (`multi`: transport, barrier, exchange, partition) and batches of worlds (`batch`).

mod batch;
mod kernels;
mod multi;

pub use batch::BodyPoses;
pub use kernels::{
    CkP2g, DEFAULT_FUSED_DEFAULTS, DEFAULT_RMAP_REPLICAS, DEFAULT_SORT_SCRATCH_FIELDS, FusedCode,
    FusedDefaults, FusedSwitches, KernelCuts, KernelSet, P2gMode, RowUnroll,
};
pub use multi::{BarrierKind, ExchangeMode, PartitionKind, Transport};

/// Ablation switches of the principles of Fei, Huang & Gao (GTC 2022). `Default` = all on.
#[derive(Clone, Debug, PartialEq)]
pub struct CudaOptions {
    /// Rebuild the mapping only when a particle leaves its free zone (else every step).
    pub free_zone: bool,
    /// Mixed sorting: in-warp cell sort between rebuilds. Off: complete sort (rebuild) every step.
    pub mixed_sort: bool,
    /// Warp-level segmented reduction in P2G (off: every lane issues its own atomics).
    pub warp_reduce: bool,
    /// P2G variant.
    pub p2g: P2gMode,
    /// CK-MPM's P2G kernel (whatever `p2g`, which names the MLS-MPM variants).
    pub ck_p2g: CkP2g,
    /// CK-MPM's warp-scatter kernels (`g2p2g_ck`, `p2g_ck_warp`) held to this many resident
    /// blocks of 128 threads a SM (`__launch_bounds__(128, N)`: at most 65536 / (128 N)
    /// registers a thread; `ck_bound=N`, 0: ptxas's own choice). `None` (the default): the fused
    /// `g2p2g_ck` held to 5 blocks in f32 (measured faster on an H200, bench/RESULTS.md), ptxas's
    /// choice in f64 and for `p2g_ck_warp` (`kernels/ck.cuh`).
    pub ck_min_blocks: Option<u32>,
    /// CK-MPM's fused kernel `g2p2g_ck` launched as the blocks resident at once (occupancy
    /// API), each looping over the warp list (`ck_grid=resident`, `Some(true)`), or as one wave
    /// of 2048 threads a SM (`ck_grid=wave`, `Some(false)`). `None` (the default): resident in
    /// f32, one wave in f64 (not timed there), as MLS-MPM's fused kernels.
    pub ck_resident_grid: Option<bool>,
    /// `p2g=reverse_map`: number of replicated maps (the paper's nine by default).
    pub rmap_replicas: usize,
    /// `p2g=reverse_map`: entries per node and map; `None`: twice the initial largest node load.
    pub rmap_slots: Option<usize>,
    /// `p2g=reverse_map`: pblocks the maps cover; `None`: four times the initial pblocks.
    pub rmap_pblocks: Option<usize>,
    /// `--use_fast_math`.
    pub fast_math: bool,
    /// Capture one step in a CUDA graph and replay it (used while dt stays fixed).
    pub graph: bool,
    /// Double precision: the whole pipeline in f64 (also set by the scene's
    /// `[solver] precision = "f64"`).
    pub f64: bool,
    /// Capacity overrides (gblocks, pblocks); `None`: from the initial layout with headroom.
    pub gblock_capacity: Option<usize>,
    /// See `gblock_capacity`.
    pub pblock_capacity: Option<usize>,
    /// Several GPUs: blocks the shared-block reduction holds (`None`: from the partition, grown
    /// at frame ends).
    pub shared_capacity: Option<usize>,
    /// Several GPUs: re-partition the particles at a frame end when they have drifted.
    pub rebalance: bool,
    /// Several GPUs: overlap the shared-block reduction with work that does not need it: the
    /// P2G of the interior gblocks (separate P2G) and the grid update of the pblocks no other
    /// GPU shares (off: P2G, the reduction, then the grid update). `None`: off with
    /// transport=p2p and the spin barrier (measured slower on with 2 H200s: docs/multi-gpu.md,
    /// "The defaults of two GPUs"), on otherwise. Resolved when a multi-GPU backend is made.
    pub overlap: Option<bool>,
    /// Several GPUs of one process: transport of the shared-block reduction (`None`: p2p when
    /// every pair of GPUs has peer access, else NCCL).
    pub transport: Option<Transport>,
    /// Several GPUs with `transport=p2p`: the synchronisation (`None`: spin).
    pub barrier: Option<BarrierKind>,
    /// Several GPUs with `transport=p2p` and the spin barrier: the kernels of the shared-block
    /// list and sum (`exchange=kernels|fused|push|push_update|list_push_update`; `None`: `push` with transport=p2p and the
    /// spin barrier, `kernels` otherwise; `fused` and `push` asked for are refused with NCCL,
    /// the events barrier and one process per GPU). Resolved when a multi-GPU backend is made.
    pub exchange: Option<ExchangeMode>,
    /// Several GPUs: how the particles are split between them (`partition=slabs|boxes`;
    /// default slabs along the longest axis), at the start and at every re-partition.
    pub partition: PartitionKind,
    /// Several GPUs of one process: the CUDA device of each rank (`devices=0:1`; `None`: rank i
    /// on device i). A device may be named more than once, to run the multi-GPU code on fewer
    /// GPUs (tests on one GPU: `devices=0:0`); ranks sharing a device run transport=p2p with
    /// the events barrier only (the spin kernels of two ranks on one device could wait on
    /// each other forever, and NCCL refuses two ranks on one device).
    pub devices: Option<Vec<usize>>,
    /// The rebuild as one persistent kernel with grid-wide barriers (`rb_fused`, one launch per
    /// step) instead of fifteen kernels that return at once when nothing is rebuilt.
    pub fused_rebuild: bool,
    /// G2P2G: the G2P of a step and the P2G of the next in one kernel (`kernels/g2p/g2p2g.cu`),
    /// the P2G kernel running only after a rebuild. One or several GPUs; MLS transfer (CK-MPM:
    /// with `ck_p2g=fused`, its default), `p2g=warp`, the free zone and mixed sorting only (not when every
    /// step rebuilds); elsewhere ignored.
    pub g2p2g: bool,
    /// Compile the kernels for the scene's material models only (a smaller material switch in
    /// the merged kernels) instead of every model of the registry. Off by default: measured on
    /// the H100 (bench/RESULTS.md) it made snow 2 % faster and jelly 8 % slower (ptxas gives the
    /// smaller G2P2G 96 registers and spills).
    pub specialize: bool,
    /// Fields of the particle state that the rebuild's sort permutes per pass (1 to
    /// the state layout's words): the scratch holds that many words per particle instead of a second copy of
    /// the state. Fewer: less memory, more passes (two grid barriers each) when the mapping is
    /// rebuilt. The result is the same for every value.
    pub sort_scratch_fields: usize,
    /// Rigid bodies (`[[rigid_body]]`): move the bodies while the GPU runs the next step (the
    /// bodies then see the material's impulses one step late) instead of waiting for every
    /// step's impulses before the next step is queued (`crate::step::rigid`).
    pub rigid_overlap: bool,
    /// A backend built from sampled bodies (`CudaBackend::from_bodies`): the device writes the
    /// particle state from the uploaded positions and a per-body table (`crate::setup::fill`) instead
    /// of the host packing the whole state image and uploading it (`fill=host`, kept for
    /// comparison). The state is the same word for word.
    pub device_fill: bool,
    /// With the device fill: bodies of shapes (box, sphere, cylinder, mesh; regular, jittered
    /// or random) are only counted on the host and their positions drawn on the device
    /// (`crate::setup::sample`; the same positions bit for bit), so the host holds no memory per
    /// particle of theirs; `sample=host` walks and uploads them as before (for comparison).
    pub device_sample: bool,
    /// Scenes whose materials are all fluids keep the 20-word fluid state
    /// ([`crate::contract::StateLayout::Fluid`]: F in one word, no plastic word) instead of
    /// the 29-word one; the results are bit-identical. Off: the 29-word layout (for comparison).
    pub fluid_state: bool,
    /// The compact particle state (APIC C in shared-exponent words, the velocity f32;
    /// [`crate::state::codec`]; single precision only); also set by the scene's
    /// `[solver] particle_state = "compact"`.
    pub compact_state: bool,
    /// A batch of worlds (`crate::batch::CudaBatch`) whose bodies are all kinematic or fixed
    /// (no sum moves them): each step's sums of the reaction on the bodies stay on the device
    /// until a load is read (one copy then, of the last step's), instead of a copy to the host
    /// after every step (`body_sums=step`, kept for comparison). The loads are the same bit for
    /// bit. A batch with a dynamic body copies and waits for every step's sums either way.
    pub batch_sums_at_read: bool,
    /// Stencil node addressing of the G2P gather and the warp scatter (`addressing=pairs|blocks`):
    /// `true` (`pairs`, the default) the node indices per row of three nodes, the node's offset in
    /// the loads' and atomics' immediate offsets (`kernels/stencil.cuh`: `stencil_pairs`;
    /// `RTMPM_G2P_GATHER=2`, `RTMPM_P2G_NODES=2`); `false` (`blocks`) the addressing before
    /// it, node by node (`stencil_blocks`; `=1`). The same nodes and the same sums bit for bit,
    /// fewer instructions; kept to compare the two in one binary.
    pub stencil_pairs: bool,
    /// A batch of worlds: when a pose given to one body of many worlds
    /// (`crate::batch::CudaBatch::set_body_poses`, Python's `set_rigid_body`) goes into its
    /// world's rapier world ([`BodyPoses`]).
    pub batch_poses: BodyPoses,
    /// A batch of worlds with rigid bodies (`body_upload=turns|serial`): the steps read two
    /// body tables in turn, each step's rows copied into its table on a stream of their own
    /// while the step before runs (`turns`, the default; `crate::batch::CudaBatch`'s bodies),
    /// or one table, the copy on the batch's stream before the step, serial with the kernels
    /// (`serial`, as before; also `RTMPM_BATCH_UPLOAD=old` in the environment). Each step reads
    /// the same records either way.
    pub batch_body_turns: bool,
    /// The fused G2P2G kernels' warp loop over warp-uniform values (`uniform_loop=on|off`,
    /// default on; `kernels/g2p/g2p2g.cu`: `RTMPM_G2P2G_UNIFORM`): the error flag by a vote, the
    /// warp count and the first entry by warp reductions, so that ptxas drops its divergence
    /// checks before every shuffle. The same arithmetic bit for bit, fewer instructions; `off`
    /// keeps the loop before it, to compare the two in one binary.
    pub uniform_loop: bool,
    /// The fused kernels' code switches, resolved per kernel set when the backend compiles its
    /// program ([`FusedSwitches::resolve`], [`KernelSet`]; `fused_defaults=off|auto` for the
    /// switches left out, `off` by default): the warp scatter's rows of three nodes unrolled
    /// (`row_unroll=off|planes|all`; `kernels/p2g/warp.cuh`: `RTMPM_P2G_UNROLL`; `Off` a loop
    /// over the nine rows, `Planes` the three rows of a plane unrolled, `All` all nine: the same
    /// arithmetic bit for bit, fewer instructions issued for a larger kernel); the instruction
    /// cuts ([`KernelCuts`]); the particle state's word index in 64 bits always
    /// (`state_index=wide`; `auto`: 32 bits unless the arrays hold 2^32 words or more; the same
    /// words, each field's address one multiply-add from the previous one; `kernels/common.cuh`:
    /// `sidx`, `RTMPM_STATE_64`).
    pub fused: FusedSwitches,
    /// Programmatic dependent launch (`pdl=on|off`, default off until measured): the step's
    /// kernels after its first (P2G, the grid update, G2P / G2P2G) launched with the attribute
    /// `CU_LAUNCH_ATTRIBUTE_PROGRAMMATIC_STREAM_SERIALIZATION`, so that a kernel's blocks are
    /// scheduled while the kernel before it drains; each of them waits (`griddepcontrol.wait`,
    /// `kernels/common.cuh`: `step_kernel_entry`) before it touches device memory. Compiled in
    /// (`-DRTMPM_PDL`) only on a GPU of compute capability 9.0 or newer; on an older GPU it is
    /// ignored with a warning. On several GPUs the same kernels of each GPU's step; the
    /// exchange's own kernels keep plain launches. The same arithmetic in the same order: the
    /// results are those of `pdl=off`.
    pub pdl: bool,
}

impl Default for CudaOptions {
    fn default() -> Self {
        CudaOptions {
            free_zone: true,
            mixed_sort: true,
            warp_reduce: true,
            p2g: P2gMode::Warp,
            ck_p2g: CkP2g::Fused,
            ck_min_blocks: None,
            ck_resident_grid: None,
            rmap_replicas: DEFAULT_RMAP_REPLICAS,
            rmap_slots: None,
            rmap_pblocks: None,
            fast_math: true,
            graph: true,
            f64: false,
            gblock_capacity: None,
            pblock_capacity: None,
            shared_capacity: None,
            rebalance: true,
            overlap: None,
            transport: None,
            barrier: None,
            exchange: None,
            partition: PartitionKind::Slabs,
            devices: None,
            fused_rebuild: true,
            g2p2g: true,
            specialize: false,
            sort_scratch_fields: DEFAULT_SORT_SCRATCH_FIELDS,
            rigid_overlap: true,
            device_fill: true,
            device_sample: true,
            fluid_state: true,
            compact_state: false,
            batch_sums_at_read: true,
            stencil_pairs: true,
            batch_poses: BodyPoses::Deferred,
            batch_body_turns: true,
            uniform_loop: true,
            fused: FusedSwitches::default(),
            pdl: false,
        }
    }
}

impl std::str::FromStr for CudaOptions {
    type Err = String;
    /// Comma separated `key=value`: `free_zone`, `mixed_sort`, `warp_reduce`, `fast_math`,
    /// `graph`, `f64`, `rebalance`, `overlap`, `g2p2g`, `rigid_overlap`, `specialize` (on/off/true/false/1/0), `rebuild` (fused/kernels), `fill` (device/host), `p2g`
    /// (warp/shared/reverse_map/sort), `ck_p2g` (direct/warp/fused), `ck_bound` (0 to 16 blocks),
    /// `ck_grid` (wave/resident), `transport` (p2p/nccl), `barrier` (spin/events), `exchange` (kernels/fused/push/push_update/list_push_update), `partition` (slabs/boxes), `devices`
    /// (ordinals separated by `:`), `gblocks`, `pblocks`, `rmap_replicas`, `rmap_slots`,
    /// `rmap_pblocks`, `shared`, `sort_fields` (counts), `fluid_state` (on/off), `state`
    /// (f32/compact), `body_sums` (read/step), `addressing` (pairs/blocks), `uniform_loop` (on/off),
    /// `body_poses` (deferred/deferred_serial/eager), `body_upload` (turns/serial),
    /// `row_unroll` (off/planes/all),
    /// `lean_lanes`, `seg_clamp`, `flat_checks` (on/off), `zero_terms` (skip/keep),
    /// `state_index` (auto/wide), `fused_defaults` (off/auto: the last six when left out),
    /// `pdl` (on/off).
    fn from_str(s: &str) -> Result<Self, String> {
        let mut o = CudaOptions::default();
        for item in s.split(',').map(str::trim).filter(|t| !t.is_empty()) {
            let (k, v) = item
                .split_once('=')
                .ok_or_else(|| format!("`{item}`: expected key=value"))?;
            let b = || match v {
                "on" | "true" | "1" | "yes" => Ok(true),
                "off" | "false" | "0" | "no" => Ok(false),
                _ => Err(format!("`{item}`: expected on/off")),
            };
            let n = || v.parse::<usize>().map_err(|e| format!("`{item}`: {e}"));
            match k {
                "free_zone" => o.free_zone = b()?,
                "mixed_sort" => o.mixed_sort = b()?,
                "warp_reduce" => o.warp_reduce = b()?,
                "fast_math" => o.fast_math = b()?,
                "graph" => o.graph = b()?,
                "f64" => o.f64 = b()?,
                "p2g" => {
                    o.p2g = match v {
                        "warp" => P2gMode::Warp,
                        "shared" => P2gMode::Shared,
                        "reverse_map" => P2gMode::ReverseMap,
                        "sort" => P2gMode::Sort,
                        _ => {
                            return Err(format!(
                                "`{item}`: expected warp, shared, reverse_map or sort"
                            ));
                        }
                    }
                }
                "ck_p2g" => {
                    o.ck_p2g = choice(
                        item,
                        v,
                        &[
                            ("direct", CkP2g::Direct),
                            ("warp", CkP2g::Warp),
                            ("fused", CkP2g::Fused),
                        ],
                    )?
                }
                "ck_bound" => {
                    let blocks = n()? as u32;
                    o.ck_min_blocks = Some(blocks);
                    if blocks > 16 {
                        return Err(format!(
                            "`{item}`: expected 0 (no bound) to 16 blocks of 128 threads a SM"
                        ));
                    }
                }
                "ck_grid" => {
                    o.ck_resident_grid =
                        Some(choice(item, v, &[("wave", false), ("resident", true)])?)
                }
                "gblocks" => o.gblock_capacity = Some(n()?),
                "pblocks" => o.pblock_capacity = Some(n()?),
                "rmap_replicas" => {
                    o.rmap_replicas = n()?;
                    if o.rmap_replicas == 0 {
                        return Err(format!("`{item}`: at least 1 map"));
                    }
                }
                "rmap_slots" => o.rmap_slots = Some(n()?),
                "rmap_pblocks" => o.rmap_pblocks = Some(n()?),
                "shared" => o.shared_capacity = Some(n()?),
                "rebalance" => o.rebalance = b()?,
                "g2p2g" => o.g2p2g = b()?,
                "rigid_overlap" => o.rigid_overlap = b()?,
                "specialize" => o.specialize = b()?,
                "overlap" => o.overlap = Some(b()?),
                "fluid_state" => o.fluid_state = b()?,
                "state" => {
                    o.compact_state = match v {
                        "f32" => false,
                        "compact" => true,
                        _ => return Err(format!("`{item}`: expected f32 or compact")),
                    }
                }
                "sort_fields" => {
                    let k = n()?;
                    if !(1..=crate::contract::MAX_FIELDS).contains(&k) {
                        return Err(format!(
                            "`{item}`: expected 1 to {} fields",
                            crate::contract::MAX_FIELDS
                        ));
                    }
                    o.sort_scratch_fields = k;
                }
                "body_sums" => {
                    o.batch_sums_at_read = choice(item, v, &[("read", true), ("step", false)])?
                }
                "uniform_loop" => o.uniform_loop = b()?,
                "pdl" => o.pdl = b()?,
                "lean_lanes" => o.fused.lean_lanes = Some(b()?),
                "seg_clamp" => o.fused.seg_clamp = Some(b()?),
                "flat_checks" => o.fused.flat_checks = Some(b()?),
                "zero_terms" => {
                    o.fused.zero_terms = Some(choice(item, v, &[("skip", true), ("keep", false)])?)
                }
                "state_index" => {
                    o.fused.wide_state_index =
                        Some(choice(item, v, &[("wide", true), ("auto", false)])?)
                }
                "fused_defaults" => {
                    o.fused.defaults = choice(
                        item,
                        v,
                        &[("off", FusedDefaults::Off), ("auto", FusedDefaults::Auto)],
                    )?
                }
                "row_unroll" => {
                    o.fused.row_unroll = Some(choice(
                        item,
                        v,
                        &[
                            ("off", RowUnroll::Off),
                            ("planes", RowUnroll::Planes),
                            ("all", RowUnroll::All),
                        ],
                    )?)
                }
                "addressing" => {
                    o.stencil_pairs = choice(item, v, &[("pairs", true), ("blocks", false)])?
                }
                "body_poses" => {
                    o.batch_poses = choice(
                        item,
                        v,
                        &[
                            ("deferred", BodyPoses::Deferred),
                            ("deferred_serial", BodyPoses::DeferredSerial),
                            ("eager", BodyPoses::Eager),
                        ],
                    )?
                }
                "body_upload" => {
                    o.batch_body_turns = choice(item, v, &[("turns", true), ("serial", false)])?
                }
                "fill" => o.device_fill = choice(item, v, &[("device", true), ("host", false)])?,
                "sample" => {
                    o.device_sample = choice(item, v, &[("device", true), ("host", false)])?
                }
                "rebuild" => {
                    o.fused_rebuild = choice(item, v, &[("fused", true), ("kernels", false)])?
                }
                "transport" => {
                    o.transport = Some(match v {
                        "p2p" => Transport::P2p,
                        "nccl" => Transport::Nccl,
                        _ => return Err(format!("`{item}`: expected p2p or nccl")),
                    })
                }
                "barrier" => {
                    o.barrier = Some(match v {
                        "spin" => BarrierKind::Spin,
                        "events" => BarrierKind::Events,
                        _ => return Err(format!("`{item}`: expected spin or events")),
                    })
                }
                "exchange" => {
                    o.exchange = Some(choice(
                        item,
                        v,
                        &[
                            ("kernels", ExchangeMode::Kernels),
                            ("fused", ExchangeMode::Fused),
                            ("push", ExchangeMode::Push),
                            ("push_update", ExchangeMode::PushUpdate),
                            ("list_push_update", ExchangeMode::ListPushUpdate),
                        ],
                    )?)
                }
                "partition" => {
                    o.partition = choice(
                        item,
                        v,
                        &[
                            ("slabs", PartitionKind::Slabs),
                            ("boxes", PartitionKind::Boxes),
                        ],
                    )?
                }
                "devices" => {
                    let d = v
                        .split(':')
                        .map(|x| x.trim().parse::<usize>())
                        .collect::<Result<Vec<_>, _>>()
                        .map_err(|e| {
                            format!("`{item}`: expected device ordinals separated by `:` ({e})")
                        })?;
                    o.devices = Some(d);
                }
                _ => return Err(format!("unknown CUDA option `{k}`")),
            }
        }
        Ok(o)
    }
}

/// The value of `names` called `v` (the option `item`), or an error that lists the names.
fn choice<T: Copy>(item: &str, v: &str, names: &[(&str, T)]) -> Result<T, String> {
    if let Some((_, t)) = names.iter().find(|(n, _)| *n == v) {
        return Ok(*t);
    }
    let list: Vec<&str> = names.iter().map(|(n, _)| *n).collect();
    Err(match list.split_last() {
        Some((last, rest)) if !rest.is_empty() => {
            format!("`{item}`: expected {} or {last}", rest.join(", "))
        }
        _ => format!("`{item}`: expected {}", list.join("")),
    })
}

#[cfg(test)]
mod tests;
