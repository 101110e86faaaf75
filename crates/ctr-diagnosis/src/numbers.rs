//! The numbers of a JSON value (a finding's parameters as the robot file writes them)
//! by key path, the same value with each number replaced, and a number in words.

use serde_json::Value;

/// A number with four significant digits, for the words.
pub(crate) fn sig(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let digits = (3 - v.abs().log10().floor() as i32).clamp(0, 12) as usize;
    format!("{v:.digits$}")
}

/// The numbers of `v` in order, each with its key path.
pub(crate) fn leaves(v: &Value, path: &str, out: &mut Vec<(String, f64)>) {
    match v {
        Value::Number(n) => out.push((path.to_owned(), n.as_f64().unwrap_or(f64::NAN))),
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                leaves(x, &format!("{path}[{i}]"), out);
            }
        }
        Value::Object(m) => {
            for (k, x) in m {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                leaves(x, &p, out);
            }
        }
        _ => {}
    }
}

/// `v` with each number replaced by the next interval of `ints`.
pub(crate) fn replace(v: &Value, ints: &mut impl Iterator<Item = [Option<f64>; 2]>) -> Value {
    match v {
        Value::Number(_) => {
            let [lo, hi] = ints.next().unwrap_or([None, None]);
            serde_json::json!([lo, hi])
        }
        Value::Array(a) => Value::Array(a.iter().map(|x| replace(x, ints)).collect()),
        Value::Object(m) => Value::Object(
            m.iter()
                .map(|(k, x)| (k.clone(), replace(x, ints)))
                .collect(),
        ),
        other => other.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replace_keeps_the_shape() {
        let v = serde_json::json!({"a": [1.0, 2.0], "kind": "x", "b": 3.0});
        let mut l = Vec::new();
        leaves(&v, "", &mut l);
        assert_eq!(l.len(), 3);
        let mut it = (0..3).map(|k| [Some(k as f64), Some(k as f64 + 0.5)]);
        let r = replace(&v, &mut it);
        assert_eq!(r["a"][1], serde_json::json!([1.0, 1.5]));
        assert_eq!(r["kind"], "x");
        assert_eq!(r["b"], serde_json::json!([2.0, 2.5]));
    }
}
