//! Keyword arguments as a `FilterConfig`, each named as in report.json's
//! `"config"`.

use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};

use pathdensity_core::config::FilterConfig;
use pathdensity_core::method::MethodSet;

use crate::errors::value_error;

/// A Python value as JSON, for the configuration's serde form.
pub(crate) fn to_json(v: &Bound<'_, PyAny>) -> PyResult<serde_json::Value> {
    use serde_json::Value;
    if v.is_none() {
        return Ok(Value::Null);
    }
    if let Ok(b) = v.cast::<pyo3::types::PyBool>() {
        return Ok(Value::Bool(b.is_true()));
    }
    if let Ok(s) = v.cast::<PyString>() {
        return Ok(Value::String(s.to_str()?.to_owned()));
    }
    if v.hasattr("__index__")? {
        if let Ok(i) = v.extract::<i64>() {
            return Ok(i.into());
        }
        if let Ok(u) = v.extract::<u64>() {
            return Ok(u.into());
        }
    }
    if let Ok(f) = v.extract::<f64>() {
        return Ok(serde_json::Number::from_f64(f).map_or(
            // Not JSON: the field check below refuses it with the value.
            Value::String(f.to_string()),
            Value::Number,
        ));
    }
    if let Ok(items) = v.try_iter() {
        return items.map(|i| to_json(&i?)).collect();
    }
    Err(value_error(format!(
        "cannot take {} as an option value",
        v.repr()?
    )))
}

/// The configuration of `options` (FilterConfig's fields, names as in
/// report.json's "config"; `methods` a list of names or a comma string),
/// every other field as the command line defaults it.
pub(crate) fn config_of(options: Option<&Bound<'_, PyDict>>) -> PyResult<FilterConfig> {
    let defaults = FilterConfig {
        methods: MethodSet::default_here(),
        ..FilterConfig::DEFAULT
    };
    let serde_json::Value::Object(mut fields) =
        serde_json::to_value(defaults).expect("the configuration serialises")
    else {
        unreachable!("a struct serialises to an object")
    };
    let Some(options) = options else {
        return Ok(defaults);
    };
    for (key, value) in options.iter() {
        let name: String = key.extract()?;
        if !fields.contains_key(&name) {
            let known: Vec<&str> = fields.keys().map(String::as_str).collect();
            return Err(PyTypeError::new_err(format!(
                "filter() got an unexpected keyword argument {name:?} (the configuration's fields are {})",
                known.join(", ")
            )));
        }
        let mut json = to_json(&value)?;
        if name == "methods"
            && let serde_json::Value::String(s) = &json
        {
            json = s
                .split(',')
                .map(|m| serde_json::Value::String(m.trim().to_owned()))
                .filter(|m| m.as_str() != Some(""))
                .collect();
        }
        // This field alone, so that the message names it.
        let one = serde_json::json!({ &name: json });
        if let Err(e) = serde_json::from_value::<FilterConfig>(one) {
            return Err(value_error(format!(
                "invalid value {} for {name}: {e}",
                value.repr()?
            )));
        }
        fields.insert(name, json);
    }
    serde_json::from_value(serde_json::Value::Object(fields))
        .map_err(|e| value_error(e.to_string()))
}
