//! A JSON document kept as a tree: read once from what Python's `json.loads` returns
//! (keys in document order, numbers exact), written back with `serde_json` (the
//! serializer `ctr-cli --report` writes with) and handed to Python as fresh plain
//! objects on every request.
//!
//! Why not `serde_json::Value`: without serde_json's `preserve_order` feature its
//! objects sort their keys, and its default float parsing may be off by one unit in the
//! last place; the report's text must come back byte for byte.

use pyo3::exceptions::PyKeyError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString};
use serde::{Serialize, Serializer};

/// A JSON value with its objects' keys in document order.
#[derive(Clone, Debug, PartialEq)]
pub enum Json {
    /// `null`.
    Null,
    /// `true` or `false`.
    Bool(bool),
    /// An integer (a report's counts and file lines).
    Int(i128),
    /// A finite number with a fraction or exponent.
    Float(f64),
    /// A string.
    Str(String),
    /// An array.
    Array(Vec<Json>),
    /// An object, its members in document order.
    Object(Vec<(String, Json)>),
}

impl Json {
    /// The tree of a value `json.loads` returned (`None`, `bool`, `int`, `float`, `str`,
    /// `list`, `dict` with `str` keys); `Err` names the first value that is none of
    /// those or has no JSON text (`NaN`, an infinity, an `int` beyond 128 bits).
    pub fn from_py(obj: &Bound<'_, PyAny>) -> Result<Json, String> {
        let not_json = || {
            let text = obj
                .repr()
                .map_or_else(|_| "a value".to_owned(), |r| r.to_string());
            format!("{text} is not a JSON value")
        };
        if obj.is_none() {
            Ok(Json::Null)
        } else if let Ok(b) = obj.cast::<PyBool>() {
            Ok(Json::Bool(b.is_true()))
        } else if obj.is_instance_of::<PyInt>() {
            obj.extract().map(Json::Int).map_err(|_| not_json())
        } else if let Ok(x) = obj.cast::<PyFloat>() {
            let x = x.value();
            x.is_finite().then_some(Json::Float(x)).ok_or_else(not_json)
        } else if let Ok(s) = obj.cast::<PyString>() {
            s.to_cow()
                .map(|s| Json::Str(s.into_owned()))
                .map_err(|_| not_json())
        } else if let Ok(list) = obj.cast::<PyList>() {
            list.iter()
                .map(|item| Json::from_py(&item))
                .collect::<Result<_, _>>()
                .map(Json::Array)
        } else if let Ok(dict) = obj.cast::<PyDict>() {
            dict.iter()
                .map(|(k, v)| {
                    let key = k.cast::<PyString>().map_err(|_| not_json())?;
                    let key = key.to_cow().map_err(|_| not_json())?.into_owned();
                    Ok((key, Json::from_py(&v)?))
                })
                .collect::<Result<_, _>>()
                .map(Json::Object)
        } else {
            Err(not_json())
        }
    }

    /// The value as new plain Python objects (`dict`, `list`, `str`, `int`, `float`,
    /// `bool`, `None`), as `json.loads` makes them.
    pub fn to_py<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        Ok(match self {
            Json::Null => py.None().into_bound(py),
            Json::Bool(b) => PyBool::new(py, *b).to_owned().into_any(),
            Json::Int(i) => (*i).into_pyobject(py)?.into_any(),
            Json::Float(x) => PyFloat::new(py, *x).into_any(),
            Json::Str(s) => PyString::new(py, s).into_any(),
            Json::Array(items) => {
                let items = items
                    .iter()
                    .map(|v| v.to_py(py))
                    .collect::<PyResult<Vec<_>>>()?;
                PyList::new(py, items)?.into_any()
            }
            Json::Object(members) => {
                let d = PyDict::new(py);
                for (k, v) in members {
                    d.set_item(k, v.to_py(py)?)?;
                }
                d.into_any()
            }
        })
    }

    /// Member `key` of an object as new Python objects; `KeyError` where there is none
    /// (as a `dict` raises it).
    pub fn item<'py>(&self, py: Python<'py>, key: &str) -> PyResult<Bound<'py, PyAny>> {
        let member = match self {
            Json::Object(members) => members.iter().find(|(k, _)| k == key),
            _ => None,
        };
        match member {
            Some((_, v)) => v.to_py(py),
            None => Err(PyKeyError::new_err(key.to_owned())),
        }
    }
}

impl Serialize for Json {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Json::Null => s.serialize_unit(),
            Json::Bool(b) => s.serialize_bool(*b),
            Json::Int(i) => s.serialize_i128(*i),
            Json::Float(x) => s.serialize_f64(*x),
            Json::Str(t) => s.serialize_str(t),
            Json::Array(items) => s.collect_seq(items),
            Json::Object(members) => s.collect_map(members.iter().map(|(k, v)| (k, v))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tree a `serde_json::Value` stands for (its objects' keys sorted).
    fn tree(v: &serde_json::Value) -> Json {
        use serde_json::Value;
        match v {
            Value::Null => Json::Null,
            Value::Bool(b) => Json::Bool(*b),
            Value::Number(n) => n
                .as_i64()
                .map(|i| Json::Int(i.into()))
                .or_else(|| n.as_u64().map(|u| Json::Int(u.into())))
                .unwrap_or_else(|| Json::Float(n.as_f64().unwrap())),
            Value::String(s) => Json::Str(s.clone()),
            Value::Array(a) => Json::Array(a.iter().map(tree).collect()),
            Value::Object(m) => Json::Object(m.iter().map(|(k, v)| (k.clone(), tree(v))).collect()),
        }
    }

    /// Written as serde_json writes the same value, compact and pretty: numbers, empty
    /// arrays and objects, escapes, nesting.
    #[test]
    fn writes_as_serde_json() {
        let v = serde_json::json!({
            "a": [1.5, {"b": "x,\"y\":[z]\n\u{e9}", "c": []}, {}],
            "d": {"e": null, "f": -0.1e-300, "g": [[1], [2, 3]], "h": true},
            "i": [u64::MAX, -3, 2.0, -0.0, 1e21, 0.30000000000000004, 1e-7],
        });
        let t = tree(&v);
        assert_eq!(
            serde_json::to_string(&t).unwrap(),
            serde_json::to_string(&v).unwrap()
        );
        assert_eq!(
            serde_json::to_string_pretty(&t).unwrap(),
            serde_json::to_string_pretty(&v).unwrap()
        );
    }

    /// Members stay in document order (a report's fields in struct order).
    #[test]
    fn keeps_member_order() {
        let t = Json::Object(vec![
            ("z".into(), Json::Int(1)),
            ("a".into(), Json::Array(vec![])),
        ]);
        assert_eq!(serde_json::to_string(&t).unwrap(), r#"{"z":1,"a":[]}"#);
        assert_eq!(
            serde_json::to_string_pretty(&t).unwrap(),
            "{\n  \"z\": 1,\n  \"a\": []\n}"
        );
    }
}
