//! Case 6: granular column collapse against Lube 2005 / Lajeunesse 2005 runout scaling.

use super::{Ctx, Row, rel_pct};
use anyhow::Result;

/// Initial column length and height (m), as in validation/granular_column.toml.
const L0: f64 = 0.1;
const H0: f64 = 0.1;

pub fn run(ctx: &Ctx) -> Result<Vec<Row>> {
    let scene = ctx.scene("granular_column.toml")?;
    let p0 = scene.sample_particles()?;
    let mut last = None;
    ctx.run(scene, p0, |_, p| last = Some(p.clone()))?;
    let p = last.expect("frames");
    let mut x: Vec<f32> = p.x.iter().map(|v| v.x).collect();
    x.sort_by(f32::total_cmp);
    let l_inf = x[((x.len() - 1) as f64 * 0.98) as usize] as f64;
    let runout = (l_inf - L0) / L0;
    let a = H0 / L0;
    // Small-a law (L_inf - L0) / L0 = lambda1 a: Lube 1.2, Lajeunesse 1.8; their mean.
    let reference = 1.5 * a;
    Ok(vec![Row {
        case: "granular_column".into(),
        quantity: format!("runout (L - L0)/L0 of the 98th pct, a = {a}"),
        reference,
        simulated: runout,
        error: rel_pct(runout, reference),
        tolerance: 50.0,
        unit: "%",
    }])
}
