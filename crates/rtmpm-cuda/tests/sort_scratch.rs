//! GPU tests of the rebuild's sort with a scratch of K fields (`sort_fields=K`, the state
//! permuted K fields at a time): the same state as one pass over every field (K = the layout's
//! words), in both rebuild paths, both precisions and every state layout. `cargo test -p rtmpm-cuda --test sort_scratch --
//! --include-ignored`; each test skips with a message when no usable CUDA device is present.

use rtmpm_cuda::contract::StateLayout;
use rtmpm_cuda::{CudaBackend, CudaOptions, probe};
use rtmpm_physics::Particles;
use rtmpm_physics::boundary::Walls;
use rtmpm_physics::material::Material;
use rtmpm_physics::math::{Mat3, Vec3};
use rtmpm_scene::{OutputSettings, Scene, StepMode, TimeSettings};
use rtmpm_sim::Backend;
use std::collections::{HashMap, HashSet};

fn gpu() -> bool {
    match probe() {
        Ok(d) => {
            println!("device: {d:?}");
            true
        }
        Err(e) => {
            println!("skipped: no usable CUDA GPU ({e})");
            false
        }
    }
}

fn jelly_scene(dx: f32) -> Scene {
    Scene {
        name: "sort-scratch".into(),
        source: None,
        domain_min: Vec3::ZERO,
        domain_max: Vec3::ONE,
        dx,
        gravity: Vec3::new(0.0, -9.81, 0.0),
        time: TimeSettings {
            duration: 1.0,
            fps: 30.0,
            step: StepMode::Fixed { dt: 1e-4 },
            damping: Default::default(),
        },
        materials: vec![
            Material::parse("jelly", 1000.0, "fixed_corotated", "mu = 4e4\nlambda = 6e4")
                .expect("jelly"),
        ],
        bodies: vec![],
        colliders: vec![],
        emitters: vec![],
        rigid_bodies: vec![],
        joints: vec![],
        walls: Walls::default(),
        output: OutputSettings {
            dir: "out".into(),
            stress: false,
            jacobian: false,
            ..Default::default()
        },
        render: Default::default(),
        seed: 0,
        solver: Default::default(),
        precision: Default::default(),
        particle_state: Default::default(),
        files: Vec::new(),
    }
}

/// Two particles per cell per axis in [lo, hi], in a scrambled order, every field different from
/// particle to particle (so a word moved to another particle's slot shows).
fn scrambled_block(s: &Scene, lo: Vec3, hi: Vec3) -> Particles {
    let h = s.dx / 2.0;
    let n = ((hi - lo) / h).round().as_uvec3();
    let total = (n.x * n.y * n.z) as usize;
    let mut p = Particles::default();
    for q in 0..total {
        // A permutation of the lattice (7919 is prime, coprime with the count unless it divides it).
        let i = if total.is_multiple_of(7919) {
            q
        } else {
            q * 7919 % total
        } as u32;
        let (a, b, c) = (i % n.x, i / n.x % n.y, i / (n.x * n.y));
        let x = lo + (Vec3::new(a as f32, b as f32, c as f32) + 0.5) * h;
        let f = q as f32 * 1e-6;
        let vol = h * h * h;
        p.push(
            x,
            Vec3::new(f, 2.0 * f, -f),
            1000.0 * vol * (1.0 + f),
            vol,
            0,
            f,
        );
        let last = p.len() - 1;
        p.c[last] = Mat3::from_cols_array(&std::array::from_fn(|k| f * (k as f32 + 1.0)));
        p.f[last] = Mat3::IDENTITY + Mat3::from_cols_array(&std::array::from_fn(|k| f * k as f32));
    }
    p
}

/// The state after the first rebuild (and a P2G, which leaves the particles alone): the rows of
/// the layout's words of each particle by original index, the original indices in slot order, and
/// the word size.
struct Sorted {
    rows: HashMap<u32, Vec<u8>>,
    order: Vec<u32>,
    cells: Vec<[i64; 3]>,
}

fn sorted_once(s: &Scene, p: &Particles, o: CudaOptions, layout: StateLayout) -> Sorted {
    let rb = if o.f64 { 8 } else { 4 };
    let mut b = CudaBackend::new(s, p, o).expect("backend");
    assert_eq!(b.state_layout(), layout);
    let (f_id, f_x, words) = (layout.id(), layout.x(), layout.words());
    b.run_p2g_only(1e-4).expect("rebuild and P2G");
    assert_eq!(b.rebuild_count().expect("rebuilds"), 1);
    assert_eq!(b.check().expect("check"), None);
    let (bytes, cap) = b.read_state_bytes().expect("state");
    let word = |f: usize, i: usize| &bytes[(f * cap + i) * rb..(f * cap + i + 1) * rb];
    let real = |f: usize, i: usize| -> f64 {
        let w = word(f, i);
        if rb == 8 {
            f64::from_le_bytes(w.try_into().expect("8 bytes"))
        } else {
            f32::from_le_bytes(w.try_into().expect("4 bytes")) as f64
        }
    };
    let mut out = Sorted {
        rows: HashMap::new(),
        order: vec![],
        cells: vec![],
    };
    for i in 0..p.len() {
        let id = u32::from_le_bytes(word(f_id, i)[..4].try_into().expect("4 bytes"));
        let row: Vec<u8> = (0..words).flat_map(|f| word(f, i).to_vec()).collect();
        assert!(out.rows.insert(id, row).is_none(), "particle {id} twice");
        out.order.push(id);
        // The stencil base cell (the sort's key within a block).
        let origin = s.domain_min.x as f64 - 4.0 * s.dx as f64;
        out.cells.push(std::array::from_fn(|a| {
            ((real(f_x + a, i) - origin) / s.dx as f64 - 0.5).floor() as i64
        }));
    }
    out
}

/// The rows of the layout's words of each particle as uploaded (`state::pack`), by original
/// index.
fn packed_rows(s: &Scene, p: &Particles, f64: bool, l: StateLayout) -> HashMap<u32, Vec<u8>> {
    let rb = if f64 { 8 } else { 4 };
    let fluid = rtmpm_cuda::state::fluid_materials(s);
    let n = p.len();
    let packed = rtmpm_cuda::state::pack(p, &fluid, l, f64, n, None).expect("pack");
    (0..n)
        .map(|i| {
            let row = (0..l.words())
                .flat_map(|f| packed[(f * n + i) * rb..(f * n + i + 1) * rb].to_vec())
                .collect();
            (i as u32, row)
        })
        .collect()
}

/// One rebuild of a scrambled block, jelly and water (whose sort leaves F's zero off-diagonal
/// words in place in the 29-word layout): for every K, both rebuild paths, both precisions and
/// every layout (water: 29 words with `fluid_state=off`, the 20-word fluid layout, compact; the
/// compact layouts in f32 only), every particle's words are bit-identical to the words uploaded
/// (so to K = words', the one pass over every field of before), and the particles are sorted:
/// each cell's particles in one run of slots.
#[test]
#[ignore = "needs a CUDA GPU"]
fn sort_scratch_fields_give_identical_state() {
    if !gpu() {
        return;
    }
    for fluid in [false, true] {
        let mut s = jelly_scene(1.0 / 32.0);
        if fluid {
            s.materials = vec![
                Material::parse("water", 1000.0, "fluid", "bulk_modulus = 1e4").expect("water"),
            ];
        }
        let p = scrambled_block(&s, Vec3::new(0.1, 0.1, 0.1), Vec3::new(0.4, 0.5, 0.45));
        println!("{} particles, fluid {fluid}", p.len());
        let layouts = if fluid {
            vec![
                StateLayout::Full,
                StateLayout::Fluid,
                StateLayout::CompactFluid,
            ]
        } else {
            vec![StateLayout::Full, StateLayout::Compact]
        };
        for (f64, layout) in [false, true]
            .into_iter()
            .flat_map(|f| layouts.iter().map(move |l| (f, *l)))
            .filter(|(f64, l)| !(*f64 && l.compact()))
        {
            let want = packed_rows(&s, &p, f64, layout);
            let words = layout.words();
            for fused_rebuild in [true, false] {
                for k in [1, 2, 3, 4, 8, 14, 19, 23, 28, 29] {
                    let o = CudaOptions {
                        f64,
                        fused_rebuild,
                        sort_scratch_fields: k.min(words),
                        fluid_state: layout.fluid(),
                        compact_state: layout.compact(),
                        ..Default::default()
                    };
                    let what = format!(
                        "fluid {fluid}, f64 {f64}, {layout:?}, fused {fused_rebuild}, K = {k}"
                    );
                    let got = sorted_once(&s, &p, o, layout);
                    assert_ne!(
                        got.order,
                        (0..p.len() as u32).collect::<Vec<_>>(),
                        "{what}: the sort changed nothing"
                    );
                    assert_eq!(got.rows.len(), p.len());
                    for (id, row) in &want {
                        assert_eq!(got.rows.get(id), Some(row), "{what}: particle {id} differs");
                    }
                    // Sorted by cell: a cell's particles are consecutive.
                    let mut done = HashSet::new();
                    for w in got.cells.windows(2) {
                        if w[0] != w[1] {
                            assert!(done.insert(w[0]), "{what}: cell {:?} split", w[0]);
                        }
                    }
                    assert!(!done.contains(&got.cells[got.cells.len() - 1]));
                    println!("{what}: identical");
                }
            }
        }
    }
}

/// A rebuild every step (free zone off) for 50 steps: K = 1 and 4 agree with K = 29 as
/// the ablation switches do (P2G's atomic sums make runs differ in the last bits).
#[test]
#[ignore = "needs a CUDA GPU"]
fn sort_scratch_fields_agree_over_rebuild_heavy_runs() {
    if !gpu() {
        return;
    }
    let s = jelly_scene(1.0 / 32.0);
    let p = scrambled_block(&s, Vec3::new(0.1, 0.1, 0.1), Vec3::new(0.4, 0.5, 0.45));
    for fused_rebuild in [true, false] {
        let run = |k: usize| {
            let o = CudaOptions {
                fast_math: false,
                free_zone: false,
                fused_rebuild,
                sort_scratch_fields: k,
                ..Default::default()
            };
            let mut b = CudaBackend::new(&s, &p, o).expect("backend");
            for i in 0..50 {
                b.step(2e-4, i as f32 * 2e-4).expect("step");
            }
            assert_eq!(b.check().expect("check"), None);
            assert!(b.rebuild_count().expect("rebuilds") >= 50);
            let mut out = Particles::default();
            b.read_particles(&mut out).expect("read");
            out
        };
        let full = run(29);
        for k in [1, 4] {
            let q = run(k);
            let worst = full
                .x
                .iter()
                .zip(&q.x)
                .map(|(a, b)| (*a - *b).length())
                .fold(0.0f32, f32::max);
            println!("fused {fused_rebuild}, K = {k}: max |dx| {worst:e}");
            assert!(worst < 1e-4, "K = {k}: positions differ by {worst}");
        }
    }
}
