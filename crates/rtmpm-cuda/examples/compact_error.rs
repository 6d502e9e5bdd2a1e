//! The compact state's error, emulated on the CPU backend (no GPU): the scenes of
//! `tests/state_layout.rs` (dense water and jelly blocks, spinning and falling, dx = 1/32, dt =
//! 2e-4) stepped `steps` times in f32, and again with C rounded to the compact format
//! (`rtmpm_cuda::state::codec`) after every step, as the GPU's compact state stores them. Prints the
//! largest and RMS distance between the two runs' positions, in cells.
//!
//! `cargo run -p rtmpm-cuda --example compact_error -- [steps]`

use rtmpm_cpu::CpuBackend;
use rtmpm_cuda::state::codec;
use rtmpm_physics::Particles;
use rtmpm_physics::math::{Mat3, Vec3};
use rtmpm_scene::Scene;
use rtmpm_sim::Backend;

fn scene(water: bool) -> Result<Scene, Box<dyn std::error::Error>> {
    let material = if water {
        "type = \"fluid\"\ndensity = 1000\nbulk_modulus = 1e4\n"
    } else {
        "type = \"fixed_corotated\"\ndensity = 1000\nmu = 4e4\nlambda = 6e4\n"
    };
    let text = format!(
        "[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ndx = 0.03125\n[time]\nduration = 1\n\
         dt = 2e-4\n[[material]]\nname = \"m\"\n{material}\
         [[body]]\nmaterial = \"m\"\nshape = \"box\"\nmin = [0.4, 0.4, 0.4]\nmax = [0.5, 0.5, 0.5]\n"
    );
    Ok(Scene::from_toml(&text, "compact_error")?)
}

/// The dense block of the GPU test: spacing dx/2 in [0.3, 0.6] x [0.3, 0.55] x [0.3, 0.6],
/// spinning at 5 rad/s and falling at 1 m/s.
fn block(s: &Scene) -> Particles {
    let (lo, hi, h) = (Vec3::splat(0.3), Vec3::new(0.6, 0.55, 0.6), s.dx / 2.0);
    let n = ((hi - lo) / h).round().as_uvec3();
    let centre = 0.5 * (lo + hi);
    let omega = Vec3::new(1.0, 2.0, 0.5).normalize() * 5.0;
    let vol = h * h * h;
    let mut p = Particles::default();
    for i in 0..n.x {
        for j in 0..n.y {
            for k in 0..n.z {
                let x = lo + (Vec3::new(i as f32, j as f32, k as f32) + 0.5) * h;
                p.push(
                    x,
                    omega.cross(x - centre) + Vec3::new(0.0, -1.0, 0.0),
                    1000.0 * vol,
                    vol,
                    0,
                    0.0,
                );
                let last = p.len() - 1;
                p.c[last] = Mat3::from_cols_array(&[
                    0.0, omega.z, -omega.y, -omega.z, 0.0, omega.x, omega.y, -omega.x, 0.0,
                ]);
            }
        }
    }
    p
}

fn round(p: &mut Particles) {
    for c in &mut p.c {
        *c = Mat3::from_cols_array(&codec::round_c(c.to_cols_array()));
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let steps: usize = std::env::args().nth(1).map_or(Ok(100), |a| a.parse())?;
    for water in [true, false] {
        let s = scene(water)?;
        let p = block(&s);
        let mut plain = CpuBackend::new(&s, p.clone(), None)?;
        let mut q = p.clone();
        round(&mut q);
        // Control: a backend per step without rounding must give the plain run exactly (the
        // CPU backend is deterministic and keeps nothing else between steps for these scenes).
        let mut control = p.clone();
        for i in 0..steps {
            let t = i as f32 * 2e-4;
            plain.step(2e-4, t)?;
            for (state, rounded) in [(&mut q, true), (&mut control, false)] {
                let mut b = CpuBackend::new(&s, state.clone(), None)?;
                b.step(2e-4, t)?;
                b.read_particles(state)?;
                if rounded {
                    round(state);
                }
            }
        }
        let mut a = Particles::default();
        plain.read_particles(&mut a)?;
        let off =
            a.x.iter()
                .zip(&control.x)
                .map(|(x, y)| (*x - *y).length())
                .fold(0.0f32, f32::max);
        println!(
            "control (rebuilt every step, not rounded): max |dx| {:.3e} dx",
            off / s.dx
        );
        let d: Vec<f32> =
            a.x.iter()
                .zip(&q.x)
                .map(|(x, y)| (*x - *y).length())
                .collect();
        let max = d.iter().fold(0.0f32, |m, v| m.max(*v));
        let rms = (d.iter().map(|v| (*v as f64).powi(2)).sum::<f64>() / d.len() as f64).sqrt();
        let moved =
            a.x.iter()
                .zip(&p.x)
                .map(|(x, y)| (*x - *y).length())
                .fold(0.0f32, f32::max);
        println!(
            "{} ({} particles, {steps} steps): max |dx| {:.3e} dx, rms {:.3e} dx (moved {:.2} dx)",
            if water { "water" } else { "jelly" },
            p.len(),
            max / s.dx,
            rms / s.dx as f64,
            moved / s.dx
        );
    }
    Ok(())
}
