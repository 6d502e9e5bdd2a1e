//! Case 6: granular column collapse against Lube 2005 / Lajeunesse 2005 runout scaling.

use crate::case::{Ctx, Row};
use crate::measure::rel_pct;
use anyhow::Result;
use rtmpm_physics::math::Vec3;
use rtmpm_physics::transfer::SolverSettings;
use rtmpm_render::plot::{Plot, Series, Style};
use rtmpm_scene::Scene;

/// Initial column length and height (m), as in validation/granular_column.toml.
const L0: f64 = 0.1;
const H0: f64 = 0.1;
/// Slab depth in cells (plane experiment, slip walls front and back).
const SLAB_CELLS: f32 = 2.0;
/// The deposit must have come to rest by the end: fastest particle below this (m/s).
const AT_REST: f32 = 0.05;

/// The scene at grid spacing `dx`: the same tank and column, walls 3 cells thick, a slab
/// `SLAB_CELLS` cells deep.
fn at_resolution(mut scene: Scene, dx: f32) -> Scene {
    let t = scene.walls.thickness as f32 * dx;
    let depth = SLAB_CELLS * dx;
    scene.domain_min = Vec3::splat(-t);
    scene.domain_max = Vec3::new(0.4 + t, 0.15 + t, depth + t);
    scene.dx = dx;
    for b in &mut scene.bodies {
        if let rtmpm_geometry::Shape::Box(c) = &mut b.shape {
            c.max.z = depth;
        }
    }
    scene
}

/// The tip of the deposit in sorted positions `x`: the farthest particle with no gap wider
/// than `gap` between it and the rest of the deposit behind it (isolated particles thrown
/// ahead of the front do not count; a layer one particle thick does).
fn deposit_tip(x: &[f32], gap: f32) -> f32 {
    let mut k = x.len() - 1;
    while k > 0 && x[k] - x[k - 1] > gap {
        k -= 1;
    }
    x[k]
}

/// The fastest particle's speed (m/s) and how many particles move faster than [`AT_REST`].
fn motion(p: &rtmpm_physics::particles::Particles) -> (f32, usize) {
    let speeds = p.v.iter().map(|v| v.length());
    let fastest = speeds.clone().fold(0.0f32, f32::max);
    (fastest, speeds.filter(|&s| s >= AT_REST).count())
}

/// Final particle positions of the collapse at grid spacing `dx`, and the time they were taken.
///
/// The runout is measured on the deposit at rest. A deposit that still moves at the scene's end
/// runs on, frame by frame, until it is at rest or twice the scene's duration has passed (CK-MPM
/// at h = L0/40 settles later than MLS-MPM: 0.088 m/s at 0.6 s, at rest by 1.2 s on an H200).
fn collapse(ctx: &Ctx, dx: f32, solver: Option<SolverSettings>) -> Result<(Vec<Vec3>, f64)> {
    let mut scene = at_resolution(ctx.scene("granular_column.toml")?, dx);
    if let Some(s) = solver {
        scene.solver = s;
    }
    let frames = scene.time.frames();
    let p0 = scene.sample_particles()?;
    // (time, fastest speed, particles not at rest) of every frame: the history a deposit that
    // does not come to rest is reported with (settling late, or a few particles that never stop).
    let mut history = Vec::new();
    let mut sim = ctx.run(scene, p0, |t, p| history.push((t, motion(p))))?;
    let mut p = rtmpm_physics::particles::Particles::default();
    sim.backend.read_particles(&mut p)?;
    let mut now = motion(&p);
    for _ in 0..frames {
        if now.0 < AT_REST {
            break;
        }
        sim.advance_frame()?;
        sim.backend.read_particles(&mut p)?;
        now = motion(&p);
        history.push((sim.time, now));
    }
    let (fastest, moving) = now;
    if fastest >= AT_REST {
        let stride = history.len().div_ceil(8).max(1);
        let trace: Vec<String> = history
            .iter()
            .step_by(stride)
            .chain(history.last())
            .map(|(t, (f, m))| format!("t {t:.2} s: {f:.3} m/s, {m} moving"))
            .collect();
        anyhow::bail!(
            "the deposit still moves at twice the scene's duration ({fastest} m/s at dx = {dx}; \
             {moving} of {} particles faster than {AT_REST} m/s; {}): lengthen [time] duration",
            p.len(),
            trace.join("; ")
        );
    }
    Ok((p.x, sim.time))
}

/// (runout of the 98th-percentile particle, runout of the deposit tip), both as (L - L0) / L0.
fn runouts(x: &[Vec3], dx: f32) -> (f64, f64) {
    let mut xs: Vec<f32> = x.iter().map(|v| v.x).collect();
    xs.sort_by(f32::total_cmp);
    let p98 = xs[((xs.len() - 1) as f64 * 0.98) as usize] as f64;
    let tip = deposit_tip(&xs, dx) as f64;
    ((p98 - L0) / L0, (tip - L0) / L0)
}

/// The collapse with the scene's transfer (MLS-MPM/APIC).
pub fn run(ctx: &Ctx) -> Result<Vec<Row>> {
    run_with(ctx, "granular_column", None)
}

/// The same collapse with CK-MPM ([`crate::case::CK`]; experimental; CPU, or CUDA on one GPU).
pub fn run_ck(ctx: &Ctx) -> Result<Vec<Row>> {
    run_with(ctx, "granular_column_ck", Some(crate::case::CK))
}

fn run_with(ctx: &Ctx, case: &str, solver: Option<SolverSettings>) -> Result<Vec<Row>> {
    // Quick: h = L0/20 (the scene file); full: h = L0/40.
    let dx = if ctx.options.quick { 0.005 } else { 0.0025 };
    let (x, at_rest) = collapse(ctx, dx, solver)?;
    let (p98, tip) = runouts(&x, dx);
    let a = H0 / L0;
    // Small-a law (L_inf - L0) / L0 = lambda1 a: Lube 1.2, Lajeunesse 1.8; their mean.
    let reference = 1.5 * a;
    let front = |lambda: f64, label: &str, rgb| Series {
        label: label.into(),
        points: vec![
            (L0 * (1.0 + lambda * a), 0.0),
            (L0 * (1.0 + lambda * a), H0),
        ],
        rgb,
        style: Style::Line,
    };
    // The first z layer of particles shows the deposit.
    let z0 = x.iter().map(|v| v.z).fold(f32::INFINITY, f32::min);
    let deposit: Vec<(f64, f64)> = x
        .iter()
        .filter(|v| v.z < z0 + 0.25 * dx)
        .map(|v| (v.x as f64, v.y as f64))
        .collect();
    ctx.plot(
        &format!("{case}_deposit"),
        Plot {
            title: format!(
                "Granular column collapse, a = {a}: deposit (h = L0/{:.0})",
                L0 / dx as f64
            ),
            x_label: "x (m)".into(),
            y_label: "y (m)".into(),
            series: vec![
                Series {
                    label: "initial column".into(),
                    points: vec![(0.0, H0), (L0, H0), (L0, 0.0)],
                    rgb: [150, 150, 150],
                    style: Style::Line,
                },
                Series {
                    label: "rtmpm deposit".into(),
                    points: deposit,
                    rgb: [200, 140, 40],
                    style: Style::Markers,
                },
                front(1.2, "runout, Lube 2005", [40, 40, 40]),
                front(1.8, "runout, Lajeunesse 2005", [40, 90, 220]),
            ],
        },
    );
    let row = |what: &str, simulated: f64| Row {
        case: case.into(),
        quantity: format!(
            "runout (L - L0)/L0, {what}, h = L0/{:.0}, deposit at t = {at_rest:.2} s",
            L0 / dx as f64
        ),
        reference,
        simulated,
        error: rel_pct(simulated, reference),
        // REFERENCES.md: plane-strain MPM against side-walled experiments, +-30-50 % at best.
        tolerance: 50.0,
        unit: "%",
    };
    let rows = vec![row("98th pct", p98), row("deposit tip", tip)];
    if ctx.options.convergence {
        for h in [0.01f32, 0.005, 0.0025] {
            let (p98, tip) = runouts(&collapse(ctx, h, solver)?.0, h);
            println!(
                "convergence granular_column: h = L0/{:.0}: runout 98th pct {p98:.3}, tip {tip:.3}",
                L0 / h as f64
            );
        }
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::deposit_tip;

    #[test]
    fn deposit_tip_skips_isolated_particles_only() {
        // A deposit spaced 0.1 apart up to 1.0, then particles thrown ahead.
        let mut x: Vec<f32> = (0..=10).map(|i| i as f32 * 0.1).collect();
        assert_eq!(deposit_tip(&x, 0.15), 1.0);
        x.extend([1.5, 2.0]);
        assert_eq!(deposit_tip(&x, 0.15), 1.0);
        // A thin but connected tail counts.
        x.truncate(11);
        x.extend([1.1, 1.2]);
        assert_eq!(deposit_tip(&x, 0.15), 1.2);
    }
}
