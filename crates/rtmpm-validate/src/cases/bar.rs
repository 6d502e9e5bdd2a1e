//! Case 1: axial vibration of a continuous elastic bar (exact, Bardenhagen 2002).

use crate::case::{Ctx, Row};
use crate::measure::{Curve, observed_order, period_and_amplitude, rel_pct};
use anyhow::Result;
use rtmpm_geometry::Shape;
use rtmpm_physics::math::Vec3;
use rtmpm_physics::transfer::SolverSettings;
use rtmpm_render::plot::{Plot, Series, Style};
use rtmpm_scene::Scene;
use std::f64::consts::PI;

const L: f64 = 25.0;
const V0: f64 = 0.1;

/// The scene with `cells` cells along the bar (walls 3 cells thick, the same bar).
fn at_resolution(mut scene: Scene, cells: u32) -> Scene {
    let Shape::Box(rtmpm_geometry::shape::Cuboid { max, .. }) = scene.bodies[0].shape.clone()
    else {
        return scene;
    };
    let dx = (L / cells as f64) as f32;
    scene.dx = dx;
    let t = scene.walls.thickness as f32 * dx;
    let snap = |v: f32| (v / dx).ceil() * dx;
    scene.domain_min = Vec3::new(-t - dx, -t, -t);
    scene.domain_max = Vec3::new(L as f32 + t + 2.0 * dx, snap(max.y) + t, snap(max.z) + t);
    scene
}

/// (period, amplitude) of the centre-of-mass velocity over the run, and the samples (t, v).
fn measure(ctx: &Ctx, cells: u32, solver: Option<SolverSettings>) -> Result<(f64, f64, Curve)> {
    let mut scene = at_resolution(ctx.scene("vibrating_bar.toml")?, cells);
    if let Some(s) = solver {
        scene.solver = s;
    }
    let mut p0 = scene.sample_particles()?;
    let beta = PI / (2.0 * L);
    for i in 0..p0.len() {
        // v(x, 0) = v0 sin(beta x) along the bar.
        p0.v[i] = Vec3::new((V0 * (beta * p0.x[i].x as f64).sin()) as f32, 0.0, 0.0);
    }
    let (mut t, mut v) = (Vec::new(), Vec::new());
    ctx.run(scene, p0, |time, p| {
        let m: f64 = p.mass.iter().map(|&m| m as f64).sum();
        let mv: f64 = p
            .mass
            .iter()
            .zip(&p.v)
            .map(|(&m, v)| m as f64 * v.x as f64)
            .sum();
        t.push(time);
        v.push(mv / m);
    })?;
    let (p, a) =
        period_and_amplitude(&t, &v).ok_or_else(|| anyhow::anyhow!("the bar did not oscillate"))?;
    Ok((p, a, t.into_iter().zip(v).collect()))
}

/// The bar with the scene's transfer (MLS-MPM/APIC).
pub fn run(ctx: &Ctx) -> Result<Vec<Row>> {
    run_with(ctx, "vibrating_bar", None)
}

/// The same bar with uGIMP ([`crate::case::GIMP`]).
pub fn run_gimp(ctx: &Ctx) -> Result<Vec<Row>> {
    run_with(ctx, "vibrating_bar_gimp", Some(crate::case::GIMP))
}

/// The same bar with CK-MPM ([`crate::case::CK`]; experimental; CPU, or CUDA on one GPU).
pub fn run_ck(ctx: &Ctx) -> Result<Vec<Row>> {
    run_with(ctx, "vibrating_bar_ck", Some(crate::case::CK))
}

fn run_with(ctx: &Ctx, case: &str, solver: Option<SolverSettings>) -> Result<Vec<Row>> {
    // 14 cells (the reference's typical run) loses 2.2 % of the amplitude to APIC dissipation over
    // 3 periods (see the convergence study); 28 cells is within 0.3 %.
    let cells = if ctx.options.quick { 28 } else { 56 };
    let (period, amplitude, samples) = measure(ctx, cells, solver)?;
    let w1 = PI / (2.0 * L) * (100.0f64 / 1.0).sqrt();
    let (p_ref, a_ref) = (2.0 * PI / w1, 2.0 * V0 / PI);
    let exact: Vec<(f64, f64)> = samples
        .iter()
        .map(|&(t, _)| (t, a_ref * (w1 * t).cos()))
        .collect();
    let transfer = match solver {
        Some(s) => s,
        None => ctx.scene("vibrating_bar.toml")?.solver,
    }
    .describe();
    ctx.plot(
        &format!("{case}_com_velocity"),
        Plot {
            title: format!("Vibrating bar: centre-of-mass velocity ({cells} cells, {transfer})"),
            x_label: "t (s)".into(),
            y_label: "v com (m/s)".into(),
            series: vec![
                Series {
                    label: "exact".into(),
                    points: exact,
                    rgb: [40, 40, 40],
                    style: Style::Line,
                },
                Series {
                    label: "rtmpm".into(),
                    points: samples,
                    rgb: [220, 60, 40],
                    style: Style::Line,
                },
            ],
        },
    );
    let mut rows = vec![
        Row {
            case: case.into(),
            quantity: format!("period of COM velocity (s), {cells} cells"),
            reference: p_ref,
            simulated: period,
            error: rel_pct(period, p_ref),
            tolerance: 2.0,
            unit: "%",
        },
        Row {
            case: case.into(),
            quantity: format!("amplitude of COM velocity (m/s), {cells} cells"),
            reference: a_ref,
            simulated: amplitude,
            error: rel_pct(amplitude, a_ref),
            tolerance: 2.0,
            unit: "%",
        },
    ];
    if ctx.options.convergence {
        let mut errs = Vec::new();
        for c in [14u32, 28, 56] {
            let (p, a, _) = measure(ctx, c, solver)?;
            let e = rel_pct(p, p_ref);
            println!(
                "convergence {case}: {c} cells: period {p:.4} s ({e:.3} %), amplitude {a:.5} m/s ({:.3} %)",
                rel_pct(a, a_ref)
            );
            errs.push(e);
        }
        println!(
            "convergence {case}: observed orders (period) {:?}",
            observed_order(&errs, 2.0)
        );
        rows.push(Row {
            case: case.into(),
            quantity: "period error shrinks (56 cells / 14 cells)".into(),
            reference: errs[0],
            simulated: errs[2],
            error: errs[2] / errs[0].max(1e-12),
            tolerance: 1.0,
            unit: "",
        });
    }
    Ok(rows)
}
