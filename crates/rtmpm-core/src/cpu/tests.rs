//! Tests of the CPU reference backend on hand-built states.

use super::*;
use crate::boundary::{BoundaryRule, Condition};
use crate::material::{Eos, FixedCorotated, Fluid, Model};
use crate::math::Mat3;
use crate::sim::Backend;

fn consts(materials: Vec<Material>, walls: u32, gravity: Vec3) -> StepConstants {
    let dx = 1.0 / 32.0;
    StepConstants {
        dx,
        inv_dx: 1.0 / dx,
        origin: Vec3::splat(-(GRID_PAD as f32) * dx),
        domain_min: Vec3::ZERO,
        domain_max: Vec3::ONE,
        n_cells: [32; 3],
        gravity,
        walls: Walls {
            thickness: walls,
            faces: [BoundaryRule {
                condition: Condition::Separate,
                friction: 0.0,
            }; 6],
        },
        damping: Default::default(),
        colliders: Vec::new(),
        materials,
    }
}

fn jelly() -> Material {
    Material {
        name: "jelly".into(),
        density: 1000.0,
        model: Model::FixedCorotated(FixedCorotated {
            mu: 1e4,
            lambda: 2e4,
        }),
    }
}

fn water() -> Material {
    Material {
        name: "water".into(),
        density: 1000.0,
        model: Model::Fluid(Fluid {
            bulk_modulus: 1e4,
            eos: Eos::Tait { gamma: 7.0 },
            viscosity: 0.0,
        }),
    }
}

/// A lattice block of particles, 2 per cell per axis, in [lo, hi].
fn block(lo: Vec3, hi: Vec3, dx: f32, material: u32, density: f32) -> Particles {
    let mut p = Particles::default();
    let h = dx / 2.0;
    let n = ((hi - lo) / h).round().as_ivec3();
    for i in 0..n.x {
        for j in 0..n.y {
            for k in 0..n.z {
                let x = lo + (IVec3::new(i, j, k).as_vec3() + 0.5) * h;
                p.push(x, Vec3::ZERO, density * h * h * h, h * h * h, material, 0.0);
            }
        }
    }
    p
}

fn read(b: &mut CpuBackend) -> Particles {
    let mut p = Particles::default();
    b.read_particles(&mut p).expect("read");
    p
}

/// Deterministic pseudo-random numbers in [-1, 1] (no RNG dependency in the hot path).
fn noise(i: usize, salt: u32) -> f32 {
    let mut x = (i as u32).wrapping_mul(0x9E37_79B9) ^ salt.wrapping_mul(0x85EB_CA6B);
    x ^= x >> 15;
    x = x.wrapping_mul(0x2C1B_3C6D);
    x ^= x >> 12;
    (x as f32 / u32::MAX as f32) * 2.0 - 1.0
}

fn scrambled(mut p: Particles) -> Particles {
    for i in 0..p.len() {
        p.v[i] = Vec3::new(noise(i, 1), noise(i, 2), noise(i, 3));
        p.c[i] = Mat3::from_cols(
            Vec3::new(noise(i, 4), noise(i, 5), noise(i, 6)),
            Vec3::new(noise(i, 7), noise(i, 8), noise(i, 9)),
            Vec3::new(noise(i, 10), noise(i, 11), noise(i, 12)),
        ) * 3.0;
        p.f[i] = Mat3::IDENTITY + p.c[i] * 0.01;
    }
    p
}

#[test]
fn p2g_conserves_mass_linear_and_angular_momentum() {
    let c = consts(vec![jelly()], 0, Vec3::ZERO);
    let dx = c.dx;
    let p = scrambled(block(Vec3::splat(0.3), Vec3::splat(0.5), dx, 0, 1000.0));
    let mut b = CpuBackend::from_constants(c, p.clone(), Some(2)).expect("backend");
    rebuild::rebuild(&mut b);
    p2g::p2g(&mut b, 1e-4);

    let (mut gm, mut gp, mut gl) = (0.0f64, [0.0f64; 3], [0.0f64; 3]);
    for (id, blk) in b.grid.chunks(64).enumerate() {
        for (cell, n) in blk.iter().enumerate() {
            let idx = b.layout.block_coords[id] * 4
                + IVec3::new(
                    (cell >> 4) as i32,
                    (cell >> 2 & 3) as i32,
                    (cell & 3) as i32,
                );
            let xi = b.consts.origin + idx.as_vec3() * dx;
            gm += n[0] as f64;
            let mom = Vec3::new(n[1], n[2], n[3]);
            let l = xi.cross(mom);
            for a in 0..3 {
                gp[a] += mom[a] as f64;
                gl[a] += l[a] as f64;
            }
        }
    }
    let pm = p.total_mass();
    let pp = p.momentum();
    // Particle angular momentum with the APIC term (Jiang et al. 2015, eq. 15):
    // L = sum x_p x m_p v_p + m_p D : eps(C), D = dx^2/4 I for quadratic B-splines.
    let d = dx * dx / 4.0;
    let mut pl = [0.0f64; 3];
    for i in 0..p.len() {
        let m = p.mass[i];
        let cm = p.c[i];
        let l = p.x[i].cross(p.v[i] * m)
            + m * d
                * Vec3::new(
                    cm.y_axis.z - cm.z_axis.y,
                    cm.z_axis.x - cm.x_axis.z,
                    cm.x_axis.y - cm.y_axis.x,
                );
        for a in 0..3 {
            pl[a] += l[a] as f64;
        }
    }
    assert!(
        (gm - pm).abs() < 1e-5 * pm,
        "mass: grid {gm} particles {pm}"
    );
    let scale = p.mass.iter().map(|&m| m as f64).sum::<f64>(); // |v| <= ~1.7
    for a in 0..3 {
        assert!(
            (gp[a] - pp[a]).abs() < 1e-5 * scale,
            "momentum[{a}]: grid {} particles {}",
            gp[a],
            pp[a]
        );
        assert!(
            (gl[a] - pl[a]).abs() < 1e-5 * scale,
            "angular momentum[{a}]: grid {} particles {}",
            gl[a],
            pl[a]
        );
    }
}

#[test]
fn rigid_rotation_is_transferred_exactly() {
    // APIC keeps affine velocity fields: a rigidly spinning body (v = w x r, C = [w]x) comes back
    // unchanged after P2G + G2P with no forces.
    let c = consts(vec![jelly()], 0, Vec3::ZERO);
    let mut p = block(Vec3::splat(0.4), Vec3::splat(0.6), c.dx, 0, 1000.0);
    let w = Vec3::new(0.3, -0.5, 0.8);
    let centre = Vec3::splat(0.5);
    let wx = Mat3::from_cols(
        Vec3::new(0.0, w.z, -w.y),
        Vec3::new(-w.z, 0.0, w.x),
        Vec3::new(w.y, -w.x, 0.0),
    );
    for i in 0..p.len() {
        p.v[i] = w.cross(p.x[i] - centre);
        p.c[i] = wx;
    }
    let before = p.clone();
    let mut b = CpuBackend::from_constants(c, p, Some(1)).expect("backend");
    b.step(1e-6, 0.0).expect("step");
    let after = read(&mut b);
    for i in 0..before.len() {
        assert!(
            (after.v[i] - before.v[i]).length() < 1e-4,
            "v of particle {i}"
        );
        let dc = after.c[i] - before.c[i];
        assert!(
            crate::math::norm2(dc).sqrt() < 1e-3,
            "C of particle {i}: {:?}",
            after.c[i]
        );
    }
}

#[test]
fn free_fall_matches_x0_minus_half_g_t_squared() {
    let g = Vec3::new(0.0, -9.8, 0.0);
    let c = consts(vec![jelly()], 0, g);
    let p = block(
        Vec3::new(0.4, 0.7, 0.4),
        Vec3::new(0.5, 0.8, 0.5),
        c.dx,
        0,
        1000.0,
    );
    let x0 = p.x.clone();
    let mut b = CpuBackend::from_constants(c, p, None).expect("backend");
    let dt = 1e-3;
    let n = 200;
    for s in 0..n {
        b.step(dt, s as f32 * dt).expect("step");
    }
    let t = n as f32 * dt;
    let p = read(&mut b);
    // Symplectic Euler lags the exact parabola by g t dt / 2.
    let tol = 0.5 * 9.8 * t * dt + 1e-5;
    for (i, &x0) in x0.iter().enumerate() {
        let exact = x0 + 0.5 * g * t * t;
        assert!(
            (p.x[i] - exact).length() <= tol,
            "particle {i}: {} vs {exact}",
            p.x[i]
        );
        assert!((p.v[i] - g * t).length() < 1e-3, "velocity {}", p.v[i]);
        let df = p.f[i] - Mat3::IDENTITY;
        assert!(
            crate::math::norm2(df).sqrt() < 1e-4,
            "no deformation in free fall"
        );
    }
}

fn dam(threads: usize) -> Particles {
    let c = consts(vec![water(), jelly()], 3, Vec3::new(0.0, -9.8, 0.0));
    let mut p = block(Vec3::splat(0.1), Vec3::new(0.4, 0.6, 0.5), c.dx, 0, 1000.0);
    p.extend(&block(
        Vec3::new(0.6, 0.1, 0.3),
        Vec3::new(0.8, 0.3, 0.5),
        c.dx,
        1,
        1000.0,
    ));
    let mut b = CpuBackend::from_constants(c, p, Some(threads)).expect("backend");
    for s in 0..40 {
        b.step(2e-4, s as f32 * 2e-4).expect("step");
    }
    read(&mut b)
}

#[test]
fn deterministic_across_thread_counts() {
    let one = dam(1);
    for threads in [2, 3] {
        let many = dam(threads);
        // Bit for bit: compare the raw bits, not within a tolerance.
        let bits = |p: &Particles| -> Vec<u32> {
            p.x.iter()
                .flat_map(|v| v.to_array())
                .chain(p.v.iter().flat_map(|v| v.to_array()))
                .chain(p.c.iter().flat_map(|m| m.to_cols_array()))
                .chain(p.f.iter().flat_map(|m| m.to_cols_array()))
                .map(f32::to_bits)
                .collect()
        };
        assert!(
            bits(&one) == bits(&many),
            "{threads} threads differ from 1 thread"
        );
    }
    assert!(
        one.v.iter().any(|v| v.length() > 0.01),
        "the scene actually moved"
    );
}

#[test]
fn blowup_is_reported_with_the_particle() {
    let c = consts(vec![jelly()], 3, Vec3::ZERO);
    let mut p = block(Vec3::splat(0.4), Vec3::splat(0.5), c.dx, 0, 1000.0);
    p.v[5] = Vec3::new(f32::NAN, 0.0, 0.0);
    let mut b = CpuBackend::from_constants(c, p, Some(1)).expect("backend");
    b.step(1e-4, 0.0).expect("step");
    let bad = b
        .check()
        .expect("check")
        .expect("a bad particle is reported");
    // Reported by original index: a particle whose state is indeed not finite.
    let p = read(&mut b);
    assert!(
        !(p.x[bad.index].is_finite() && p.v[bad.index].is_finite()),
        "reported particle {} is healthy",
        bad.index
    );
}
