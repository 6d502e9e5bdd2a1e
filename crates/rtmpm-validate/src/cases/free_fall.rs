//! Case 4: free fall (exact): x = x0 + v0 t - g t^2 / 2 for every particle.

use crate::case::{Ctx, Row};
use anyhow::Result;
use rtmpm_scene::StepMode;

pub fn run(ctx: &Ctx) -> Result<Vec<Row>> {
    let scene = ctx.scene("free_fall.toml")?;
    let p0 = scene.sample_particles()?;
    let StepMode::Fixed { dt } = scene.time.step else {
        anyhow::bail!("free_fall.toml needs a fixed dt")
    };
    let g = scene.gravity;
    let mut last = None;
    let sim = ctx.run(scene, p0.clone(), |t, p| last = Some((t, p.clone())))?;
    let (t, p) = last.expect("at least one frame");
    let t32 = t as f32;
    let mut worst = 0.0f32;
    let mut worst_f = 0.0f32;
    for i in 0..p.len() {
        let exact = p0.x[i] + p0.v[i] * t32 + 0.5 * g * t32 * t32;
        worst = worst.max((p.x[i] - exact).length());
        let df = p.f[i] - rtmpm_physics::math::Mat3::IDENTITY;
        worst_f = worst_f.max(rtmpm_physics::math::norm2(df).sqrt());
    }
    // Symplectic Euler lags the parabola by |g| t dt / 2; float round-off adds ~1e-6 m.
    let tol = 0.5 * g.length() * t32 * dt + 1e-5;
    let _ = sim;
    Ok(vec![
        Row {
            case: "free_fall".into(),
            quantity: format!("max |x - (x0 + v0 t - g t^2/2)| at t={t:.2} s"),
            reference: 0.0,
            simulated: worst as f64,
            error: worst as f64,
            tolerance: tol as f64,
            unit: "m",
        },
        Row {
            case: "free_fall".into(),
            quantity: "max |F - I| (no deformation)".into(),
            reference: 0.0,
            simulated: worst_f as f64,
            error: worst_f as f64,
            tolerance: 1e-4,
            unit: "",
        },
    ])
}
