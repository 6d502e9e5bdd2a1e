//! Packing in every [`StateLayout`]: the fluid layout is the 29-word image without F's
//! off-diagonal words and the plastic word; the compact layouts round v and C within the codec's
//! bound and keep every other word.

use super::*;
use crate::state::codec;

/// Fluid and solid particles with every field set (fluid: F = J^(1/3) I after packing).
fn particles(n: usize, materials: u32) -> Particles {
    let mut p = Particles::default();
    for i in 0..n {
        let t = i as f32;
        p.push(
            Vec3::new(t.sin(), t.cos(), 1e-3 * t),
            Vec3::new(0.5 - t.cos(), 2.0 + 1e-3 * t, -t.sin() * 1e-4),
            1e-3 + 1e-6 * t,
            1e-6 * (1.0 + t.sin().abs()),
            (i as u32) % materials,
            0.25 * t.cos(),
        );
        p.f[i] = Mat3::from_cols_array(&[1.1, 0.2, 0.0, -0.1, 0.9, 0.3, 0.0, 0.0, 1.05 + 1e-4 * t]);
        p.c[i] = Mat3::from_cols_array(&std::array::from_fn(|e| (t + e as f32).sin() * 10.0));
    }
    p
}

/// Word `w` of slot `i` of an f32 image with stride `cap`.
fn word(bytes: &[u8], cap: usize, w: usize, i: usize) -> [u8; 4] {
    let at = (w * cap + i) * 4;
    [bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]
}

#[test]
fn the_fluid_layout_is_the_full_image_without_the_fluid_s_zero_and_plastic_words() {
    let p = particles(3000, 2);
    let fluid = [true, true];
    let cap = 3100;
    for f64 in [false, true] {
        let wb = word_bytes(f64);
        let full = pack(&p, &fluid, StateLayout::Full, f64, cap, None).expect("pack");
        let packed = pack(&p, &fluid, StateLayout::Fluid, f64, cap, None).expect("pack");
        assert_eq!(packed.len(), 20 * cap * wb);
        let (l, fl) = (StateLayout::Fluid, StateLayout::Full);
        // Word of the fluid layout -> word of the full one.
        let mut map: Vec<(usize, usize)> = (0..15).map(|w| (w, w)).collect();
        map.push((l.f(), fl.f()));
        map.extend([
            (l.mass(), fl.mass()),
            (l.vol0(), fl.vol0()),
            (l.material(), fl.material()),
            (l.id(), fl.id()),
        ]);
        for (a, b) in map {
            let (ra, rb) = (a * cap * wb, b * cap * wb);
            assert!(
                packed[ra..ra + cap * wb] == full[rb..rb + cap * wb],
                "word {a} of the fluid layout differs from word {b}"
            );
        }
        // The dropped words: F's off-diagonal zeros (and its equal diagonal), the plastic word
        // (a fluid's is never read).
        let fw = |k: usize, i: usize| &full[((fl.f() + k) * cap + i) * wb..][..wb];
        for i in 0..p.len() {
            for k in [1, 2, 3, 5, 6, 7] {
                assert!(fw(k, i).iter().all(|b| *b == 0), "F[{k}] of {i}");
            }
            assert_eq!(fw(0, i), fw(4, i));
            assert_eq!(fw(0, i), fw(8, i));
        }
        // Unpacked: the same particles as from the 29-word image, but plastic 0.
        let (mut a, mut b) = (Particles::default(), Particles::default());
        unpack(&packed, p.len(), cap, l, f64, &mut a).expect("unpack");
        unpack(&full, p.len(), cap, fl, f64, &mut b).expect("unpack");
        b.plastic.iter_mut().for_each(|v| *v = 0.0);
        assert_eq!(a, b);
    }
    // A solid material cannot be packed in a fluid layout.
    assert!(pack(&p, &[true, false], StateLayout::Fluid, false, cap, None).is_err());
}

#[test]
fn the_compact_layouts_round_v_and_c_within_the_bound_and_keep_the_rest() {
    let p = particles(5000, 2);
    let cap = 5003;
    for (l, fluid) in [
        (StateLayout::Compact, [false, true]),
        (StateLayout::CompactFluid, [true, true]),
    ] {
        let plain = if l.fluid() {
            StateLayout::Fluid
        } else {
            StateLayout::Full
        };
        let packed = pack(&p, &fluid, l, false, cap, None).expect("pack");
        assert_eq!(packed.len(), l.words() * cap * 4);
        let reference = pack(&p, &fluid, plain, false, cap, None).expect("pack");
        // x, F, plastic, mass, vol0, material and id: the plain layout's words.
        let mut same: Vec<(usize, usize)> = (0..3).map(|a| (l.x() + a, plain.x() + a)).collect();
        same.extend((0..l.f_words()).map(|k| (l.f() + k, plain.f() + k)));
        same.extend(l.plastic().zip(plain.plastic()));
        same.extend([
            (l.mass(), plain.mass()),
            (l.vol0(), plain.vol0()),
            (l.material(), plain.material()),
            (l.id(), plain.id()),
        ]);
        for i in 0..p.len() {
            for &(a, b) in &same {
                assert_eq!(word(&packed, cap, a, i), word(&reference, cap, b, i));
            }
        }
        let mut q = Particles::default();
        unpack(&packed, p.len(), cap, l, false, &mut q).expect("unpack");
        let mut r = Particles::default();
        unpack(&reference, p.len(), cap, plain, false, &mut r).expect("unpack");
        for i in 0..p.len() {
            let v = p.v[i].to_array();
            let c = p.c[i].to_cols_array();
            let mc = c.iter().fold(0f32, |m, x| m.max(x.abs()));
            let (qv, qc) = (q.v[i].to_array(), q.c[i].to_cols_array());
            for k in 0..9 {
                assert!((qc[k] as f64 - c[k] as f64).abs() <= codec::bound(mc, codec::C_BITS));
            }
            // The host rounds exactly as the codec does.
            assert_eq!(qv, v, "v is f32 in every layout");
            assert_eq!(qc, codec::round_c(c));
            assert_eq!(
                (q.x[i], q.f[i], q.plastic[i]),
                (r.x[i], r.f[i], r.plastic[i])
            );
            assert_eq!(
                (q.mass[i], q.vol0[i], q.material[i]),
                (r.mass[i], r.vol0[i], r.material[i])
            );
        }
        // Packing what was unpacked gives the same v and C words (the formats are idempotent).
        let again = pack(&q, &fluid, l, false, cap, None).expect("pack");
        for i in 0..p.len() {
            for w in l.v()..l.f() {
                assert_eq!(word(&again, cap, w, i), word(&packed, cap, w, i), "{l:?}");
            }
        }
        // x and v read back for the precision tests: v decoded.
        let xv = unpack_x_v_f64(&packed, p.len(), cap, l, false).expect("x, v");
        assert_eq!(xv[7][1], q.v[7].to_array().map(|a| a as f64));
        // Single precision only.
        assert!(pack(&p, &fluid, l, true, cap, None).is_err());
    }
}

#[test]
fn the_backend_chooses_the_layout_from_the_scene_and_options() {
    let water = "[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ndx = 0.05\n[time]\nduration = 1\n\
        [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000\nbulk_modulus = 1e5\n\
        [[body]]\nmaterial = \"w\"\nshape = \"box\"\nmin = [0.2, 0.2, 0.2]\nmax = [0.4, 0.4, 0.4]\n";
    let jelly = water.replace(
        "type = \"fluid\"\ndensity = 1000\nbulk_modulus = 1e5",
        "type = \"neo_hookean\"\ndensity = 1000\nyoungs_modulus = 1e5\npoisson_ratio = 0.3",
    );
    let w = Scene::from_toml(water, "w").expect("water");
    let j = Scene::from_toml(&jelly, "j").expect("jelly");
    let o = CudaOptions::default();
    assert_eq!(layout_for(&w, &o), Ok(StateLayout::Fluid));
    assert_eq!(layout_for(&j, &o), Ok(StateLayout::Full));
    // The scene's [solver] particle_state = "compact".
    let with = |t: &str| format!("{t}[solver]\nparticle_state = \"compact\"\n");
    let wc = Scene::from_toml(&with(water), "wc").expect("compact water");
    let jc = Scene::from_toml(&with(&jelly), "jc").expect("compact jelly");
    assert_eq!(layout_for(&wc, &o), Ok(StateLayout::CompactFluid));
    assert_eq!(layout_for(&jc, &o), Ok(StateLayout::Compact));
    let e = Scene::from_toml(&format!("{}precision = \"f64\"\n", with(water)), "f64")
        .expect_err("compact f64");
    assert!(e.to_string().contains("single precision only"), "{e}");
    assert!(Scene::from_toml(&with(water).replace("compact", "f16"), "bad").is_err());
    // The budget (rtmpm-scene, before any backend exists) counts the same words.
    for scene in [&w, &j, &wc, &jc] {
        assert_eq!(
            rtmpm_scene::budget::gpu_state_words(scene) as usize,
            layout_for(scene, &o).map(|l| l.words()).unwrap_or(0)
        );
    }
    let off = CudaOptions {
        fluid_state: false,
        ..Default::default()
    };
    assert_eq!(layout_for(&w, &off), Ok(StateLayout::Full));
    let compact = CudaOptions {
        compact_state: true,
        ..Default::default()
    };
    assert_eq!(layout_for(&w, &compact), Ok(StateLayout::CompactFluid));
    assert_eq!(layout_for(&j, &compact), Ok(StateLayout::Compact));
    let e = layout_for(
        &j,
        &CudaOptions {
            f64: true,
            ..compact
        },
    )
    .unwrap_err();
    assert!(e.contains("single precision only"), "{e}");
}

/// The rows of the first `n` slots of every word of an image with stride `cap`, as the read of
/// all particles copies them.
fn rows_of(bytes: &[u8], n: usize, cap: usize, words: usize, wb: usize) -> Vec<&[u8]> {
    (0..words)
        .map(|w| &bytes[w * cap * wb..(w * cap + n) * wb])
        .collect()
}

/// The parallel unpack of the rows of every word (what `read_particles` copies) gives the
/// particles the one-thread unpack of the whole image gives, in every layout and precision,
/// with shuffled ids, a capacity past the count and several tasks' worth of particles; an id
/// held twice or out of range is an error.
#[test]
fn the_parallel_unpack_of_the_rows_is_the_unpack_of_the_image() {
    let n = 40_000 + 17;
    let cap = n + 300;
    // A permutation: slot i holds original particle (i * 7919) mod n (7919 is prime, n is not a
    // multiple of it).
    let ids: Vec<u32> = (0..n).map(|i| ((i * 7919) % n) as u32).collect();
    for (layout, fluid, f64) in [
        (StateLayout::Full, false, false),
        (StateLayout::Full, false, true),
        (StateLayout::Fluid, true, false),
        (StateLayout::Fluid, true, true),
        (StateLayout::Compact, false, false),
        (StateLayout::CompactFluid, true, false),
    ] {
        let p = particles(n, 2);
        let bytes = pack(&p, &[fluid, fluid], layout, f64, cap, Some(&ids)).expect("pack");
        let wb = word_bytes(f64);
        let mut whole = Particles::default();
        unpack(&bytes, n, cap, layout, f64, &mut whole).expect("unpack");
        let mut par = Particles::default();
        let rows = rows_of(&bytes, n, cap, layout.words(), wb);
        unpack_rows(&rows, n, layout, f64, &mut par).expect("unpack_rows");
        assert!(par == whole, "{layout:?}, f64 = {f64}");
        // Slot i held particle i with id ids[i]: it comes back at ids[i] (positions exact in
        // every layout).
        for i in [1, 2, n / 2, n - 1] {
            assert_eq!(par.x[ids[i] as usize], p.x[i], "{layout:?}, slot {i}");
            assert_eq!(par.mass[ids[i] as usize], p.mass[i], "{layout:?}, slot {i}");
        }
    }
    // Slot 1 given slot 0's id: refused.
    let p = particles(4, 1);
    let bytes = pack(&p, &[false], FULL, false, 4, Some(&[0, 0, 2, 3])).expect("pack");
    let rows = rows_of(&bytes, 4, 4, FULL.words(), 4);
    let e = unpack_rows(&rows, 4, FULL, false, &mut Particles::default()).unwrap_err();
    assert!(e.contains("id 0 held by two slots"), "{e}");
    let bytes = pack(&p, &[false], FULL, false, 4, Some(&[0, 9, 2, 3])).expect("pack");
    let rows = rows_of(&bytes, 4, 4, FULL.words(), 4);
    let e = unpack_rows(&rows, 4, FULL, false, &mut Particles::default()).unwrap_err();
    assert!(e.contains("corrupt particle id 9"), "{e}");
    // Too few rows.
    assert!(unpack_rows(&rows[..3], 4, FULL, false, &mut Particles::default()).is_err());
}
