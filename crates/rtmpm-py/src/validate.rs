//! `rtmpm.validate()`: the published validation cases (the `rtmpm-validate` crate, which
//! `rtmpm validate` runs too) from Python, their table as a list of dicts.

use crate::errors::RtmpmError;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use rtmpm_backends::BackendKind;
use std::path::PathBuf;

/// Run published validation cases (``validation/*.toml``: free fall, hydrostatic column,
/// vibrating bar, dam break, colliding disks, granular and cohesive columns, slump, rigid
/// bodies, emitters; ``docs/validation.md``) and compare them with their references, as
/// ``rtmpm validate`` does.
///
/// ``case``: a name or a list of names (default: every case; the experimental CK-MPM cases
/// only when named); ``rtmpm.validation_cases()`` lists them. ``backend``: ``"cpu"``,
/// ``"cuda"`` or ``"auto"``. ``quick``: the coarse resolutions CI runs (seconds to minutes on
/// a few cores). ``scenes``: the folder of the validation scenes (default ``validation`` in
/// the current directory: the repository's). ``plots``: a folder to write the plots into.
///
/// Returns a dict: ``passed`` (every row within its tolerance and no case broken), ``rows``
/// (dicts with ``case``, ``quantity``, ``reference``, ``simulated``, ``error``,
/// ``tolerance``, ``unit``, ``passed``), ``failed`` (the cases with a failing row),
/// ``broken`` and ``skipped`` (dicts of case name to reason), ``table`` (the command line's
/// table as text) and ``plots`` (the files written). Raises ``ValueError`` for an unknown case
/// or a bad argument, ``RtmpmError`` when the scenes are not found.
#[pyfunction]
#[pyo3(signature = (case=None, backend="cpu", quick=true, scenes=None, precision=None, threads=None, plots=None, convergence=false))]
#[allow(clippy::too_many_arguments)]
pub fn validate<'py>(
    py: Python<'py>,
    case: Option<&Bound<'py, PyAny>>,
    backend: &str,
    quick: bool,
    scenes: Option<PathBuf>,
    precision: Option<&str>,
    threads: Option<usize>,
    plots: Option<PathBuf>,
    convergence: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let cases = case_list(case)?;
    let options = options(backend, quick, scenes, precision, threads, convergence)?;
    let report = py
        .detach(|| rtmpm_validate::run(&cases, &options))
        .map_err(|e| RtmpmError::new_err(format!("{e:#}")))?;
    let written = match &plots {
        Some(dir) => py
            .detach(|| report.write_plots(dir))
            .map_err(|e| RtmpmError::new_err(format!("{e:#}")))?,
        None => Vec::new(),
    };
    result(py, &report, &written)
}

/// The names of the validation cases of :func:`validate` (the CK-MPM ones last).
#[pyfunction]
pub fn validation_cases() -> Vec<&'static str> {
    rtmpm_validate::case_names()
}

/// `case` as a list of known case names: None (every case), a name, or a list of names.
fn case_list(case: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<String>> {
    let names: Vec<String> = match case {
        None => Vec::new(),
        Some(c) if c.is_none() => Vec::new(),
        Some(c) => match c.extract::<String>() {
            Ok(s) => vec![s],
            Err(_) => c.extract::<Vec<String>>().map_err(|_| {
                PyValueError::new_err("case must be a case name or a list of case names")
            })?,
        },
    };
    let known = rtmpm_validate::case_names();
    for n in &names {
        if !known.contains(&n.as_str()) {
            return Err(PyValueError::new_err(format!(
                "unknown validation case {n:?}; cases: {}",
                known.join(", ")
            )));
        }
    }
    Ok(names)
}

fn options(
    backend: &str,
    quick: bool,
    scenes: Option<PathBuf>,
    precision: Option<&str>,
    threads: Option<usize>,
    convergence: bool,
) -> PyResult<rtmpm_validate::Options> {
    let backend: BackendKind = backend.parse().map_err(PyValueError::new_err)?;
    if threads == Some(0) {
        return Err(PyValueError::new_err("threads must be at least 1"));
    }
    let precision = precision
        .map(|p| p.parse::<rtmpm_scene::Precision>())
        .transpose()
        .map_err(|e| PyValueError::new_err(format!("precision: {e}")))?;
    let defaults = rtmpm_validate::Options::default();
    Ok(rtmpm_validate::Options {
        backend,
        quick,
        convergence,
        scenes: scenes.unwrap_or(defaults.scenes),
        threads,
        precision,
        particle_state: None,
        cuda: defaults.cuda,
    })
}

/// The report as the dict :func:`validate` returns.
fn result<'py>(
    py: Python<'py>,
    report: &rtmpm_validate::Report,
    written: &[PathBuf],
) -> PyResult<Bound<'py, PyDict>> {
    let rows = PyList::empty(py);
    let mut failed: Vec<&str> = Vec::new();
    for r in &report.rows {
        let d = PyDict::new(py);
        d.set_item("case", &r.case)?;
        d.set_item("quantity", &r.quantity)?;
        d.set_item("reference", r.reference)?;
        d.set_item("simulated", r.simulated)?;
        d.set_item("error", r.error)?;
        d.set_item("tolerance", r.tolerance)?;
        d.set_item("unit", r.unit)?;
        d.set_item("passed", r.pass())?;
        rows.append(d)?;
        if !r.pass() && !failed.contains(&r.case.as_str()) {
            failed.push(&r.case);
        }
    }
    let out = PyDict::new(py);
    out.set_item("passed", report.passed())?;
    out.set_item("rows", rows)?;
    out.set_item("failed", failed)?;
    let reasons = |list: &[(String, String)]| -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (name, why) in list {
            d.set_item(name, why)?;
        }
        Ok(d)
    };
    out.set_item("broken", reasons(&report.broken)?)?;
    out.set_item("skipped", reasons(&report.skipped)?)?;
    out.set_item("table", report.table())?;
    out.set_item("plots", written.to_vec())?;
    Ok(out)
}
