//! Case 5: two colliding elastic disks (Sulsky, Chen & Schreyer 1994): energy behaviour, with the
//! reference's transfer (linear-hat MPM, MUSL, FLIP; the scene's `[solver]` table).

use crate::case::{Ctx, Row};
use crate::measure::{Curve, rel_pct};
use anyhow::Result;
use rtmpm_render::plot::{Plot, Series, Style};

/// Slab thickness (m): energies are reported per unit thickness.
const THICKNESS: f64 = 0.1;
/// Initial kinetic energy per unit thickness: 2 disks x 1/2 rho pi r^2 |v|^2.
const KE0: f64 = 2.513;

pub fn run(ctx: &Ctx) -> Result<Vec<Row>> {
    let scene = ctx.scene("colliding_disks.toml")?;
    let model = scene.materials[0].model.clone();
    let transfer = scene.solver.describe();
    let p0 = scene.sample_particles()?;
    let (mut ke, mut se, mut total): (Curve, Curve, Curve) = (Vec::new(), Vec::new(), Vec::new());
    let mut missing_energy = false;
    ctx.run(scene, p0, |t, p| {
        let k: f64 = p
            .mass
            .iter()
            .zip(&p.v)
            .map(|(&m, v)| 0.5 * m as f64 * v.length_squared() as f64)
            .sum();
        let mut s = 0.0;
        for i in 0..p.len() {
            match model.energy_density(p.f[i]) {
                Some(psi) => s += p.vol0[i] as f64 * psi as f64,
                None => missing_energy = true,
            }
        }
        ke.push((t, k / THICKNESS));
        se.push((t, s / THICKNESS));
        total.push((t, (k + s) / THICKNESS));
    })?;
    anyhow::ensure!(
        !missing_energy,
        "the disks' material defines no strain energy"
    );
    let e0 = total[0].1;
    let worst = total
        .iter()
        .map(|&(_, e)| rel_pct(e, e0))
        .fold(0.0, f64::max);
    let ke_min = ke.iter().map(|p| p.1).fold(f64::MAX, f64::min);
    ctx.plot(
        "colliding_disks_energy",
        Plot {
            title: format!("Colliding disks: energies per unit thickness ({transfer})"),
            x_label: "t (s)".into(),
            y_label: "energy (J/m)".into(),
            series: vec![
                Series {
                    label: "kinetic".into(),
                    points: ke,
                    rgb: [220, 60, 40],
                    style: Style::Line,
                },
                Series {
                    label: "strain".into(),
                    points: se,
                    rgb: [40, 90, 220],
                    style: Style::Line,
                },
                Series {
                    label: "total".into(),
                    points: total,
                    rgb: [40, 40, 40],
                    style: Style::Line,
                },
            ],
        },
    );
    Ok(vec![
        Row {
            case: "colliding_disks".into(),
            quantity: "initial kinetic energy (J/m)".into(),
            reference: KE0,
            simulated: e0,
            error: rel_pct(e0, KE0),
            // Circles sampled with 2 x 2 particles per cell (4 cells per radius): area within 5 %.
            tolerance: 5.0,
            unit: "%",
        },
        Row {
            case: "colliding_disks".into(),
            quantity: "max |E_total(t) - E_total(0)| / E_total(0)".into(),
            reference: 0.0,
            simulated: worst,
            error: worst,
            tolerance: 5.0,
            unit: "%",
        },
        Row {
            case: "colliding_disks".into(),
            quantity: "min kinetic / initial (drops in contact)".into(),
            reference: 0.0,
            simulated: ke_min / e0,
            error: ke_min / e0,
            tolerance: 0.5,
            unit: "",
        },
    ])
}
