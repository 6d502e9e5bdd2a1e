//! Tests of the packing of the device state (`state/pack.rs`, `state/unpack.rs`).

use super::pack::PACK_CHUNK;
use super::word::Word;
use super::*;
use crate::contract::*;
use rtmpm_physics::Particles;
use rtmpm_physics::math::{Mat3, Vec3};

const NFIELDS: usize = 29;
const F_X: usize = 0;
const F_V: usize = 3;
const F_C: usize = 6;
const F_F: usize = 15;
const F_PLASTIC: usize = 24;
const F_MASS: usize = 25;
const F_VOL0: usize = 26;
const F_MAT: usize = 27;
const F_ID: usize = 28;
const FULL: StateLayout = StateLayout::Full;

/// The one-thread packing of before (the 29-word layout with its constants of before): word by
/// word into a vector, then to bytes.
fn reference_pack<W: Word>(p: &Particles, fluid: &[bool], cap: usize, ids: &[u32]) -> Vec<u8> {
    let mut host = vec![W::default(); NFIELDS * cap];
    for i in 0..p.len() {
        let mut put = |f: usize, v: W| host[f * cap + i] = v;
        for a in 0..3 {
            put(F_X + a, W::from_f32(p.x[i][a]));
            put(F_V + a, W::from_f32(p.v[i][a]));
        }
        let m = p.material[i];
        let f = if fluid[m as usize] {
            Mat3::from_diagonal(Vec3::splat(p.f[i].determinant().cbrt()))
        } else {
            p.f[i]
        };
        let (c, fm) = (p.c[i].to_cols_array(), f.to_cols_array());
        for e in 0..9 {
            put(F_C + e, W::from_f32(c[e]));
            put(F_F + e, W::from_f32(fm[e]));
        }
        put(F_PLASTIC, W::from_f32(p.plastic[i]));
        put(F_MASS, W::from_f32(p.mass[i]));
        put(F_VOL0, W::from_f32(p.vol0[i]));
        put(F_MAT, W::from_id(m));
        put(F_ID, W::from_id(ids[i]));
    }
    let mut bytes = vec![0u8; host.len() * W::BYTES];
    for (w, out) in host.into_iter().zip(bytes.chunks_mut(W::BYTES)) {
        w.put(out);
    }
    bytes
}

/// Several tasks' worth of particles (a partial last one), fluid and solid, a capacity past
/// the count and ids: the parallel image is the one-thread image byte for byte.
#[test]
fn the_parallel_pack_is_the_one_thread_pack() {
    let n = 2 * PACK_CHUNK + 1234;
    let mut p = Particles::default();
    let mut ids = Vec::with_capacity(n);
    for i in 0..n {
        let t = i as f32;
        p.push(
            Vec3::new(t.sin(), t.cos(), 1e-3 * t),
            Vec3::new(0.5 - t.cos(), 2.0, -t.sin()),
            1e-3 + 1e-6 * t,
            1e-6 * (1.0 + t.sin().abs()),
            (i % 3) as u32,
            0.25 * t.cos(),
        );
        p.f[i] = Mat3::from_cols_array(&[
            1.0 + 1e-4 * t.sin(),
            0.1,
            0.0,
            -0.1,
            0.9,
            0.3,
            0.0,
            0.0,
            1.05,
        ]);
        p.c[i] = Mat3::from_cols_array(&std::array::from_fn(|e| (t + e as f32).sin()));
        ids.push((n - 1 - i) as u32);
    }
    let fluid = [true, false, true];
    // Packed into kept memory after other bytes (a GPU batch's puts): the same image after them,
    // them untouched, in every layout and precision; a bad material refused there too.
    for l in StateLayout::ALL {
        for f64 in [false, true] {
            if pack(&p, &fluid, l, f64, n, None).is_err() {
                continue; // a fluid layout with a solid material, a compact one in f64
            }
            let mut kept = vec![7u8; 13];
            for cap in [n, n + 77] {
                let at = kept.len();
                pack_into(&p, &fluid, l, f64, cap, &mut kept).expect("pack into");
                let image = pack(&p, &fluid, l, f64, cap, None).expect("pack");
                assert!(kept[at..] == image[..], "{l:?}, f64 {f64}, cap {cap}");
            }
            assert_eq!(kept[..13], [7u8; 13]);
        }
    }
    for cap in [n, n + 77] {
        let got = pack(&p, &fluid, FULL, false, cap, Some(&ids)).expect("pack");
        assert!(
            got == reference_pack::<f32>(&p, &fluid, cap, &ids),
            "f32, cap {cap}"
        );
        let got = pack(&p, &fluid, FULL, true, cap, Some(&ids)).expect("pack");
        assert!(
            got == reference_pack::<f64>(&p, &fluid, cap, &ids),
            "f64, cap {cap}"
        );
    }
    // The first particle of a bad material is named, as before.
    p.material[PACK_CHUNK + 5] = 7;
    p.material[PACK_CHUNK + 9] = 9;
    let e = pack(&p, &fluid, FULL, false, n, None).unwrap_err();
    assert!(
        e.contains(&format!("particle {} has material 7", PACK_CHUNK + 5)),
        "{e}"
    );
    let e = pack_into(&p, &fluid, FULL, false, n, &mut Vec::new()).unwrap_err();
    assert!(
        e.contains(&format!("particle {} has material 7", PACK_CHUNK + 5)),
        "{e}"
    );
    assert_eq!(
        pack(&Particles::default(), &fluid, FULL, false, 3, None)
            .expect("empty")
            .len(),
        NFIELDS * 3 * 4
    );
}

/// Packing the sampled bodies gives the image of packing the sampled particles, byte for
/// byte: shapes and samplings of every kind, fluid and solid, spinning, and a points body.
#[test]
fn packing_the_sampled_bodies_is_packing_their_particles() {
    let dir = std::env::temp_dir().join(format!("rtmpm-pack-bodies-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let mut ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n\
                    property float x\nproperty float y\nproperty float z\nend_header\n"
        .to_vec();
    for v in [0.2f32, 0.2, 0.2, 0.25, 0.2, 0.2, 0.2, 0.3, 0.25] {
        ply.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::write(dir.join("pts.ply"), ply).expect("ply");
    let text = "seed = 3\n[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ndx = 0.02\n\
        [time]\nduration = 1\n\
        [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000\nbulk_modulus = 1e5\n\
        [[material]]\nname = \"s\"\ntype = \"snow\"\ndensity = 400\n\
        youngs_modulus = 1.4e5\npoisson_ratio = 0.2\n\
        [[body]]\nmaterial = \"s\"\nshape = \"sphere\"\ncenter = [0.3, 0.5, 0.5]\n\
        radius = 0.2\nsampling = \"jittered\"\nangular_velocity = [0, 3, 1]\n\
        [[body]]\nmaterial = \"w\"\nshape = \"box\"\nmin = [0.6, 0.1, 0.1]\n\
        max = [0.9, 0.4, 0.5]\nsampling = \"regular\"\nvelocity = [0, -1, 0]\n\
        [[body]]\nmaterial = \"w\"\nshape = \"particles\"\nfile = \"pts.ply\"\n\
        [[body]]\nmaterial = \"s\"\nshape = \"cylinder\"\ncenter = [0.7, 0.7, 0.6]\n\
        axis = [0, 1, 0]\nradius = 0.1\nheight = 0.2\nsampling = \"random\"\n";
    let scene = rtmpm_scene::Scene::from_toml_in(text, "pack", &dir).expect("scene");
    let _ = std::fs::remove_dir_all(&dir);
    let p = scene.sample_particles().expect("particles");
    assert!(p.len() > 2 * PACK_CHUNK, "{}", p.len());
    let bodies = rtmpm_scene::sampling::sample_bodies(&scene, &|_| {}).expect("bodies");
    let fluid = [true, false];
    for (l, f64) in [(FULL, false), (FULL, true), (StateLayout::Compact, false)] {
        let want = pack(&p, &fluid, l, f64, p.len(), None).expect("pack");
        let got = pack_bodies(&bodies, &fluid, l, f64).expect("pack bodies");
        assert!(got == want, "{l:?}, f64 = {f64}: the images differ");
    }
    // The fluid layouts (every material taken for a fluid here).
    for l in [StateLayout::Fluid, StateLayout::CompactFluid] {
        let want = pack(&p, &[true, true], l, false, p.len(), None).expect("pack");
        let got = pack_bodies(&bodies, &[true, true], l, false).expect("pack bodies");
        assert!(got == want, "{l:?}: the images differ");
    }
    // What the backend takes from the particles besides the image, from the bodies.
    assert_eq!(
        map_positions(&bodies, |x| x),
        p.x,
        "positions in the particles' order"
    );
    let want = crate::setup::capacity::bases(&scene, &p);
    let got = map_positions(&bodies, crate::setup::capacity::base_of(&scene));
    assert_eq!(got, want);
    let speed = p.v.iter().map(|v| v.length()).fold(0.0, f32::max);
    assert!(speed > 0.5, "{speed}");
    assert_eq!(max_speed(&bodies).to_bits(), speed.to_bits());
    let e = pack_bodies(&bodies, &[true], FULL, false).unwrap_err();
    assert!(e.contains("particle 0 has material 1"), "{e}");
}

#[test]
fn pack_unpack_round_trip_both_precisions() {
    let mut p = Particles::default();
    for i in 0..5 {
        let x = Vec3::new(0.1 * i as f32, 0.3, 1.0 / 3.0);
        p.push(x, Vec3::new(1.5, -2.25, 0.1), 0.01, 1e-6, i % 2, 0.5);
    }
    p.f[3] = Mat3::from_cols_array(&[1.1, 0.2, 0.0, -0.1, 0.9, 0.3, 0.0, 0.0, 1.05]);
    for f64 in [false, true] {
        for cap in [5, 8] {
            let bytes = pack(&p, &[false, false], FULL, f64, cap, None).expect("pack");
            assert_eq!(bytes.len(), NFIELDS * cap * word_bytes(f64));
            let mut q = Particles::default();
            unpack(&bytes, 5, cap, FULL, f64, &mut q).expect("unpack");
            assert_eq!(p, q, "f64 = {f64}, cap = {cap}");
        }
    }
    assert!(pack(&p, &[false], FULL, true, 5, None).is_err());
    assert!(pack(&p, &[false, false], FULL, false, 5, Some(&[0, 1])).is_err());
    // Ids put each particle at its original index (reversed here).
    let bytes = pack(&p, &[false, false], FULL, false, 6, Some(&[4, 3, 2, 1, 0])).expect("pack");
    let mut q = Particles::default();
    unpack(&bytes, 5, 6, FULL, false, &mut q).expect("unpack");
    assert_eq!(q.x[0], p.x[4]);
    assert_eq!(q.f[1], p.f[3]);
}

#[test]
fn a_fluid_particle_is_packed_as_j_to_the_third_times_identity() {
    let mut p = Particles::default();
    p.push(Vec3::ZERO, Vec3::ZERO, 0.01, 1e-6, 0, 0.0);
    p.push(Vec3::ONE, Vec3::ZERO, 0.01, 1e-6, 1, 0.0);
    let sheared = Mat3::from_cols_array(&[1.1, 0.2, 0.0, -0.1, 0.9, 0.3, 0.0, 0.0, 1.05]);
    p.f[0] = sheared;
    p.f[1] = sheared;
    let bytes = pack(&p, &[true, false], FULL, false, 2, None).expect("pack");
    let mut q = Particles::default();
    unpack(&bytes, 2, 2, FULL, false, &mut q).expect("unpack");
    let s = sheared.determinant().cbrt();
    assert_eq!(q.f[0], Mat3::from_diagonal(Vec3::splat(s)));
    assert!((q.f[0].determinant() - sheared.determinant()).abs() < 1e-6);
    assert_eq!(q.f[1], sheared, "a solid keeps its F");
}

mod layouts;
