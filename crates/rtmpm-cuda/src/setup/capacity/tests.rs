//! Unit tests of the buffer plan (`setup/capacity`): capacities, bytes a particle of the big
//! scenes, the budget against the plan, the refusal past the free memory.
use super::*;
use rtmpm_scene::Budget;

/// Water at dx = 1/512, 8 particles per cell (regular), in the unit cube with slip walls:
/// `boxes` boxes along x (min, max of each): the big scenes of `bench/RESULTS.md`.
fn water(boxes: &[([f32; 3], [f32; 3])]) -> Scene {
    water_at(512, boxes)
}

/// The same at dx = 1/`cells`.
fn water_at(cells: u32, boxes: &[([f32; 3], [f32; 3])]) -> Scene {
    let mut text = format!(
        "name = \"water\"\n[domain]\nmin = [0,0,0]\nmax = [1,1,1]\ndx = {}\n\
         [time]\nduration = 0.01\nfps = 100\ndt = 1e-4\n\
         [walls]\nthickness = 3\ncondition = \"slip\"\n\
         [[material]]\nname = \"water\"\ntype = \"fluid\"\ndensity = 1000\n\
         bulk_modulus = 4e4\ngamma = 7.15\n",
        1.0 / cells as f64
    );
    for (lo, hi) in boxes {
        text += &format!(
            "[[body]]\nmaterial = \"water\"\nshape = \"box\"\nmin = {lo:?}\nmax = {hi:?}\n\
             sampling = \"regular\"\nparticles_per_cell = 8\n"
        );
    }
    Scene::from_toml(&text, "<test>").expect("water scene")
}

/// The planned device bytes of `scene` (its precision, options `o` otherwise, G2P2G) with
/// a sort scratch of `fields` fields, and the estimate of its budget.
fn planned_with(scene: &Scene, fields: usize, o: CudaOptions) -> (usize, BufferBytes, u64) {
    let budget = Budget::estimate(scene, Some(1));
    let n = budget.particles as usize;
    let f64 = scene.precision == rtmpm_scene::Precision::F64;
    let o = CudaOptions { f64, ..o };
    let words = crate::state::layout_for(scene, &o).expect("layout").words();
    let cap = Capacity::plan(scene, n, n, &BlockLayout::default(), &o);
    let grids = GridCopies {
        next: true,
        aux: false,
    };
    let rb = if f64 { 8 } else { 4 };
    (n, cap.bytes(rb, words, fields, grids), budget.gpu_bytes)
}

/// [`planned_with`] the default options (the fluid layout for water).
fn planned(scene: &Scene, fields: usize) -> (usize, BufferBytes, u64) {
    planned_with(scene, fields, CudaOptions::default())
}

#[test]
fn the_budget_covers_the_plan_in_f64() {
    // dx = 1/256: the grid of the whole domain fits in GRID_BUDGET_BYTES in f64 (at 1/512
    // it does not, the plan follows the initial layout and the budget, which counts every
    // node of the domain, overestimates).
    let mut scene = water_at(256, &[([0.1, 0.02, 0.25], [0.4, 0.485, 0.75])]);
    scene.precision = rtmpm_scene::Precision::F64;
    let (n, b, estimate) = planned(&scene, crate::options::DEFAULT_SORT_SCRATCH_FIELDS);
    assert!(n > 9_000_000, "{n}");
    // The fluid layout: 20 words of 8 bytes.
    assert_eq!((b.state, b.scratch, b.prank), (160 * n, 32 * n, 4 * n));
    let plan = b.total() as f64;
    assert!(
        estimate as f64 >= plan && estimate as f64 <= 1.15 * plan,
        "estimate {estimate} for a plan of {plan}"
    );
}

#[test]
fn bytes_per_particle_of_the_big_water_scenes() {
    // 125M: four boxes 0.125 m wide (`bench/water_125m.toml`; 276 B/particle measured before
    // this plan, bench/RESULTS.md).
    let four: Vec<_> = (0..4)
        .map(|i| {
            let x = 0.125 + 0.125 * i as f32;
            ([x, 0.02, 0.25], [x + 0.125, 0.485, 0.75])
        })
        .collect();
    // About 500M: most of the floor, half the height, in 16 boxes (at most 50M per body).
    let big: Vec<_> = (0..16)
        .map(|i| {
            let x = 0.01 + 0.06125 * i as f32;
            ([x, 0.01, 0.01], [x + 0.06125, 0.495, 0.99])
        })
        .collect();
    let default = crate::options::DEFAULT_SORT_SCRATCH_FIELDS;
    let full_layout = CudaOptions {
        fluid_state: false,
        ..Default::default()
    };
    // (scene, particle count, bytes per particle in the 29-word layout, bound, in the
    // 20-word fluid layout (the default for water), bound)
    for (scene, particles, expect, new_bound, expect_fluid, fluid_bound) in [
        (
            water(&four),
            124_000_000..126_000_000,
            181.2,
            185.0,
            145.2,
            148.0,
        ),
        (
            water(&big),
            499_000_000..502_000_000,
            147.6,
            150.0,
            111.6,
            114.0,
        ),
    ] {
        let (n, now, _) = planned_with(&scene, default, full_layout.clone());
        assert!(particles.contains(&n), "{n} particles");
        // Before: a second full copy of the state as the sort's scratch, and the sort keys
        // in their own array.
        let (_, full, _) = planned_with(&scene, 29, full_layout.clone());
        let before = full.total() + 4 * n;
        let per = |b: usize| b as f64 / n as f64;
        // Per particle: state 116, scratch 16, ranks 4, warp list 12/32 (+ gblocks).
        assert_eq!(now.state, 116 * n);
        assert_eq!(now.scratch, 16 * n);
        assert_eq!(now.prank, 4 * n);
        assert_eq!(full.scratch, 116 * n);
        assert!(
            per(now.total()) <= new_bound,
            "{} B/particle",
            per(now.total())
        );
        assert!(
            (per(now.total()) - expect).abs() < 0.05,
            "{}",
            per(now.total())
        );
        assert!(
            per(before) - per(now.total()) >= 104.0,
            "{} -> {}",
            per(before),
            per(now.total())
        );
        // The default for water: the fluid layout, 20 words (80 bytes) instead of 29.
        let (n2, fluid, estimate) = planned(&scene, default);
        assert_eq!(n2, n);
        assert_eq!(fluid.state, 80 * n);
        assert_eq!(fluid.scratch, 16 * n);
        assert_eq!(fluid.total() + 36 * n, now.total());
        assert!(
            per(fluid.total()) <= fluid_bound && (per(fluid.total()) - expect_fluid).abs() < 0.05,
            "{} B/particle",
            per(fluid.total())
        );
        // The budget's estimate (rtmpm check, the refusal before allocating) covers the
        // plan, without refusing what fits by far.
        let e = estimate as f64;
        assert!(
            e >= fluid.total() as f64 && e <= 1.15 * fluid.total() as f64,
            "estimate {e:.3e} B for a plan of {:.3e} B",
            fluid.total() as f64
        );
        eprintln!(
            "{n} particles: {:.1} B/particle before, {:.1} in 29 words ({:?}), {:.1} in the \
             fluid layout, estimate {:.1}",
            per(before),
            per(now.total()),
            now.groups()
                .map(|(g, b)| (g, (per(b) * 10.0).round() / 10.0)),
            per(fluid.total()),
            e / n as f64
        );
    }
}

#[test]
fn a_plan_past_the_free_memory_is_refused_with_what_fits() {
    let cap = Capacity {
        particles: 1_000_000,
        gblocks: 1000,
        pblocks: 2000,
        hash: 4096,
        warps: 1_000_000 / 32 + 1001,
        buckets: 64_001,
    };
    let b = cap.bytes(4, 20, 4, GridCopies::default());
    let total = b.total();
    // Fits with the reserve to spare; refused one byte short of it.
    assert_eq!(
        refusal(&b, cap.particles, total + DEVICE_RESERVE_BYTES, "GPU 0", ""),
        None
    );
    let why = refusal(
        &b,
        cap.particles,
        total + DEVICE_RESERVE_BYTES - 1,
        "GPU 0",
        "",
    )
    .expect("refused");
    assert!(why.contains("GPU 0") && why.contains("--gpus N"), "{why}");
    // The particles that fit: (free - reserve - fixed) / bytes a particle, here about half.
    let per = (b.state + b.scratch + b.prank + b.warps) as f64 / cap.particles as f64;
    let fixed = total - (b.state + b.scratch + b.prank + b.warps);
    let free = DEVICE_RESERVE_BYTES + fixed + (per * 500_000.0) as usize;
    let why = refusal(&b, cap.particles, free, "GPU 0", ", the compact state").expect("refused");
    let fits: u64 = why
        .split("About ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|n| n.parse().ok())
        .expect("a count");
    assert!((499_990..=500_000).contains(&fits), "{fits}: {why}");
    assert!(why.contains("the compact state"), "{why}");
    // Nothing free: none fit, no underflow.
    let why = refusal(&b, cap.particles, 0, "GPU 0", "").expect("refused");
    assert!(why.contains("About 0 particles fit"), "{why}");
}

#[test]
fn the_scratch_holds_the_sort_keys_in_every_precision() {
    let cap = Capacity {
        particles: 1000,
        gblocks: 10,
        pblocks: 20,
        hash: 64,
        warps: 50,
        buckets: 641,
    };
    for rb in [4, 8] {
        for k in [0, 1, 4, 29, 99] {
            let b = cap.bytes(rb, 29, k, GridCopies::default());
            assert!(b.scratch >= 4 * cap.particles);
            assert_eq!(b.scratch, k.clamp(1, 29) * rb * cap.particles);
            let fluid = cap.bytes(rb, 20, k, GridCopies::default());
            assert_eq!(fluid.state, 20 * rb * cap.particles);
            assert_eq!(fluid.scratch, k.clamp(1, 20) * rb * cap.particles);
            assert_eq!(b.grid_next + b.grid_aux, 0);
            assert_eq!(b.total(), b.groups().iter().map(|g| g.1).sum::<usize>());
        }
    }
}

/// The block counts found from the positions alone are the layout's, for bodies of shapes
/// (several chunks each), a body of points (from chunks of another size) and particles at
/// the domain's corner (blocks whose neighbours have negative coordinates).
#[test]
fn block_counts_are_the_layouts() {
    use rtmpm_scene::sampling::sample_bodies;
    let scene = water_at(
        64,
        &[
            ([0.05, 0.05, 0.05], [0.3, 0.6, 0.4]),
            ([0.5, 0.1, 0.5], [0.9, 0.3, 0.95]),
        ],
    );
    let mut bodies = sample_bodies(&scene, &|_| {}).expect("sample");
    let mut p = Particles::default();
    for i in 0..200_000 {
        let t = i as f32 * 1e-3;
        let x = Vec3::new(
            0.5 + 0.45 * t.sin(),
            0.5 + 0.45 * (0.7 * t).cos(),
            (t * 0.37).fract(),
        );
        p.push(x, Vec3::ZERO, 1.0, 1.0, 0, 0.0);
    }
    p.push(Vec3::ZERO, Vec3::ZERO, 1.0, 1.0, 0, 0.0);
    bodies.insert(1, SampledBody::Points(p));
    let bases = crate::state::map_positions(&bodies, base_of(&scene));
    let mut layout = BlockLayout::default();
    layout.rebuild(&bases);
    let got = block_counts(&scene, &bodies);
    assert_eq!(got, (layout.gblock_count, layout.pblock_count()));
    assert!(got.0 > 100 && got.1 > got.0, "{got:?}");
}

/// The block counts are found only where the plan reads them: a domain whose grid exceeds
/// the budget, without both capacities given.
#[test]
fn block_counts_only_when_the_domain_grid_does_not_fit() {
    let small = water_at(512, &[([0.1, 0.1, 0.1], [0.2, 0.2, 0.2])]);
    let big = water_at(1024, &[([0.1, 0.1, 0.1], [0.2, 0.2, 0.2])]);
    let o = CudaOptions::default();
    assert!(!Capacity::needs_block_counts(&small, &o));
    assert!(Capacity::needs_block_counts(&big, &o));
    let given = CudaOptions {
        gblock_capacity: Some(100),
        pblock_capacity: Some(1000),
        ..CudaOptions::default()
    };
    assert!(!Capacity::needs_block_counts(&big, &given));
    // Whatever the counts, the small domain's plan is the domain's.
    let a = Capacity::plan_blocks(&small, 1000, 0, (0, 0), &o);
    let b = Capacity::plan_blocks(&small, 1000, 0, (5, 50), &o);
    assert_eq!(a, b);
    let c = Capacity::plan_blocks(&big, 1000, 0, (5, 50), &o);
    assert_ne!(c, Capacity::plan_blocks(&big, 1000, 0, (6, 60), &o));
}
