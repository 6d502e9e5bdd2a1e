//! A Python dict (the parsed form of a scene file) to TOML text, for `Scene.from_dict`.

use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

/// `d` as a TOML document; errors name the key path of the offending value.
pub fn dict_to_toml(d: &Bound<'_, PyDict>) -> PyResult<String> {
    let table = table(d, "")?;
    toml::to_string(&table).map_err(|e| PyValueError::new_err(format!("scene dict: {e}")))
}

fn table(d: &Bound<'_, PyDict>, path: &str) -> PyResult<toml::Table> {
    let mut t = toml::Table::new();
    for (k, v) in d.iter() {
        let key: String = k.extract().map_err(|_| {
            PyTypeError::new_err(format!(
                "scene dict: keys must be strings, got {} at `{path}`",
                type_name(&k)
            ))
        })?;
        let here = if path.is_empty() {
            key.clone()
        } else {
            format!("{path}.{key}")
        };
        if v.is_none() {
            // None means "not given" (TOML has no null).
            continue;
        }
        t.insert(key, value(&v, &here)?);
    }
    Ok(t)
}

fn value(v: &Bound<'_, PyAny>, path: &str) -> PyResult<toml::Value> {
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        let i: i64 = v.extract().map_err(|_| {
            PyValueError::new_err(format!("scene dict: `{path}`: integer out of range"))
        })?;
        return Ok(toml::Value::Integer(i));
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(v.extract()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        return Ok(toml::Value::Table(table(d, path)?));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() || v.hasattr("tolist")? {
        // Lists, tuples and NumPy arrays/scalars (through tolist()).
        let v = if v.hasattr("tolist")? {
            v.call_method0("tolist")?
        } else {
            v.clone()
        };
        if !(v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>()) {
            return value(&v, path);
        }
        let mut out = Vec::new();
        for (i, item) in v.try_iter()?.enumerate() {
            out.push(value(&item?, &format!("{path}[{i}]"))?);
        }
        return Ok(toml::Value::Array(out));
    }
    if let Ok(f) = v.extract::<f64>() {
        // Other numbers (e.g. NumPy scalars, fractions).
        return Ok(toml::Value::Float(f));
    }
    Err(PyTypeError::new_err(format!(
        "scene dict: `{path}`: {} is not a TOML value (use dict, list, str, int, float or bool)",
        type_name(v)
    )))
}

fn type_name(v: &Bound<'_, PyAny>) -> String {
    v.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into())
}
