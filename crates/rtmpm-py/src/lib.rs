//! placeholder
use pyo3::prelude::*;

#[pymodule]
fn _rtmpm(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
