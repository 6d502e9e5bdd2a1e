//! The compile module's tests: every kernel through NVRTC (sm_90 and sm_80, f32 and f64, every
//! compile-time variant) and the properties of the PTX the options must give (the defines of the
//! switches, the exchange kernels' 16-byte moves, launch bounds, node atomics, unfused positions).

use super::*;

fn compile_fresh(o: &KernelOptions) -> Result<String, String> {
    // Bypass the cache so a syntax error always fails.
    // SAFETY: tests in this module run this with a private folder; other tests don't read it.
    let dir = std::env::temp_dir().join(format!("rtmpm-nvrtc-test-{}", std::process::id()));
    unsafe { std::env::set_var("RTMPM_CACHE_DIR", &dir) };
    let r = compile(o);
    let _ = std::fs::remove_dir_all(&dir);
    r
}

/// True when NVRTC can be loaded; else prints why the test is skipped (CI installs NVRTC and
/// sets RTMPM_REQUIRE_NVRTC=1: there a missing library fails).
fn nvrtc_or_skip() -> bool {
    if nvrtc_available() {
        return true;
    }
    assert!(
        std::env::var_os("RTMPM_REQUIRE_NVRTC").is_none(),
        "RTMPM_REQUIRE_NVRTC is set but libnvrtc.so.13 cannot be loaded"
    );
    println!("skipped: libnvrtc.so.13 not found (pip install nvidia-cuda-nvrtc==13.0.*)");
    false
}

/// Every entry point of the Kernel enum is in `ptx` (`what` names the variant).
fn assert_every_kernel(ptx: &str, what: &str) {
    for k in crate::kernels::Kernel::ALL {
        assert!(
            ptx.contains(&format!(".entry {}(", k.name())),
            "{what}: {} missing from PTX",
            k.name()
        );
    }
}

#[test]
fn every_kernel_compiles_with_nvrtc_for_sm90() {
    if !nvrtc_or_skip() {
        return;
    }
    use crate::contract::StateLayout;
    let variants = [
        (true, false, false, StateLayout::Full),
        (false, false, false, StateLayout::Full),
        (true, true, false, StateLayout::Full),
        (false, true, false, StateLayout::Full),
        (true, false, true, StateLayout::Full),
        (true, false, false, StateLayout::Fluid),
        (true, true, false, StateLayout::Fluid),
        (true, false, true, StateLayout::Fluid),
        (true, false, false, StateLayout::Compact),
        (true, false, false, StateLayout::CompactFluid),
        (false, false, true, StateLayout::CompactFluid),
    ];
    // The first four (fast math on and off, f32 and f64) are compiled as the backend compiles
    // them, optimised, and their PTX is checked op by op; the others (state indices, state
    // layouts) with NVRTC's `--Ofast-compile=max`, which compiles every kernel through the same
    // front end in a fraction of the time (about 0.5 s against 19 s of CPU a variant on CI's
    // machine) but leaves PTX that the op checks do not apply to. The variants compile on
    // every core at once (NVRTC compiles separate programs in parallel), every thread taking
    // every n-th variant so that the optimised ones spread over the threads.
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    std::thread::scope(|scope| {
        for t in 0..threads.min(variants.len()) {
            scope.spawn(move || {
                for (i, &v) in variants.iter().enumerate().skip(t).step_by(threads) {
                    check_variant(v, i < 4);
                }
            });
        }
    });
}

/// The compile-time variants of the fused step (`kernels/p2g/warp.cuh`,
/// `kernels/g2p/particle.cuh`; the defaults, which the test above compiles, are
/// RTMPM_P2G_REDUCE=1, RTMPM_G2P_GATHER=2, RTMPM_P2G_NODES=2) compile in
/// f32 and f64 with every kernel, alone and together, so that turning one on is a one-line
/// change. Front end only (`--Ofast-compile=max`), on every core at once.
#[test]
fn the_compile_time_kernel_variants_compile() {
    if !nvrtc_or_skip() {
        return;
    }
    let variants: &[&[&str]] = &[
        &["-DRTMPM_P2G_REDUCE=0"],
        &["-DRTMPM_P2G_REDUCE=4"],
        &["-DRTMPM_G2P_GATHER=0"],
        &["-DRTMPM_P2G_NODES=0"],
        // The stencil-block addressing before the pair addressing (`addressing=blocks`).
        &["-DRTMPM_G2P_GATHER=1", "-DRTMPM_P2G_NODES=1"],
        &["-DRTMPM_G2P_GATHER=1"],
        &["-DRTMPM_P2G_NODES=1"],
        // The fused kernels' warp loop before the warp-uniform one (`uniform_loop=off`), alone
        // and with the block addressing (main's kernels before both).
        &["-DRTMPM_G2P2G_UNIFORM=0"],
        &[
            "-DRTMPM_G2P2G_UNIFORM=0",
            "-DRTMPM_G2P_GATHER=1",
            "-DRTMPM_P2G_NODES=1",
        ],
        &["-DRTMPM_P2G_ROUNDS_MAX=3"],
        &["-DRTMPM_P2G_REDUCE=4", "-DRTMPM_P2G_ROUNDS_MAX=3"],
        &["-DRTMPM_P2G_UNROLL=1"],
        &["-DRTMPM_P2G_UNROLL=2"],
        // The second round of instruction cuts (`KernelCuts`), alone, together, and with the
        // unrolled rows (whose compile-time row indices the zero terms use).
        &["-DRTMPM_G2P2G_LEAN_LANES=1"],
        &["-DRTMPM_P2G_SEG_CLAMP=1"],
        &["-DRTMPM_P2G_ZERO_TERMS=1"],
        &["-DRTMPM_G2P_FLAT_CHECKS=1"],
        &[
            "-DRTMPM_G2P2G_LEAN_LANES=1",
            "-DRTMPM_P2G_SEG_CLAMP=1",
            "-DRTMPM_P2G_ZERO_TERMS=1",
            "-DRTMPM_G2P_FLAT_CHECKS=1",
            "-DRTMPM_STATE_64",
        ],
        &["-DRTMPM_P2G_ZERO_TERMS=1", "-DRTMPM_P2G_UNROLL=1"],
        &["-DRTMPM_P2G_ZERO_TERMS=1", "-DRTMPM_P2G_UNROLL=2"],
        &["-DRTMPM_P2G_SEG_CLAMP=1", "-DRTMPM_P2G_REDUCE=0"],
        &["-DRTMPM_P2G_SEG_CLAMP=1", "-DRTMPM_P2G_REDUCE=4"],
        &["-DRTMPM_STATE_STREAM=1"],
        // The fused kernels' register bounds before 96 registers became the default.
        &["-DG2P2G_MIN_BLOCKS=0", "-DG2P2G_FLUID_MIN_BLOCKS=4"],
        // Many worlds in one set of arrays (crate::batch).
        &["-DRTMPM_BATCH"],
        // The node-by-node step as it was before the three became the default.
        &[
            "-DRTMPM_P2G_REDUCE=0",
            "-DRTMPM_G2P_GATHER=0",
            "-DRTMPM_P2G_NODES=0",
        ],
    ];
    let jobs: Vec<(bool, &[&str])> = [false, true]
        .into_iter()
        .flat_map(|f64| variants.iter().map(move |d| (f64, *d)))
        .collect();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    std::thread::scope(|scope| {
        for t in 0..threads.min(jobs.len()) {
            let jobs = &jobs;
            scope.spawn(move || {
                for &(f64, defines) in jobs.iter().skip(t).step_by(threads) {
                    let o = KernelOptions::all_models((9, 0), true, f64);
                    let mut opts = nvrtc_options(&o);
                    opts.extend(defines.iter().map(|d| d.to_string()));
                    opts.push("--Ofast-compile=max".into());
                    let what = format!("f64 {f64}, {defines:?}");
                    let ptx = program_source(f64)
                        .and_then(|src| nvrtc(&src, "rtmpm_pipeline.cu", opts).map(|c| c.ptx))
                        .unwrap_or_else(|e| panic!("{what}: {e}"));
                    assert_every_kernel(&ptx, &what);
                }
            });
        }
    });
}

/// The CUDA option that selects a kernel variant at compile time: `ck_bound=N` becomes
/// `-DCK_MIN_BLOCKS=N` on every architecture; left out, nothing is defined.
#[test]
fn the_ck_bound_option_becomes_a_define() {
    let mut o = KernelOptions::all_models((9, 0), true, false);
    assert!(
        !nvrtc_options(&o)
            .iter()
            .any(|d| d.contains("CK_MIN_BLOCKS"))
    );
    o.ck_min_blocks = Some(5);
    let v = nvrtc_options(&o);
    assert!(v.contains(&"-DCK_MIN_BLOCKS=5".to_string()), "{v:?}");
    o.arch = (8, 0);
    let v = nvrtc_options(&o);
    assert!(v.contains(&"-DCK_MIN_BLOCKS=5".to_string()), "{v:?}");
}

/// `addressing=blocks` becomes the defines of the stencil-block addressing,
/// `uniform_loop=off` that of the warp loop before it and `row_unroll=planes` that of the
/// unrolled rows; the defaults define nothing (the kernels' own defaults).
#[test]
fn the_addressing_option_becomes_defines() {
    let mut o = KernelOptions::all_models((9, 0), true, false);
    assert!(o.stencil_pairs);
    let v = nvrtc_options(&o);
    assert!(
        !v.iter()
            .any(|d| d.contains("RTMPM_G2P_GATHER") || d.contains("RTMPM_P2G_NODES")),
        "{v:?}"
    );
    o.stencil_pairs = false;
    let v = nvrtc_options(&o);
    assert!(v.contains(&"-DRTMPM_G2P_GATHER=1".to_string()), "{v:?}");
    assert!(v.contains(&"-DRTMPM_P2G_NODES=1".to_string()), "{v:?}");
    assert!(
        !v.iter().any(|d| d.contains("RTMPM_G2P2G_UNIFORM")),
        "{v:?}"
    );
    o.uniform_loop = false;
    let v = nvrtc_options(&o);
    assert!(v.contains(&"-DRTMPM_G2P2G_UNIFORM=0".to_string()), "{v:?}");
    assert!(!v.iter().any(|d| d.contains("RTMPM_P2G_UNROLL")), "{v:?}");
    o.row_unroll = crate::RowUnroll::Planes.define();
    let v = nvrtc_options(&o);
    assert!(v.contains(&"-DRTMPM_P2G_UNROLL=2".to_string()), "{v:?}");
}

/// Each instruction cut of `KernelCuts` becomes its own define, none by default.
#[test]
fn the_instruction_cuts_become_defines() {
    let mut o = KernelOptions::all_models((9, 0), true, false);
    let names = [
        "RTMPM_G2P2G_LEAN_LANES",
        "RTMPM_P2G_SEG_CLAMP",
        "RTMPM_P2G_ZERO_TERMS",
        "RTMPM_G2P_FLAT_CHECKS",
    ];
    let v = nvrtc_options(&o);
    assert!(
        !v.iter().any(|d| names.iter().any(|n| d.contains(n))),
        "{v:?}"
    );
    for (i, name) in names.iter().enumerate() {
        o.cuts = crate::options::KernelCuts {
            lean_lanes: i == 0,
            seg_clamp: i == 1,
            zero_terms: i == 2,
            flat_checks: i == 3,
        };
        let v = nvrtc_options(&o);
        let on: Vec<_> = v
            .iter()
            .filter(|d| names.iter().any(|n| d.contains(n)))
            .collect();
        assert_eq!(on, [&format!("-D{name}=1")], "{v:?}");
    }
}

/// The entry directives and the body of kernel `k` in `ptx` (up to its closing brace).
fn entry<'a>(ptx: &'a str, k: &str) -> &'a str {
    ptx.split(&format!(".entry {k}("))
        .nth(1)
        .and_then(|s| s.split("\n}\n").next())
        .unwrap_or_default()
}

/// The kernels of `exchange=fused|push` (`kernels/multi/reduce_shared.cu`), compiled alone
/// and optimised for sm_90 in f32 and f64: `sb_push` stores 16 bytes a thread into the
/// inboxes and arrives with system-scope atomics, `sb_gather` waits with a system-scope
/// acquire on its own counter and reads its inbox 16 bytes a thread past the L1, and so does
/// `grid_update_gather` (`exchange=push_update`), which also updates the nodes (their
/// velocities stored); `sb_list_fused` takes the spin barrier (a system-scope atomic and
/// acquire) inside it, and `sb_list_push` (`exchange=list_push_update`) both the barrier and
/// the push's 16-byte stores and arrivals.
#[test]
fn the_fused_and_pushed_exchange_kernels_move_16_bytes_a_thread() {
    if !nvrtc_or_skip() {
        return;
    }
    for f64 in [false, true] {
        let o = KernelOptions::all_models((9, 0), true, f64);
        let ptx = compile_unit(
            "exchange_check.cu",
            "#include \"multi/reduce_shared.cu\"\n",
            &o,
        )
        .unwrap_or_else(|e| panic!("f64 {f64}: {e}"));
        let v = if f64 { "v2.f64" } else { "v4.f32" };
        if std::env::var_os("RTMPM_DUMP_EXCHANGE_PTX").is_some() {
            for k in [
                "sb_push",
                "sb_gather",
                "grid_update_gather",
                "sb_list_fused",
                "sb_list_push",
            ] {
                println!("==== {k} ({v})\n{}", entry(&ptx, k));
            }
        }
        let push = entry(&ptx, "sb_push");
        // Global or generic (NVRTC run at the same time as the front-end-only compiles of
        // the other tests has left the stores generic): 16 bytes either way.
        assert!(
            push.contains(&format!("st.global.{v}")) || push.contains(&format!("st.{v}")),
            "sb_push, {v}"
        );
        assert!(push.contains("atom.global.sys.add.u64"), "sb_push");
        assert!(push.contains("membar.sys"), "sb_push");
        let gather = entry(&ptx, "sb_gather");
        assert!(
            gather.contains(&format!("ld.global.cg.{v}")),
            "sb_gather, {v}"
        );
        assert!(gather.contains("ld.acquire.sys.global.u64"), "sb_gather");
        let update = entry(&ptx, "grid_update_gather");
        assert!(
            update.contains(&format!("ld.global.cg.{v}")),
            "grid_update_gather, {v}"
        );
        assert!(
            update.contains("ld.acquire.sys.global.u64"),
            "grid_update_gather"
        );
        // Its blocks meet after the wait (the threads of a block read the inbox only then).
        assert!(update.contains("bar.sync"), "grid_update_gather");
        let list = entry(&ptx, "sb_list_fused");
        assert!(list.contains("ld.acquire.sys.global.u64"), "sb_list_fused");
        assert!(list.contains("atom.global.sys.add.u64"), "sb_list_fused");
        let both = entry(&ptx, "sb_list_push");
        assert!(
            both.contains(&format!("st.global.{v}")) || both.contains(&format!("st.{v}")),
            "sb_list_push, {v}"
        );
        assert!(both.contains("ld.acquire.sys.global.u64"), "sb_list_push");
        // The spin barrier's arrival and the push's arrivals at every GPU's counter.
        assert!(
            both.matches("atom.global.sys.add.u64").count() >= 2,
            "sb_list_push"
        );
        assert!(both.contains("membar.sys"), "sb_list_push");
    }
}

/// The kernels of `ck_bound=N` compile with NVRTC (front end only, on every core at once):
/// for sm_90 and sm_80, f32 and f64, CK-MPM's warp-scatter kernels carry the bound
/// (`.minnctapersm N`), by default 5 blocks for the fused `g2p2g_ck` in f32 and none
/// otherwise.
#[test]
fn the_ck_bound_kernels_compile() {
    if !nvrtc_or_skip() {
        return;
    }
    // (arch, f64, ck_bound); `None`: the kernels' default bound.
    type Job = ((i32, i32), bool, Option<u32>);
    let jobs: &[Job] = &[
        ((9, 0), false, None),
        ((9, 0), true, None),
        ((9, 0), false, Some(0)),
        ((9, 0), false, Some(6)),
        ((9, 0), true, Some(5)),
        ((8, 0), false, Some(5)),
    ];
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    std::thread::scope(|scope| {
        for t in 0..threads.min(jobs.len()) {
            scope.spawn(move || {
                for &(arch, f64, bound) in jobs.iter().skip(t).step_by(threads) {
                    let o = KernelOptions {
                        ck_min_blocks: bound,
                        ..KernelOptions::all_models(arch, true, f64)
                    };
                    let mut opts = nvrtc_options(&o);
                    opts.push("--Ofast-compile=max".into());
                    let what = format!("{o:?}");
                    let ptx = program_source(f64)
                        .and_then(|src| nvrtc(&src, "rtmpm_pipeline.cu", opts).map(|c| c.ptx))
                        .unwrap_or_else(|e| panic!("{what}: {e}"));
                    assert_every_kernel(&ptx, &what);
                    check_bound(&ptx, &o, &what);
                }
            });
        }
    });
}

/// The PTX checks of [`the_ck_bound_kernels_compile`]: the bound asked for, or by default 5
/// blocks for the fused `g2p2g_ck` in f32 and none otherwise.
fn check_bound(ptx: &str, o: &KernelOptions, what: &str) {
    let default_fused = if o.f64 { 0 } else { 5 };
    for (k, default) in [("g2p2g_ck", default_fused), ("p2g_ck_warp", 0)] {
        let blocks = o.ck_min_blocks.unwrap_or(default);
        let body = entry(ptx, k);
        assert_eq!(
            body.contains(&format!(".minnctapersm {blocks}")),
            blocks > 0,
            "{what}: {k}"
        );
        assert_eq!(body.contains(".minnctapersm"), blocks > 0, "{what}: {k}");
    }
}

/// The kernels that scatter (mass, momentum) into grid nodes through `atomic_add_node`
/// (`kernels/p2g/warp.cuh`; a node's four reals lie side by side, 16-byte aligned).
const NODE_SCATTER_KERNELS: [&str; 8] = [
    "p2g",
    "g2p2g",
    "g2p2g_fluid",
    "p2g_mpm",
    "p2g_musl",
    "p2g_ck",
    "p2g_ck_warp",
    "g2p2g_ck",
];

/// The atomic adds of kernel `k` in optimised PTX: (16-byte vector adds of f32, scalar adds of
/// `real`), global or generic.
fn node_atomics(ptx: &str, k: &str, real: &str) -> (usize, usize) {
    let body = ptx
        .split(&format!(".entry {k}("))
        .nth(1)
        .and_then(|s| s.split("\n}\n").next())
        .unwrap_or_default();
    let ops = |suffix: &str| {
        body.lines()
            .map(str::trim_start)
            .filter(|op| {
                (op.starts_with("atom.") || op.starts_with("red."))
                    && op
                        .split_whitespace()
                        .next()
                        .is_some_and(|o| o.ends_with(suffix))
            })
            .count()
    };
    (ops(".add.v4.f32"), ops(&format!(".add.{real}")))
}

/// Before Hopper (sm_80) every kernel compiles and the node scatter is four scalar atomics:
/// the 16-byte vector atomic add exists from sm_90 on. Front end only: there the node
/// function stays a call (its loop of four too), so its body is read.
#[test]
fn every_kernel_compiles_for_sm80_with_scalar_node_atomics() {
    if !nvrtc_or_skip() {
        return;
    }
    let mut opts = nvrtc_options(&KernelOptions::all_models((8, 0), true, false));
    opts.push("--Ofast-compile=max".into());
    let ptx = program_source(false)
        .and_then(|src| nvrtc(&src, "rtmpm_pipeline.cu", opts).map(|c| c.ptx))
        .unwrap_or_else(|e| panic!("sm_80: {e}"));
    assert_every_kernel(&ptx, "sm_80");
    assert!(!ptx.contains("atomicAddP6float4") && !ptx.contains(".add.v4.f32"));
    let node = ptx
        .split(".func _Z15atomic_add_nodePfPKf(")
        .nth(1)
        .and_then(|s| s.split("\n}\n").next())
        .unwrap_or_default();
    assert!(node.contains("_Z9atomicAddPff"), "{node}");
}

/// One variant of [`every_kernel_compiles_with_nvrtc_for_sm90`]: every kernel and the
/// constant symbols in its PTX; `optimised`: compiled as the backend does, and the device
/// fill and the device's walk of bodies rounded op by op.
fn check_variant(
    (fast_math, f64, state64, layout): (bool, bool, bool, crate::contract::StateLayout),
    optimised: bool,
) {
    {
        let o = KernelOptions {
            state64,
            layout,
            ..KernelOptions::all_models((9, 0), fast_math, f64)
        };
        let ptx = if optimised {
            compile_fresh(&o)
        } else {
            let mut opts = nvrtc_options(&o);
            opts.push("--Ofast-compile=max".into());
            program_source(o.f64)
                .and_then(|src| nvrtc(&src, "rtmpm_pipeline.cu", opts).map(|c| c.ptx))
        }
        .unwrap_or_else(|e| panic!("{o:?}: {e}"));
        assert_every_kernel(&ptx, &format!("{o:?}"));
        // Read-only parameters in constant memory, written by the host under these names.
        for sym in crate::kernels::CONSTANT_SYMBOLS {
            assert!(
                ptx.contains(&format!(" .b8 {sym}[")),
                "{o:?}: constant {sym} missing from PTX"
            );
        }
        if !optimised {
            return;
        }
        // The node scatter: one 16-byte vector atomic a node in f32 on sm_90 (ptxas 13.0
        // assembles it as one `REDG.E.ADD.F32x4`), four scalar ones in f64.
        let real = if f64 { "f64" } else { "f32" };
        for k in NODE_SCATTER_KERNELS {
            let (v4, scalar) = node_atomics(&ptx, k, real);
            let ok = if f64 {
                v4 == 0 && scalar > 0
            } else {
                v4 > 0 && scalar == 0
            };
            assert!(ok, "{o:?}: {k}: {v4} vector atomics, {scalar} scalar");
        }
        // The device fill rounds every operation on its own and keeps subnormals (the host
        // packing's arithmetic, word for word: src/setup/fill/mod.rs), also under fast math.
        let fill = ptx
            .split(".entry fill_body(")
            .nth(1)
            .and_then(|s| s.split(".entry ").next())
            .unwrap_or_default();
        assert!(fill.contains("sub.rn.f32"), "{o:?}: fill_body");
        assert!(
            !fill.contains("fma") && !fill.contains(".ftz"),
            "{o:?}: fill_body contracts or flushes"
        );
        // So does the device's walk of deferred bodies (kernels/sample.cuh: the host's walk,
        // bit for bit).
        for k in ["sample_count", "sample_write"] {
            // The entry's body: up to its closing brace (device functions may follow).
            let body = ptx
                .split(&format!(".entry {k}("))
                .nth(1)
                .and_then(|s| s.split("\n}\n").next())
                .unwrap_or_default();
            assert!(body.contains("mul.rn.f32"), "{o:?}: {k}");
            let bad: Vec<&str> = body
                .lines()
                .filter(|l| l.contains("fma") || l.contains(".ftz"))
                .collect();
            assert!(bad.is_empty(), "{o:?}: {k} contracts or flushes: {bad:?}");
        }
        for k in ["grid_update", "grid_update_gather"] {
            grid_update_positions_unfused(&ptx, k, real, &format!("{o:?}"));
        }
        // The put over the gblocks (kernels/batch.cu, put_slot_words) loads every word of a
        // slot but its id before it stores any (the put of every slot, a load then its store).
        let gblocks = longest_load_run(entry(&ptx, "batch_put_gblocks"));
        assert!(
            gblocks >= layout.words() - 1,
            "{o:?}: batch_put_gblocks: {gblocks} loads at most between stores"
        );
    }
}

/// The most global loads in `body` (PTX) with no global store between them.
fn longest_load_run(body: &str) -> usize {
    let (mut run, mut longest) = (0, 0);
    for op in body.lines().map(str::trim_start) {
        if op.starts_with("ld.global") {
            run += 1;
            longest = longest.max(run);
        } else if op.starts_with("st.global") {
            run = 0;
        }
    }
    longest
}

/// The grid update places its nodes as the CPU backend does (kernels/grid_update.cu:
/// node_position): no fused multiply-add takes a node index converted to a real (one
/// rounding instead of two puts a node on a collider's face on the other side of it).
/// `kernel`: the entry (`grid_update`, or `grid_update_gather` of `exchange=push_update`).
fn grid_update_positions_unfused(ptx: &str, kernel: &str, real: &str, what: &str) {
    // The entry and the node functions it calls where they stay calls (fast math, or
    // called from several kernels), each on its own: PTX names its registers per function.
    let mut bodies = vec![entry(ptx, kernel).to_string()];
    for f in ptx.split(".func ").skip(1) {
        let name = f.split(['(', ' ', '\n']).next().unwrap_or_default();
        let node = ["grid_update_node", "node_boundary", "grid_node_finish"];
        if f.starts_with(name)
            && f[name.len()..].starts_with('(')
            && node.iter().any(|n| name.contains(n))
        {
            bodies.push(f.split("\n}\n").next().unwrap_or_default().to_string());
        }
    }
    let cvt = format!("cvt.rn.{real}.s32");
    let tokens = |l: &str| -> Vec<String> {
        l.split(|c: char| c == ',' || c == ';' || c.is_whitespace())
            .filter(|t| !t.is_empty())
            .map(str::to_string)
            .collect()
    };
    let mut found = 0;
    for body in &bodies {
        let indices: Vec<String> = body
            .lines()
            .filter(|l| l.contains(&cvt))
            .filter_map(|l| tokens(l).get(1).cloned())
            .collect();
        found += indices.len();
        let fused: Vec<&str> = body
            .lines()
            .filter(|l| l.trim_start().starts_with("fma"))
            .filter(|l| tokens(l).iter().any(|t| indices.contains(t)))
            .collect();
        assert!(
            fused.is_empty(),
            "{what}: {kernel} fuses node positions: {fused:?}"
        );
    }
    assert!(found > 0, "{what}: no node index in {kernel}");
}

#[test]
fn state_indices_switch_to_64_bits_at_2_pow_32_words() {
    // 29 fields: 148,102,320 particles hold 4,294,967,280 words; one more passes 2^32.
    assert!(!state_needs_64_bits(29, 148_102_320));
    assert!(state_needs_64_bits(29, 148_102_321));
    assert!(state_needs_64_bits(29, 500_000_000));
    // 20 (fluid) and 15 (compact fluid) words.
    assert!(!state_needs_64_bits(20, 214_748_364));
    assert!(state_needs_64_bits(20, 214_748_365));
    assert!(!state_needs_64_bits(15, 286_331_153));
    assert!(state_needs_64_bits(15, 286_331_154));
    let o = KernelOptions {
        state64: true,
        ..KernelOptions::all_models((9, 0), true, false)
    };
    assert!(nvrtc_options(&o).contains(&"-DRTMPM_STATE_64".to_string()));
    assert!(
        !nvrtc_options(&KernelOptions::all_models((9, 0), true, false))
            .contains(&"-DRTMPM_STATE_64".to_string())
    );
}

#[test]
fn preprocessor_inlines_headers_once_with_line_directives() {
    let s = program_source(false).unwrap();
    assert_eq!(s.matches("#line 1 \"common.cuh\"").count(), 1);
    assert_eq!(s.matches("#line 1 \"contract.cuh\"").count(), 1);
    assert!(s.contains("#line 1 \"g2p/g2p.cu\""));
    assert!(!s.starts_with("#define RTMPM_F64"));
    assert!(
        program_source(true)
            .unwrap()
            .starts_with("#define RTMPM_F64")
    );
}

/// `pdl=on` becomes `-DRTMPM_PDL=1` only for compute capability 9.0 and newer; off by default.
#[test]
fn the_pdl_option_becomes_a_define_from_sm90_on() {
    let define = "-DRTMPM_PDL=1".to_string();
    let mut o = KernelOptions::all_models((9, 0), true, false);
    assert!(!o.pdl && !nvrtc_options(&o).contains(&define));
    o.pdl = true;
    assert!(nvrtc_options(&o).contains(&define));
    o.arch = (10, 0);
    assert!(nvrtc_options(&o).contains(&define));
    for arch in [(8, 0), (8, 6), (8, 9)] {
        o.arch = arch;
        assert!(!nvrtc_options(&o).contains(&define), "{arch:?}");
    }
    assert!(pdl_supported((9, 0)) && !pdl_supported((8, 9)));
}

/// The lines of `body` (a kernel's PTX) before its `griddepcontrol.wait` that touch memory
/// another kernel may write or read: loads other than of the kernel's parameters, constant
/// banks and the thread's own local memory (the copy of the parameters the kernel may make
/// there), stores other than to local memory, atomics and calls.
fn memory_ops_before_wait(body: &str) -> Vec<&str> {
    body.lines()
        .map(str::trim)
        .take_while(|l| !l.starts_with("griddepcontrol.wait"))
        .filter(|l| {
            let op = l.split_whitespace().next().unwrap_or_default();
            let private = [".param", ".const", ".local"]
                .iter()
                .any(|space| op.contains(space));
            ((op.starts_with("ld.") || op.starts_with("st.")) && !private)
                || op.starts_with("atom.")
                || op.starts_with("red.")
                || op.starts_with("call")
        })
        .collect()
}

/// The PTX function `step_kernel_entry` (`kernels/common.cuh`) as NVRTC's fast front end leaves
/// it, not inlined.
const ENTRY_FUNC: &str = "_Z17step_kernel_entryv";

/// With `pdl=on` for sm_90, f32, optimised as the backend compiles it: every kernel of
/// [`crate::kernels::PDL_KERNELS`] and `rb_fused` carries `griddepcontrol.wait` and
/// `griddepcontrol.launch_dependents`, the wait before any load, store, atomic or call that
/// another kernel's memory could be behind; no other kernel carries either (the host launches
/// only those with the attribute). f64 and the fluid layout (NVRTC's fast front end) compile
/// with both instructions, `-DRTMPM_PDL_TRIGGER=0` with the wait only. `pdl=off` on sm_90 and
/// `pdl=on` for sm_80 leave them out.
#[test]
fn with_pdl_the_step_kernels_wait_before_they_touch_memory() {
    if !nvrtc_or_skip() {
        return;
    }
    use crate::contract::StateLayout;
    use crate::kernels::{Kernel, PDL_KERNELS};
    let on = |arch, f64, layout| KernelOptions {
        pdl: true,
        layout,
        ..KernelOptions::all_models(arch, true, f64)
    };
    // (options, optimised, PDL expected in the PTX, the trigger: RTMPM_PDL_TRIGGER's default)
    let jobs = [
        (on((9, 0), false, StateLayout::Full), true, true, true),
        (on((9, 0), true, StateLayout::Full), false, true, true),
        (on((9, 0), false, StateLayout::Fluid), false, true, true),
        (on((9, 0), false, StateLayout::Full), false, true, false),
        (
            KernelOptions::all_models((9, 0), true, false),
            false,
            false,
            true,
        ),
        (on((8, 0), false, StateLayout::Full), false, false, true),
    ];
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    std::thread::scope(|scope| {
        for t in 0..threads.min(jobs.len()) {
            let jobs = &jobs;
            scope.spawn(move || {
                for (o, optimised, expect, trigger) in jobs.iter().skip(t).step_by(threads) {
                    let what = format!("{o:?}");
                    let ptx = if *optimised {
                        compile_fresh(o)
                    } else {
                        let mut opts = nvrtc_options(o);
                        opts.push("--Ofast-compile=max".into());
                        if !*trigger {
                            opts.push("-DRTMPM_PDL_TRIGGER=0".into());
                        }
                        program_source(o.f64)
                            .and_then(|src| nvrtc(&src, "rtmpm_pipeline.cu", opts).map(|c| c.ptx))
                    }
                    .unwrap_or_else(|e| panic!("{what}: {e}"));
                    let what = format!("{what}, trigger {trigger}");
                    assert_every_kernel(&ptx, &what);
                    if !*expect {
                        assert!(!ptx.contains("griddepcontrol"), "{what}");
                        continue;
                    }
                    if !*optimised {
                        // NVRTC's fast front end inlines nothing: the kernels call
                        // `step_kernel_entry` (through their bodies' functions), which holds the
                        // two instructions; the optimised compile checks each kernel.
                        let func = ptx
                            .split(&format!(".func {ENTRY_FUNC}("))
                            .nth(1)
                            .and_then(|s| s.split("\n}\n").next())
                            .unwrap_or_default();
                        assert!(func.contains("griddepcontrol.wait;"), "{what}: {func}");
                        assert_eq!(
                            func.contains("griddepcontrol.launch_dependents;"),
                            *trigger,
                            "{what}: {func}"
                        );
                        continue;
                    }
                    for &k in Kernel::ALL.iter() {
                        let body = entry(&ptx, k.name());
                        let listed = PDL_KERNELS.contains(&k) || k == Kernel::RbFused;
                        let (wait, trigger) = (
                            body.contains("griddepcontrol.wait;"),
                            body.contains("griddepcontrol.launch_dependents;"),
                        );
                        assert_eq!((wait, trigger), (listed, listed), "{what}: {}", k.name());
                        if listed {
                            let early = memory_ops_before_wait(body);
                            assert!(
                                early.is_empty(),
                                "{what}: {} touches memory before its wait: {early:?}",
                                k.name()
                            );
                        }
                    }
                }
            });
        }
    });
}
