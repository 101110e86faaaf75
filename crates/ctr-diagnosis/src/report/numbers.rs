//! The numbers of a JSON value (a finding's parameters as the robot file writes them)
//! by key path, the same value with each number replaced, and a number in words.

use serde_json::Value;

/// Share of the largest number printed beside it (a value's interval ends) below which a
/// number prints as 0: what is left there is the fit's rounding (a play fitted to
/// 2e-11 deg beside an interval up to 0.95 deg, an interval end at -1e-14).
pub(crate) const NEGLIGIBLE_BESIDE: f64 = 1e-6;

/// [`sig`] of `v` printed beside `others` (its interval's ends): 0 where it is below
/// [`NEGLIGIBLE_BESIDE`] of the largest of them all.
///
/// ```text
/// assert_eq!(sig_beside(2e-11, &[0.0, 0.9545]), "0");
/// assert_eq!(sig_beside(-1e-14, &[0.5314, 2.332]), "0");
/// assert_eq!(sig_beside(0.5314, &[0.0, 2.332]), "0.5314");
/// ```
pub(crate) fn sig_beside(v: f64, others: &[f64]) -> String {
    let largest = others
        .iter()
        .chain([&v])
        .filter(|x| x.is_finite())
        .fold(0.0_f64, |m, x| m.max(x.abs()));
    if v.is_finite() && v.abs() < NEGLIGIBLE_BESIDE * largest {
        return "0".into();
    }
    sig(v)
}

/// A value and its interval's ends in words, each by [`sig_beside`] the others
/// (`None`: an end not known).
pub(crate) fn sig_interval(v: f64, lo: Option<f64>, hi: Option<f64>) -> [Option<String>; 3] {
    let all: Vec<f64> = [Some(v), lo, hi].into_iter().flatten().collect();
    [Some(v), lo, hi].map(|x| x.map(|x| sig_beside(x, &all)))
}

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

/// A parameter (or an identified combination) with its value and the ends of its 95 %
/// interval (`None`: the data set no bound there).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Interval {
    /// Its key path in the parameters (`tau_s`, `peak_deg[0]`) or the combination in
    /// words.
    pub name: String,
    /// The fitted value.
    pub value: f64,
    /// Lower end.
    pub lo: Option<f64>,
    /// Upper end.
    pub hi: Option<f64>,
}

/// A finding's parameters with their intervals (`ci95`, the same shape with each number
/// `[lo, hi]`), and after them the combinations `ci95.identified` lists.
pub(crate) fn intervals(params: &Value, ci95: &Value) -> (Vec<Interval>, Vec<Interval>) {
    let mut values = Vec::new();
    leaves(params, "", &mut values);
    let mut bounds = Vec::new();
    let without = match ci95 {
        Value::Object(m) => {
            let mut m = m.clone();
            m.remove("identified");
            Value::Object(m)
        }
        other => other.clone(),
    };
    leaves(&without, "", &mut bounds);
    let end = |name: &str, k: usize| {
        let path = format!("{name}[{k}]");
        bounds.iter().find(|(p, _)| *p == path).map(|(_, v)| *v)
    };
    let parameters = values
        .into_iter()
        .map(|(name, value)| Interval {
            lo: end(&name, 0),
            hi: end(&name, 1),
            name,
            value,
        })
        .collect();
    let identified = ci95
        .get("identified")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
        .map(|c| Interval {
            name: c["combination"].as_str().unwrap_or("?").to_owned(),
            value: c["value"].as_f64().unwrap_or(f64::NAN),
            lo: c["ci95"][0].as_f64(),
            hi: c["ci95"][1].as_f64(),
        })
        .collect();
    (parameters, identified)
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

    /// What the fit leaves at rounding beside an interval prints as 0; what is not
    /// negligible keeps its four digits.
    #[test]
    fn rounding_beside_an_interval_prints_as_zero() {
        assert_eq!(sig_beside(2e-11, &[0.0, 0.9545]), "0");
        assert_eq!(sig_beside(-1e-14, &[0.5314, 2.332]), "0");
        assert_eq!(sig_beside(0.5314, &[0.0, 2.332]), "0.5314");
        assert_eq!(sig_beside(2e-11, &[1e-11, 3e-11]), sig(2e-11));
        let [v, lo, hi] = sig_interval(0.5314, Some(-1e-14), Some(2.332));
        assert_eq!(
            (v.unwrap(), lo.unwrap(), hi.unwrap()),
            ("0.5314".into(), "0".into(), "2.332".into())
        );
        assert_eq!(sig_interval(1.0, None, Some(2.0))[1], None);
    }
}
