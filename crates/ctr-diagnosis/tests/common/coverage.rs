//! Intervals (`ci95`) held against the truth: how many scalars they hold, how wide
//! they are, the misses in words (the interval tests of `blind.rs` and `replicas.rs`).

use ctr_diagnosis::Finding;
use serde_json::Value;

/// Absolute floor of a useful half-width, in the parameter's unit (mm, deg, s, a
/// factor or a unit vector's component).
pub const HALF_WIDTH_FLOOR: f64 = 0.05;

/// Numbers of `v` with their key paths.
pub fn numbers(v: &Value, path: &str, out: &mut Vec<(String, f64)>) {
    match v {
        Value::Number(x) => out.push((path.into(), x.as_f64().unwrap())),
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                numbers(x, &format!("{path}[{i}]"), out);
            }
        }
        Value::Object(m) => {
            for (k, x) in m {
                numbers(x, &format!("{path}.{k}"), out);
            }
        }
        _ => {}
    }
}

/// Tube numbers named in an identified combination (`... of tube 2 / ... of tube 1`).
fn tubes_named(s: &str) -> Vec<usize> {
    s.split("tube ")
        .skip(1)
        .filter_map(|t| t.split(|c: char| !c.is_ascii_digit()).next()?.parse().ok())
        .collect()
}

/// Intervals against the truth: how many scalars they hold, their half-widths
/// relative to a quarter of the size plus the floor, the misses in words.
#[derive(Default)]
pub struct Tally {
    pub inside: usize,
    pub total: usize,
    pub widths: Vec<f64>,
    pub misses: Vec<String>,
}

impl Tally {
    pub fn add(&mut self, what: String, truth: f64, fit: f64, lo: f64, hi: f64) {
        self.total += 1;
        let ok = lo <= truth && truth <= hi;
        self.inside += usize::from(ok);
        if !ok {
            self.misses.push(format!(
                "{what}: truth {truth:.4} fit {fit:.4} ci [{lo:.4}, {hi:.4}]"
            ));
        }
        if lo.is_finite() && hi.is_finite() {
            self.widths
                .push((hi - lo) / 2.0 / (0.25 * truth.abs() + HALF_WIDTH_FLOOR));
        }
    }

    /// A finding's intervals against `truth` (the report's form of the effect);
    /// `ratio` gives the truth of an identified combination from the tubes it names.
    pub fn finding(
        &mut self,
        name: &str,
        f: &Finding,
        truth: &Value,
        ratio: impl Fn(&[usize]) -> Option<f64>,
    ) {
        let id = f.effect.as_str();
        let (mut t, mut ci, mut value) = (Vec::new(), Vec::new(), Vec::new());
        numbers(truth, "", &mut t);
        numbers(&f.ci95, "", &mut ci);
        numbers(&f.parameters, "", &mut value);
        let identified = f.ci95.get("identified").and_then(|v| v.as_array());
        for (path, tv) in &t {
            let lo = ci.iter().find(|(p, _)| *p == format!("{path}[0]"));
            let hi = ci.iter().find(|(p, _)| *p == format!("{path}[1]"));
            // no bound (not identified): holds the truth but says nothing; where a
            // combination is identified instead, the combination counts
            let (Some(lo), Some(hi)) = (lo, hi) else {
                continue;
            };
            if identified.is_some() && lo.1 <= 0.2 && hi.1 >= 5.0 {
                continue;
            }
            let fit = value
                .iter()
                .find(|(p, _)| p == path)
                .map_or(f64::NAN, |v| v.1);
            self.add(format!("{name} {id}{path}"), *tv, fit, lo.1, hi.1);
        }
        for c in identified.into_iter().flatten() {
            let combination = c["combination"].as_str().unwrap();
            let Some(tv) = ratio(&tubes_named(combination)) else {
                continue;
            };
            let (lo, hi) = (
                c["ci95"][0].as_f64().unwrap(),
                c["ci95"][1].as_f64().unwrap(),
            );
            let fit = c["value"].as_f64().unwrap();
            self.add(format!("{name} {combination}"), tv, fit, lo, hi);
        }
    }
}

/// Every `ci95` interval of `r`'s findings that does not hold its own parameter's value
/// (an angle of a peak or a rotation up to whole turns), in words: none is expected
/// (issue 42: an interval's end once was another parameter's value).
pub fn intervals_not_holding_their_values(r: &ctr_diagnosis::Report) -> Vec<String> {
    let mut out = Vec::new();
    for f in &r.findings {
        let mut values = Vec::new();
        numbers(&f.parameters, "", &mut values);
        for (path, v) in values {
            // `.key[i]` -> the interval node at the same place
            let mut node = &f.ci95;
            for part in path.trim_start_matches('.').split('.') {
                let (key, index) = match part.split_once('[') {
                    Some((k, i)) => (k, i.trim_end_matches(']').parse::<usize>().ok()),
                    None => (part, None),
                };
                node = &node[key];
                if let Some(i) = index {
                    node = &node[i];
                }
            }
            let (Some(lo), Some(hi)) = (node[0].as_f64(), node[1].as_f64()) else {
                continue; // an open end, or no interval here
            };
            let turns: &[f64] = if path.contains("peak_deg") || path.contains("rotation_deg") {
                &[0.0, 360.0, -360.0]
            } else {
                &[0.0]
            };
            let slack = 1e-9 * (1.0 + v.abs());
            if !turns
                .iter()
                .any(|t| lo - slack <= v + t && v + t <= hi + slack)
            {
                out.push(format!(
                    "{} {path} = {v}: ci95 [{lo}, {hi}]",
                    f.effect.as_str()
                ));
            }
        }
    }
    out
}
