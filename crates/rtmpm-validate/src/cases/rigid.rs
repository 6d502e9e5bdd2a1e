//! The validation checks of rigid bodies two-way coupled to the material, and of emitters:
//! `archimedes`, `sinking`, `rigid_momentum` (cargo feature `rigid`) and `emitter_mass`. The
//! scenes are `validation/{archimedes,sinking,rigid_momentum,emitter_mass}.toml`; `--quick` runs
//! them as they are (the resolution of the cargo tests `crates/rtmpm-cpu/tests/rigid.rs` and
//! `emitters.rs`), the full run at half the grid spacing (archimedes at a quarter, for twice the
//! time). The measurements are `rtmpm_driver::checks`, shared with those tests.

use crate::case::{Ctx, Row};
use crate::measure::rel_pct;
use anyhow::{Result, anyhow};
use rtmpm_driver::checks;
use rtmpm_render::plot::{Plot, Series, Style};

/// The rigid cases need the rigid-body engine (rapier3d), which this build may lack.
pub const NEEDS_FEATURE: &str = "needs the rigid-body engine, which this build of rtmpm lacks \
     (built without the cargo feature `rigid`, which the default features include): build it \
     with the default features (`cargo build --release`, or `cargo run --release -- validate \
     ...`), or add `--features rigid`";

/// True when this build simulates `[[rigid_body]]` tables.
pub fn available() -> bool {
    rtmpm_rigid::AVAILABLE
}

fn need_engine() -> Result<()> {
    if available() {
        Ok(())
    } else {
        Err(anyhow!("{NEEDS_FEATURE}"))
    }
}

/// The scene text of `file` at the resolution of the run: as it is with `--quick`, else with its
/// grid spacing divided by `refine` (walls kept as thick in metres).
fn scene_text(ctx: &Ctx, file: &str, refine: u32) -> Result<String> {
    let text = ctx.scene_text(file)?;
    if ctx.options.quick {
        Ok(text)
    } else {
        checks::refine(&text, refine).map_err(|e| anyhow!("{file}: {e}"))
    }
}

/// Archimedes at full resolution: dx / 4, 20 cells per box height, the light box's draft 5
/// cells. A node-based boundary places the box to about 0.1 to 0.2 dx (the draft moves with the
/// alignment of the water surface with the grid), and the 5 % on the 2.5 cm draft of
/// the density-250 box is 1.25 mm: at dx / 2 (0.125 dx) the boxes of density 250 and 500 missed
/// it by up to 0.4 % at some alignments, at dx / 4 and dx / 8 none did (validation/RESULTS.md,
/// "Rigid bodies and emitters"; this resolution was chosen after those runs).
const ARCHIMEDES_REFINE: u32 = 4;

/// Seconds simulated by the full-resolution Archimedes runs: finer grids damp the bobbing less,
/// and at dx / 4 the boxes of density 500 and 750 still bobbed by about 7 mm at the scene's 1.5 s
/// (the average over its last half second then moved the density-500 box's fraction by about 3
/// %); they are still by 2.2 s. The quick runs keep the scene's 1.5 s. Chosen after those runs.
const ARCHIMEDES_FULL_DURATION: f64 = 3.0;

/// Archimedes: boxes of density 250, 500 and 750 settle with the submerged fraction of their
/// height, and of their volume in their pose of each averaged frame, equal to the density ratio
/// within 5 %.
pub fn archimedes(ctx: &Ctx) -> Result<Vec<Row>> {
    need_engine()?;
    let mut base = scene_text(ctx, "archimedes.toml", ARCHIMEDES_REFINE)?;
    if !ctx.options.quick {
        base = checks::edit_toml(&base, &[("time.duration", ARCHIMEDES_FULL_DURATION.into())])
            .map_err(|e| anyhow!("archimedes.toml: {e}"))?;
    }
    let mut rows = Vec::new();
    let mut series = Vec::new();
    for (density, rgb) in [
        (250.0, [220, 60, 40]),
        (500.0, [40, 150, 60]),
        (750.0, [40, 90, 220]),
    ] {
        let text = checks::edit_toml(&base, &[("rigid_body.0.density", density.into())])
            .map_err(|e| anyhow!("archimedes.toml: {e}"))?;
        let mut sim = ctx.simulation(&text, "archimedes.toml")?;
        let dx = sim.scene.dx;
        let mut heights = Vec::new();
        let f = checks::float(&mut sim, |t, y| heights.push((t, y)))?;
        let ratio = density / 1000.0;
        rows.push(Row {
            case: "archimedes".into(),
            quantity: format!("submerged fraction, density {density}, dx = {dx}"),
            reference: ratio,
            simulated: f.fraction,
            error: rel_pct(f.fraction, ratio),
            tolerance: 5.0,
            unit: "%",
        });
        // Archimedes' displaced volume, which the fraction of height is only while the box is
        // upright: a box that rocks or rests tilted is measured in its pose of each averaged
        // frame.
        if let Some(v) = f.volume_fraction {
            rows.push(Row {
                case: "archimedes".into(),
                quantity: format!(
                    "submerged volume fraction, density {density} (mean tilt {:.1} deg)",
                    f.mean_tilt_degrees
                ),
                reference: ratio,
                simulated: v,
                error: rel_pct(v, ratio),
                tolerance: 5.0,
                unit: "%",
            });
        }
        // Archimedes' answer as a centre height: an upright box of height h with the fraction
        // `ratio` of it below the open water's surface (measured, averaged as the rows are)
        // has its centre at surface - (ratio - 1/2) h; drawn over the run in a lighter shade of
        // the run's colour. (Tilted by t, a box with the same displaced volume has its centre
        // closer to the surface by the factor cos t: the 500 box, unstable upright, rests tilted
        // with its centre at the surface either way.)
        let rest = f.surface - (ratio - 0.5) * f.height;
        let span = (
            heights.first().map_or(0.0, |p| p.0),
            heights.last().map_or(0.0, |p| p.0),
        );
        series.push(Series {
            label: format!("Archimedes, {density}"),
            points: vec![(span.0, rest), (span.1, rest)],
            rgb: rgb.map(|c| c / 2 + 128),
            style: Style::Line,
        });
        series.push(Series {
            label: format!("density {density}"),
            points: heights,
            rgb,
            style: Style::Line,
        });
    }
    ctx.plot(
        "archimedes_heights",
        Plot {
            title: "Archimedes: centre height of boxes dropped on water".into(),
            x_label: "t (s)".into(),
            y_label: "centre height (m)".into(),
            series,
        },
    );
    Ok(rows)
}

/// Sinking: a sphere of density 2,500 reaches the floor, one of 500 floats.
pub fn sinking(ctx: &Ctx) -> Result<Vec<Row>> {
    need_engine()?;
    let text = scene_text(ctx, "sinking.toml", 2)?;
    let mut sim = ctx.simulation(&text, "sinking.toml")?;
    let dx32 = sim.scene.dx;
    let dx = dx32 as f64;
    let floor = sim.scene.interior().0.y as f64;
    // The initial water surface: the top of the water body.
    let mut p = rtmpm_physics::Particles::default();
    sim.backend.read_particles(&mut p)?;
    let surface = p.x.iter().map(|x| x.y).fold(f32::MIN, f32::max) as f64 + 0.25 * dx;
    let s = checks::settle(&mut sim)?;
    let radius = |b: &rtmpm_rigid::BodyState| b.shape.half_extents(b.rotation).y as f64;
    let gap = s[0].center.y as f64 - radius(&s[0]) - floor;
    // Depth of the light sphere's bottom below the initial surface, over its diameter: 1 or
    // more when fully submerged.
    let light = (surface - (s[1].center.y as f64 - radius(&s[1]))) / (2.0 * radius(&s[1]));
    Ok(vec![
        Row {
            case: "sinking".into(),
            quantity: format!("density 2500: gap to the floor (m), dx = {dx32}"),
            reference: 0.0,
            simulated: gap,
            error: gap.abs(),
            tolerance: dx,
            unit: "m",
        },
        Row {
            case: "sinking".into(),
            quantity: "density 500: submerged fraction (< 1 floats)".into(),
            reference: 0.5,
            simulated: light,
            error: light,
            tolerance: 1.0,
            unit: "",
        },
    ])
}

/// Momentum: a jelly ball hits a free box in zero gravity; momentum of material plus body
/// conserved within 1 %, the box's speed the elastic estimate within 10 %.
pub fn momentum(ctx: &Ctx) -> Result<Vec<Row>> {
    need_engine()?;
    let text = scene_text(ctx, "rigid_momentum.toml", 2)?;
    let mut sim = ctx.simulation(&text, "rigid_momentum.toml")?;
    let dx = sim.scene.dx;
    let c = checks::collide(&mut sim)?;
    Ok(vec![
        Row {
            case: "rigid_momentum".into(),
            quantity: format!("|p_end - p_start| / |p_start|, material + body, dx = {dx}"),
            reference: 0.0,
            simulated: 100.0 * c.momentum_error(),
            error: 100.0 * c.momentum_error(),
            tolerance: 1.0,
            unit: "%",
        },
        Row {
            case: "rigid_momentum".into(),
            quantity: "box speed (m/s) vs elastic estimate".into(),
            reference: c.elastic,
            simulated: c.body_speed,
            error: rel_pct(c.body_speed, c.elastic),
            tolerance: 10.0,
            unit: "%",
        },
    ])
}

/// Emitter: the emitted mass after t equals rate x t within one particle.
pub fn emitter_mass(ctx: &Ctx) -> Result<Vec<Row>> {
    let text = scene_text(ctx, "emitter_mass.toml", 2)?;
    let mut sim = ctx.simulation(&text, "emitter_mass.toml")?;
    let dx = sim.scene.dx;
    let e = checks::emission(&mut sim)?;
    Ok(vec![
        Row {
            case: "emitter_mass".into(),
            quantity: format!("max |emitted - rate t| (particles), dx = {dx}"),
            reference: 0.0,
            simulated: e.worst_particles,
            error: e.worst_particles,
            tolerance: 1.0,
            unit: "",
        },
        Row {
            case: "emitter_mass".into(),
            quantity: "particles emitted in all".into(),
            reference: e.expected,
            simulated: e.emitted as f64,
            error: (e.emitted as f64 - e.expected).abs(),
            tolerance: 1.0,
            unit: "",
        },
    ])
}
