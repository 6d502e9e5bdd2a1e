//! The published validation cases of rtmpm (`validation/*.toml`): each runs its scenes on a
//! backend, measures, and compares with its reference (an analytic solution or an experiment),
//! giving the rows of a table and plots. `rtmpm validate` prints the table; Python's
//! `rtmpm.validate()` returns it. Sources: the repository's `docs/validation.md`.
//!
//! ```no_run
//! let options = rtmpm_validate::Options { quick: true, ..Default::default() };
//! let report = rtmpm_validate::run(&["free_fall".to_string()], &options)?;
//! print!("{}", report.table());
//! assert!(report.passed());
//! # Ok::<(), anyhow::Error>(())
//! ```

mod case;
mod cases;
mod measure;

use case::Ctx;
pub use case::{Options, Row};
pub use rtmpm_backends::BackendKind;

use anyhow::{Context, Result, bail};
use cases::{bar, column, dam_break, disks, free_fall, granular, hydrostatic, rigid, slump};
use rtmpm_render::plot::Plot;
use std::path::{Path, PathBuf};
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

/// The cases of the experimental CK-MPM transfer (either backend; CUDA on one GPU): run only
/// when named (`--case vibrating_bar_ck`), never by default.
const CK_CASES: &[(&str, Case)] = &[
    ("hydrostatic_column_ck", hydrostatic::run_ck),
    ("vibrating_bar_ck", bar::run_ck),
    ("dam_break_ck", dam_break::run_ck),
    ("granular_column_ck", granular::run_ck),
];

/// The cases that need the cargo feature `rigid`.
const RIGID_CASES: &[&str] = &["archimedes", "sinking", "rigid_momentum"];

/// The names of the cases: those run by default, then the experimental CK-MPM ones (run only
/// when named).
pub fn case_names() -> Vec<&'static str> {
    CASES.iter().chain(CK_CASES).map(|(n, _)| *n).collect()
}

/// What a validation run gives: the table's rows, the plots, and the cases that could not run.
pub struct Report {
    /// Every measured quantity of the cases that ran, in the order run.
    pub rows: Vec<Row>,
    /// The plots of the cases, by name (written as `<name>.png` by [`Report::write_plots`]).
    pub plots: Vec<(String, Plot)>,
    /// Cases that could not run (a backend that refuses its scene, a blow-up), with the reason.
    pub broken: Vec<(String, String)>,
    /// Cases left out with the reason (the rigid-body cases in a build without rigid bodies).
    pub skipped: Vec<(String, String)>,
}

impl Report {
    /// True when every row passed and no case was broken.
    pub fn passed(&self) -> bool {
        self.broken.is_empty() && self.rows.iter().all(Row::pass)
    }

    /// The rows that failed.
    pub fn failed(&self) -> impl Iterator<Item = &Row> {
        self.rows.iter().filter(|r| !r.pass())
    }

    /// The table of the rows as `rtmpm validate` prints it, one line per row after a header.
    pub fn table(&self) -> String {
        let mut t = format!(
            "{:<24} {:<44} {:>12} {:>12} {:>11} {:>11}  result\n",
            "case", "quantity", "reference", "simulated", "error", "tolerance"
        );
        for r in &self.rows {
            let num = |v: f64| {
                if r.unit == "%" || v == 0.0 || (1e-2..1e5).contains(&v.abs()) {
                    format!("{v:.4}")
                } else {
                    format!("{v:.3e}")
                }
            };
            t += &format!(
                "{:<24} {:<44} {:>12} {:>12} {:>11} {:>11}  {}\n",
                r.case,
                r.quantity,
                num(r.reference),
                num(r.simulated),
                format!("{}{}", num(r.error), r.unit),
                format!("{}{}", num(r.tolerance), r.unit),
                if r.pass() { "PASS" } else { "FAIL" }
            );
        }
        t
    }

    /// Write the plots into `dir` (created when missing) as PNG files; returns their paths.
    pub fn write_plots(&self, dir: &Path) -> Result<Vec<PathBuf>> {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        let mut paths = Vec::new();
        for (name, plot) in &self.plots {
            let path = dir.join(format!("{name}.png"));
            plot.render(900, 560)
                .write_png(&path)
                .with_context(|| format!("writing {}", path.display()))?;
            paths.push(path);
        }
        Ok(paths)
    }
}

/// Run the named cases (every default case when `cases` is empty; the CK-MPM cases only when
/// named) with `options`, printing each case's progress on stderr. An unknown name or a missing
/// scene folder is an error; a case that cannot run is reported in [`Report::broken`] and the
/// others still run.
pub fn run(cases: &[String], options: &Options) -> Result<Report> {
    if !options.scenes.is_dir() {
        bail!(
            "validation scenes not found in {} (run from the repository root or pass --scenes)",
            options.scenes.display()
        );
    }
    for name in cases {
        if !case_names().contains(&name.as_str()) {
            bail!("unknown case `{name}`; cases: {}", case_names().join(", "));
        }
    }
    let selected: Vec<&(&str, Case)> = CASES
        .iter()
        .filter(|(n, _)| cases.is_empty() || cases.iter().any(|c| c == n))
        .chain(
            CK_CASES
                .iter()
                .filter(|(n, _)| cases.iter().any(|c| c == n)),
        )
        .collect();
    let ctx = Ctx::new(options);
    let mut report = Report {
        rows: Vec::new(),
        plots: Vec::new(),
        broken: Vec::new(),
        skipped: Vec::new(),
    };
    for (name, case) in selected {
        if RIGID_CASES.contains(name) && !rigid::available() && cases.is_empty() {
            let why = format!("it {}", rigid::NEEDS_FEATURE);
            eprintln!("validate: {name} skipped: {why}");
            report.skipped.push((name.to_string(), why));
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
                report.rows.extend(r);
            }
            Err(e) => {
                eprintln!("validate: {name} could not run: {e:#}");
                report.broken.push((name.to_string(), format!("{e:#}")));
            }
        }
    }
    report.plots = ctx.take_plots();
    Ok(report)
}
