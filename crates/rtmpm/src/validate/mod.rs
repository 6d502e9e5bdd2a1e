//! `rtmpm validate`: run the published validation cases (`validation/*.toml`), measure, compare
//! with the reference and print a table. Sources: `../shared/validation/REFERENCES.md`,
//! `docs/validation.md`.

mod bar;
mod case;
mod column;
mod dam_break;
mod disks;
mod free_fall;
mod granular;
mod hydrostatic;
mod measure;
mod rigid;
mod slump;

use anyhow::{Context, Result, bail};
pub use case::ValidateArgs;
use case::{Ctx, Row};
use std::time::Instant;

type Case = fn(&Ctx) -> Result<Vec<Row>>;

const CASES: &[(&str, Case)] = &[
    ("free_fall", free_fall::run),
    ("hydrostatic_column", hydrostatic::run),
    ("hydrostatic_column_gimp", hydrostatic::run_gimp),
    ("vibrating_bar", bar::run),
    ("vibrating_bar_gimp", bar::run_gimp),
    ("dam_break", dam_break::run),
    ("colliding_disks", disks::run),
    ("granular_column", granular::run),
    ("slump", slump::run),
    ("cohesive_column", column::run),
    ("archimedes", rigid::archimedes),
    ("sinking", rigid::sinking),
    ("rigid_momentum", rigid::momentum),
    ("emitter_mass", rigid::emitter_mass),
];

/// The cases of the experimental CK-MPM transfer (CPU backend only): run only when named
/// (`--case vibrating_bar_ck`), never by default.
const CK_CASES: &[(&str, Case)] = &[
    ("hydrostatic_column_ck", hydrostatic::run_ck),
    ("vibrating_bar_ck", bar::run_ck),
    ("dam_break_ck", dam_break::run_ck),
    ("granular_column_ck", granular::run_ck),
];

/// The cases that need the cargo feature `rigid`.
const RIGID_CASES: &[&str] = &["archimedes", "sinking", "rigid_momentum"];

pub fn validate(args: ValidateArgs) -> Result<()> {
    if !args.scenes.is_dir() {
        bail!(
            "validation scenes not found in {} (run from the repository root or pass --scenes)",
            args.scenes.display()
        );
    }
    for name in &args.case {
        if !CASES.iter().chain(CK_CASES).any(|(n, _)| n == name) {
            let names: Vec<_> = CASES.iter().chain(CK_CASES).map(|(n, _)| *n).collect();
            bail!("unknown case `{name}`; cases: {}", names.join(", "));
        }
    }
    let selected: Vec<&(&str, Case)> = CASES
        .iter()
        .filter(|(n, _)| args.case.is_empty() || args.case.iter().any(|c| c == n))
        .chain(
            CK_CASES
                .iter()
                .filter(|(n, _)| args.case.iter().any(|c| c == n)),
        )
        .collect();
    let ctx = Ctx::new(&args);
    let mut rows = Vec::new();
    // A case that cannot run (a backend that refuses its scene, a blow-up) is reported after
    // the table; the other cases still run.
    let mut broken: Vec<(String, anyhow::Error)> = Vec::new();
    for (name, case) in selected {
        if RIGID_CASES.contains(name) && !rigid::available() && args.case.is_empty() {
            eprintln!("validate: {name} skipped: it {}", rigid::NEEDS_FEATURE);
            continue;
        }
        let start = Instant::now();
        eprintln!("validate: {name} ...");
        match case(&ctx) {
            Ok(r) => {
                eprintln!(
                    "validate: {name} done in {:.1} s",
                    start.elapsed().as_secs_f64()
                );
                rows.extend(r);
            }
            Err(e) => {
                eprintln!("validate: {name} could not run: {e:#}");
                broken.push((name.to_string(), e));
            }
        }
    }
    print_table(&rows);
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    for (name, plot) in ctx.plots().iter() {
        let path = args.out.join(format!("{name}.png"));
        plot.render(900, 560)
            .write_png(&path)
            .with_context(|| format!("writing {}", path.display()))?;
        println!("plot: {}", path.display());
    }
    for (name, e) in &broken {
        println!("case {name} could not run: {e:#}");
    }
    let failed = rows.iter().filter(|r| !r.pass()).count();
    if failed > 0 || !broken.is_empty() {
        bail!(
            "{failed} of {} validation checks failed; {} cases could not run",
            rows.len(),
            broken.len()
        );
    }
    println!("{} passed, 0 failed", rows.len());
    Ok(())
}

fn print_table(rows: &[Row]) {
    println!(
        "{:<24} {:<44} {:>12} {:>12} {:>11} {:>11}  result",
        "case", "quantity", "reference", "simulated", "error", "tolerance"
    );
    for r in rows {
        let num = |v: f64| {
            if r.unit == "%" || v == 0.0 || (1e-2..1e5).contains(&v.abs()) {
                format!("{v:.4}")
            } else {
                format!("{v:.3e}")
            }
        };
        println!(
            "{:<24} {:<44} {:>12} {:>12} {:>11} {:>11}  {}",
            r.case,
            r.quantity,
            num(r.reference),
            num(r.simulated),
            format!("{}{}", num(r.error), r.unit),
            format!("{}{}", num(r.tolerance), r.unit),
            if r.pass() { "PASS" } else { "FAIL" }
        );
    }
}
