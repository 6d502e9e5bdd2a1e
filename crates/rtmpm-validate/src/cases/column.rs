//! Case 9: a cohesive soil (non-associated Cam-clay) stands below its critical height and
//! collapses above it. A free-standing column carries its weight in uniaxial compression, so it
//! stands while `rho g H` stays below the uniaxial compressive strength `q_u` of the material's
//! yield surface (`Nacc::uniaxial_strength`; for a Mohr-Coulomb soil `q_u = 2 c tan(45 + phi/2)`,
//! half the Rankine/Terzaghi height of a vertical cut, REFERENCES.md case 9): `H_c = q_u / (rho g)`.

use crate::case::{Ctx, Row};
use anyhow::{Context, Result, bail, ensure};
use rtmpm_geometry::Shape;
use rtmpm_geometry::shape::Cuboid;
use rtmpm_physics::material::Model;
use rtmpm_physics::math::Vec3;
use rtmpm_render::plot::{Plot, Series, Style};

/// A column stands: its final height is at least this fraction of its initial height (elastic
/// compression under its weight is far smaller).
const STANDS: f64 = 0.95;
/// A column collapsed: its final height is at most this fraction of its initial height.
const COLLAPSED: f64 = 0.7;

pub fn run(ctx: &Ctx) -> Result<Vec<Row>> {
    let mut scene = ctx.scene("cohesive_column.toml")?;
    let m = &scene.materials[0];
    let Model::Nacc(soil) = &m.model else {
        bail!("cohesive_column.toml: the material must be nacc");
    };
    let g = scene.gravity.length() as f64;
    let qu = soil.uniaxial_strength(soil.alpha0) as f64;
    let hc = qu / (m.density as f64 * g);
    // The columns: (centre x, initial height), from the scene's boxes.
    let columns: Vec<(f32, f64)> = scene
        .bodies
        .iter()
        .map(|b| match b.shape {
            Shape::Box(Cuboid { min, max }) => Ok((0.5 * (min.x + max.x), (max.y - min.y) as f64)),
            _ => bail!("cohesive_column.toml: the columns must be boxes"),
        })
        .collect::<Result<_>>()?;
    if !ctx.options.quick {
        // Full: a finer grid, the same columns and domain interior.
        let dx = 0.5 * scene.dx;
        let t = scene.walls.thickness as f32;
        scene.domain_min += Vec3::splat(t * (scene.dx - dx));
        scene.domain_max -= Vec3::splat(t * (scene.dx - dx));
        scene.dx = dx;
    }
    let dx = scene.dx;
    let p0 = scene.sample_particles()?;
    let start = p0.x.clone();
    let mut last = None;
    ctx.run(scene, p0, |_, p| last = Some(p.clone()))?;
    let p = last.context("no frame")?;
    let mut rows = Vec::new();
    let mut series = Vec::new();
    for (k, &(xc, h0)) in columns.iter().enumerate() {
        // The column's particles: those nearer its centre than the other column's.
        let mine = |x: &Vec3| {
            columns
                .iter()
                .enumerate()
                .min_by(|a, b| (a.1.0 - x.x).abs().total_cmp(&(b.1.0 - x.x).abs()))
                .map(|(j, _)| j)
                == Some(k)
        };
        let top = |x: &[Vec3]| {
            x.iter()
                .filter(|x| mine(x))
                .map(|x| x.y)
                .fold(f32::NEG_INFINITY, f32::max) as f64
        };
        let (t0, t1) = (top(&start), top(&p.x));
        ensure!(t1.is_finite(), "column {k} has no particle left");
        // The height lost by the top particle (the top particle sits below the surface by the
        // lattice's offset, which the difference cancels).
        let ratio = (h0 - (t0 - t1)) / h0;
        let rel = h0 / hc;
        let (quantity, bound, error) = if rel < 1.0 {
            (
                format!("H = {rel:.2} H_c: final/initial height (stands: >= {STANDS})"),
                STANDS,
                (STANDS - ratio).max(0.0),
            )
        } else {
            (
                format!("H = {rel:.2} H_c: final/initial height (collapses: <= {COLLAPSED})"),
                COLLAPSED,
                (ratio - COLLAPSED).max(0.0),
            )
        };
        rows.push(Row {
            case: "cohesive_column".into(),
            quantity,
            reference: bound,
            simulated: ratio,
            error,
            tolerance: 0.0,
            unit: "",
        });
        series.push(Series {
            label: format!("H = {rel:.2} H_c"),
            points: p
                .x
                .iter()
                .filter(|x| mine(x) && x.z.abs() < 0.5 * dx)
                .map(|x| ((x.x - xc) as f64, x.y as f64))
                .collect(),
            rgb: if rel < 1.0 {
                [40, 120, 200]
            } else {
                [200, 90, 30]
            },
            style: Style::Markers,
        });
    }
    series.push(Series {
        label: format!("critical height H_c = q_u / (rho g) = {hc:.4} m"),
        points: vec![(-0.12, hc), (0.12, hc)],
        rgb: [40, 40, 40],
        style: Style::Line,
    });
    ctx.plot(
        "cohesive_column",
        Plot {
            title: format!(
                "Cohesive (NACC) columns after release, h = {dx} m: section through the centre"
            ),
            x_label: "x - x_column (m)".into(),
            y_label: "y (m)".into(),
            series,
        },
    );
    Ok(rows)
}
