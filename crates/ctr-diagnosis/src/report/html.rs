//! The report as one self-contained HTML page (`ctr-cli diagnose --html`,
//! `ctr_py.Report.to_html()`): inline CSS and inline SVG plots, no script, no font and
//! nothing else fetched, so it opens offline and can be mailed as one file.
//!
//! The page is drawn from the report's JSON (the text `--report` writes, compact), the
//! recording it was made from, the user's robot and the fitted one: both front ends
//! build a [`Page`] from the same four and get the same bytes. It shows, in order: the
//! verdict (`explained` or not, against the noise); the error before and after, and the
//! rows where a model is near a snap (when there are); the findings with their
//! parameters and 95 % intervals, and what the data do not pin; the error by run; the
//! residual against the feature that located the error; each run's measured and
//! modelled tip paths; what is left unexplained and where; the suggested next run; the
//! fitted robot file; how the figures were made. Every string taken from a file (run
//! labels, names, the robot file) is HTML-escaped.

use crate::error::DiagnoseError;
use crate::locate::stability::Stability;
use crate::report::numbers::{intervals, sig, sig_interval, Interval};
use crate::report::plots::{Plot, RunError, Traces};
use crate::report::Grade;
use crate::report::{fitted_file, Report, REMOVED};
use ctr_analysis::model::ModelSpec;
use ctr_formats::{Recording, RobotSpec};
use serde_json::Value;
use std::fmt::Write;

/// The page's style sheet (inline: the page fetches nothing).
const STYLE: &str = "body{font-family:sans-serif;max-width:960px;margin:2em auto;padding:0 1em;\
color:#222;line-height:1.4}h1{font-size:1.5em}h2{font-size:1.2em;margin-top:2em;\
border-bottom:1px solid #ccc}table{border-collapse:collapse;margin:.5em 0}\
td,th{border:1px solid #ccc;padding:.2em .6em;text-align:left}td.n{text-align:right;\
font-variant-numeric:tabular-nums}.verdict{font-size:1.2em;padding:.6em 1em;\
border-radius:4px}.explained{background:#e3f4e1;border:1px solid #4a9a3f}\
.unexplained{background:#fdf0dc;border:1px solid #c77c02}figure{margin:1em 0}\
figure svg{max-width:100%;height:auto;border:1px solid #eee}\
pre{background:#f6f6f6;padding:.8em;overflow-x:auto}.note{color:#555}";

/// A diagnosis report ready to be drawn: the report's JSON, the recording's name, both
/// models' tips along the recording, and the fitted robot file.
///
/// ```no_run
/// use ctr_analysis::model::ModelSpec;
/// use ctr_formats::{Recording, RobotSpec};
/// use std::path::Path;
/// let spec = RobotSpec::from_path(Path::new("robot.toml"))?;
/// let rec = Recording::from_path(Path::new("rec.csv"), spec.robot.n_tubes())?;
/// let d = ctr_diagnosis::diagnose(&ModelSpec::from_spec(&spec), &rec, &Default::default())?;
/// let page = ctr_diagnosis::Page::new(&d.report, &rec, &spec, &d.fitted_spec(&spec))?;
/// std::fs::write("report.html", page.to_html()?)?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug)]
pub struct Page {
    recording: String,
    report: Value,
    traces: Traces,
    fitted_file: String,
}

impl Page {
    /// The page of `report`, made from `rec` with the user's robot `user`; `fitted` is
    /// the fitted robot ([`Diagnosis::fitted_spec`](crate::Diagnosis::fitted_spec)).
    pub fn new(
        report: &Report,
        rec: &Recording,
        user: &RobotSpec,
        fitted: &RobotSpec,
    ) -> Result<Page, DiagnoseError> {
        let json = serde_json::to_string(report).expect("a report serializes");
        Page::from_json(&json, rec, user, fitted)
    }

    /// [`new`](Self::new) from the report's JSON text (as `serde_json` writes a
    /// [`Report`]; what `ctr_py` keeps).
    pub fn from_json(
        report_json: &str,
        rec: &Recording,
        user: &RobotSpec,
        fitted: &RobotSpec,
    ) -> Result<Page, DiagnoseError> {
        let report: Value = serde_json::from_str(report_json)
            .map_err(|e| DiagnoseError::Model(format!("the report is not JSON: {e}")))?;
        let traces = Traces::new(
            &report,
            rec,
            &ModelSpec::from_spec(user),
            &ModelSpec::from_spec(fitted),
        )?;
        // a report written before grades counts its findings established
        let graded: Vec<(&str, Grade)> = report["findings"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(|f| {
                let grade = f["grade"].as_str().and_then(Grade::parse);
                Some((f["effect"].as_str()?, grade.unwrap_or(Grade::Established)))
            })
            .collect();
        let fitted_file = fitted_file(fitted, &graded, false);
        Ok(Page {
            recording: rec.file.clone(),
            report,
            traces,
            fitted_file,
        })
    }

    /// The plots, as `ctr-cli diagnose --plots` writes them (one SVG file each).
    pub fn plots(&self) -> Result<Vec<Plot>, DiagnoseError> {
        self.traces.plots().map_err(DiagnoseError::Plot)
    }

    /// The whole page.
    pub fn to_html(&self) -> Result<String, DiagnoseError> {
        let plots = self.plots()?;
        let r = &self.report;
        let name = escape(&self.recording);
        let mut h = format!(
            "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
             <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
             <title>Diagnosis of {name}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n\
             <h1>Diagnosis of {name}</h1>\n"
        );
        verdict(&mut h, r);
        findings(&mut h, r);
        h += "<h2 id=\"error-by-run\">Error by run</h2>\n";
        run_table(&mut h, &self.traces.run_errors());
        let figure = |h: &mut String, p: &Plot| {
            let _ = write!(
                h,
                "<figure id=\"{}\" aria-label=\"{}\">\n{}\n</figure>\n",
                escape(&p.file_name),
                escape(&p.caption),
                p.svg.trim_end()
            );
        };
        let (by_run, rest) = plots.split_first().expect("error by run is always drawn");
        figure(&mut h, by_run);
        let (residual, paths): (Vec<&Plot>, Vec<&Plot>) = rest
            .iter()
            .partition(|p| p.file_name.starts_with("residual-vs-"));
        h += "<h2 id=\"residual\">The residual against what located it</h2>\n";
        match residual.first() {
            Some(p) => {
                h += "<p>The size of the tip error against the feature the user model's \
                      error follows most (before: user model; after: fitted).</p>\n";
                figure(&mut h, p);
            }
            None => {
                h += "<p>The error was not located on a joint, an exposed length, a relative \
                      angle or time (see where it sits below), so there is no plot.</p>\n"
            }
        }
        h += "<h2 id=\"paths\">Tip paths, run by run</h2>\n";
        for p in paths {
            figure(&mut h, p);
        }
        left(&mut h, r);
        suggested(&mut h, r);
        let _ = write!(
            h,
            "<h2 id=\"fitted\">The fitted robot file</h2>\n<p>As <code>ctr-cli diagnose \
             --out</code> writes it; <code>ctr-cli fk</code> reads it as is.</p>\n\
             <pre>{}</pre>\n",
            escape(&self.fitted_file)
        );
        method(&mut h, r);
        h += "</body>\n</html>\n";
        Ok(h)
    }
}

/// `s` with `&`, `<`, `>`, `"` and `'` written as HTML entities.
///
/// ```
/// assert_eq!(ctr_diagnosis::escape_html("<a href='x'>&</a>"), "&lt;a href=&#39;x&#39;&gt;&amp;&lt;/a&gt;");
/// ```
pub fn escape_html(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out += "&amp;",
            '<' => out += "&lt;",
            '>' => out += "&gt;",
            '"' => out += "&quot;",
            '\'' => out += "&#39;",
            c => out.push(c),
        }
    }
    out
}

use escape_html as escape;

/// A JSON string, escaped ("" when absent).
fn text(v: &Value) -> String {
    escape(v.as_str().unwrap_or_default())
}

/// A JSON number (NaN when null or absent).
fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

/// A length in mm as the summary writes it.
fn mm(v: &Value) -> String {
    format!("{:.3}", num(v))
}

fn array(v: &Value) -> &[Value] {
    v.as_array().map_or(&[], Vec::as_slice)
}

fn verdict(h: &mut String, r: &Value) {
    let explained = r["explained"].as_bool() == Some(true);
    let (class, word) = if explained {
        ("explained", "explained")
    } else {
        ("unexplained", "not explained")
    };
    let _ = write!(
        h,
        "<p id=\"verdict\" class=\"verdict {class}\" data-explained=\"{explained}\">\
         <strong>Verdict: {word}</strong> (<code>explained: {explained}</code>): after \
         fitting, {} mm RMS is left on held-out rows ({} mm with tracker outliers set \
         aside) against {} mm of noise estimated from the data.</p>\n\
         <table id=\"figures\"><tr><th>model</th><th>RMS, fit rows (mm)</th>\
         <th>largest, fit rows (mm)</th><th>RMS, held-out rows (mm)</th></tr>\n",
        mm(&r["final"]["heldout_rms_mm"]),
        mm(&r["final_inliers"]["heldout_rms_mm"]),
        mm(&r["noise"]["rms_mm"])
    );
    for (label, f) in [
        ("user model", &r["baseline"]),
        ("fitted", &r["final"]),
        ("fitted, outliers set aside", &r["final_inliers"]),
    ] {
        let _ = writeln!(
            h,
            "<tr><td>{label}</td><td class=\"n\">{}</td><td class=\"n\">{}</td>\
             <td class=\"n\">{}</td></tr>",
            mm(&f["rms_mm"]),
            mm(&f["max_mm"]),
            mm(&f["heldout_rms_mm"])
        );
    }
    h.push_str("</table>\n");
    // the tip angles apart from the positions (only with angular columns)
    if let Some(deg) = r["final"]["heldout_rms_deg"].as_f64() {
        let _ = writeln!(
            h,
            "<p id=\"angles\">Tip angle: {:.2} deg RMS on held-out rows after fitting, {:.2} deg \
             before, against {:.2} deg of noise (the figures in mm above are of the tip \
             position alone).</p>",
            deg,
            num(&r["baseline"]["heldout_rms_deg"]),
            num(&r["noise"]["angular"]["rms_deg"])
        );
    }
    // the rows near a snap (a report without the key: none said)
    let near = serde_json::from_value::<Stability>(r["stability"].clone())
        .ok()
        .and_then(|s| s.words());
    if let Some(words) = near {
        let _ = writeln!(h, "<p id=\"near-snap\">{}</p>", escape(&words));
    }
}

/// One interval as a table row: name, value, lower and upper end.
fn interval_row(h: &mut String, i: &Interval) {
    let [v, lo, hi] = sig_interval(i.value, i.lo, i.hi).map(|x| x.unwrap_or("not bounded".into()));
    let _ = writeln!(
        h,
        "<tr><td>{}</td><td class=\"n\">{v}</td><td class=\"n\">{lo}</td><td class=\"n\">{hi}</td></tr>",
        escape(&i.name),
    );
}

/// A finding's grade in its JSON (a report written before grades: established).
fn grade_of(f: &Value) -> Grade {
    f["grade"]
        .as_str()
        .and_then(Grade::parse)
        .unwrap_or(Grade::Established)
}

fn findings(h: &mut String, r: &Value) {
    h.push_str("<h2 id=\"findings\">Findings</h2>\n");
    let found = array(&r["findings"]);
    if found.is_empty() {
        h.push_str("<p>No left-out effect explains part of the error.</p>\n");
    }
    // established first: the physics the data show, then what only helps prediction
    for grade in [Grade::Established, Grade::Predictive] {
        let of_grade: Vec<&Value> = found.iter().filter(|f| grade_of(f) == grade).collect();
        if of_grade.is_empty() {
            continue;
        }
        let _ = writeln!(
            h,
            "<h3 class=\"grade\">{}</h3>",
            match grade {
                Grade::Established => "Established: physics the data show",
                Grade::Predictive =>
                    "Predictive: each helps prediction, its form is not established (it may \
                     stand in for something outside the vocabulary)",
            }
        );
        of_grade.into_iter().for_each(|f| finding(h, f));
    }
    not_physics(h, r);
}

/// One finding's section: what, where, what the fitted model loses without it, its
/// parameters with their intervals, why it is only predictive, its equals.
fn finding(h: &mut String, f: &Value) {
    let grade = grade_of(f);
    let angles = f["heldout_rms_deg"]
        .as_array()
        .filter(|a| a.len() == 2)
        .map_or(String::new(), |a| {
            format!(
                "; tip angle {:.2} instead of {:.2} deg",
                num(&a[0]),
                num(&a[1])
            )
        });
    let _ = write!(
        h,
        "<section class=\"finding {}\" data-grade=\"{}\">\n<h3><code>{}</code> \
         <span class=\"badge\">{}</span></h3>\n<p>{}</p>\n<p>Where: {}</p>\n\
         <p>Without it, the fitted model's held-out RMS would be {} mm instead of {} mm{} \
         (fit rows {} instead of {} mm).</p>\n\
         <table class=\"parameters\"><tr><th>parameter</th><th>fitted</th>\
         <th>95 % interval, low</th><th>high</th></tr>\n",
        grade.as_str(),
        grade.as_str(),
        text(&f["effect"]),
        grade.as_str(),
        text(&f["explanation"]),
        text(&f["where"]),
        mm(&f["heldout_rms_mm_before"]),
        mm(&f["heldout_rms_mm_after"]),
        angles,
        mm(&f["rms_mm_before"]),
        mm(&f["rms_mm_after"])
    );
    let (parameters, identified) = intervals(&f["parameters"], &f["ci95"]);
    parameters.iter().for_each(|p| interval_row(h, p));
    if !identified.is_empty() {
        h.push_str("<tr><th colspan=\"4\">identified combinations</th></tr>\n");
        identified.iter().for_each(|p| interval_row(h, p));
    }
    h.push_str("</table>\n");
    if grade == Grade::Predictive {
        let _ = writeln!(
            h,
            "<p class=\"why-predictive\">Why predictive: {}.</p>",
            text(&f["grade_reason"])
        );
    }
    let equally: Vec<String> = array(&f["equally_explained_by"])
        .iter()
        .map(|a| {
            format!(
                "<code>{}</code> ({} mm held out)",
                text(&a["effect"]),
                mm(&a["heldout_rms_mm"])
            )
        })
        .collect();
    if !equally.is_empty() {
        let _ = writeln!(
            h,
            "<p class=\"equally\">Equally: {} explain{} this residual as well; the data \
             do not tell them apart (this one is named only because the search took it \
             first).</p>",
            equally.join(", "),
            if equally.len() == 1 { "s" } else { "" }
        );
    }
    h.push_str("</section>\n");
}

/// The findings the checks took out, and what the data do not identify.
fn not_physics(h: &mut String, r: &Value) {
    for t in array(&r["tried"]) {
        if let Some(why) = t["note"].as_str().and_then(|n| n.strip_prefix(REMOVED)) {
            let _ = writeln!(
                h,
                "<p class=\"not-physics\">Not physics: <code>{}</code> ({}).</p>",
                text(&t["effect"]),
                escape(why)
            );
        }
    }
    for line in array(&r["identifiability"]) {
        let _ = writeln!(h, "<p>Identifiability: {}.</p>", text(line));
    }
    for c in array(&r["correlated"]) {
        let _ = writeln!(
            h,
            "<p>Hard to tell apart: {} and {} (correlation {:.2}).</p>",
            text(&c["a"]),
            text(&c["b"]),
            num(&c["r"])
        );
    }
}

fn run_table(h: &mut String, runs: &[RunError]) {
    h.push_str(
        "<table id=\"runs\"><tr><th>run</th><th>rows</th><th>RMS, user model (mm)</th>\
         <th>RMS, fitted (mm)</th></tr>\n",
    );
    for run in runs {
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td class=\"n\">{}</td><td class=\"n\">{:.3}</td>\
             <td class=\"n\">{:.3}</td></tr>",
            escape(&run.label),
            run.rows,
            run.before_mm,
            run.after_mm
        );
    }
    h.push_str("</table>\n");
}

/// What is left unexplained and where; the user model's error located; the empirical
/// term.
fn left(h: &mut String, r: &Value) {
    let _ = write!(
        h,
        "<h2 id=\"unexplained\">What is left, and where</h2>\n<p>After fitting: {} mm RMS, \
         {} mm held out. The {}.</p>\n",
        mm(&r["final"]["rms_mm"]),
        mm(&r["final"]["heldout_rms_mm"]),
        text(&r["unexplained"])
    );
    if let Some(e) = r.get("empirical").filter(|e| e.is_object()) {
        empirical(h, e);
    }
    h.push_str(
        "<p>Where the user model's error sat before fitting, strongest pattern first:</p>\n\
         <table id=\"located\"><tr><th>pattern</th><th>share of the squared error</th></tr>\n",
    );
    for s in array(&r["located"]) {
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td class=\"n\">{:.0} %</td></tr>",
            text(&s["text"]),
            100.0 * num(&s["explained"])
        );
    }
    h.push_str("</table>\n");
}

/// The empirical term: a learned discrepancy with its band and inputs, or a linear
/// correction with its largest terms.
fn empirical(h: &mut String, e: &Value) {
    if e["band"].is_object() {
        let _ = write!(
            h,
            "<p id=\"discrepancy\">A learned discrepancy (not physics: {}) leaves {} mm \
             held out; its 95 % band holds {:.0} % of the held-out coordinates (median \
             half-width {} mm). Its inputs, the most telling first:</p>\n\
             <table id=\"empirical\"><tr><th>input</th><th>length scale</th></tr>\n",
            text(&e["method"]),
            mm(&e["heldout_rms_mm"]),
            100.0 * num(&e["band"]["heldout_coverage_95"]),
            mm(&Value::from(
                1.959_963_984_540_054 * num(&e["band"]["median_sd_mm"])
            ))
        );
        for i in array(&e["inputs"]) {
            let _ = writeln!(
                h,
                "<tr><td>{}</td><td class=\"n\">{:.3}</td></tr>",
                text(&i["input"]),
                num(&i["length_scale"])
            );
        }
        h.push_str("</table>\n");
        return;
    }
    let _ = write!(
        h,
        "<p>An empirical term (not physics: {}; {} terms) leaves {} mm held out. Its \
         largest terms:</p>\n<table id=\"empirical\"><tr><th>feature</th><th>axis</th>\
         <th>RMS contribution (mm)</th></tr>\n",
        text(&e["method"]),
        e["terms"].as_u64().unwrap_or_default(),
        mm(&e["heldout_rms_mm"])
    );
    for t in array(&e["dominant"]) {
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{}</td><td class=\"n\">{:.2}</td></tr>",
            text(&t["feature"]),
            text(&t["axis"]),
            num(&t["rms_mm"])
        );
    }
    h.push_str("</table>\n");
}

fn suggested(h: &mut String, r: &Value) {
    h.push_str("<h2 id=\"next-run\">Next run to record</h2>\n");
    let run = &r["suggested_run"];
    if !run.is_object() {
        h.push_str(
            "<p>None suggested: every fitted parameter is pinned well, or no simple run \
             would pin it better.</p>\n",
        );
        return;
    }
    let _ = write!(
        h,
        "<p id=\"suggested-run\">{} ({} rows, one every {} s; <code>ctr-cli diagnose \
         --suggest-run RUN.csv</code> writes its joints). Expected: {}.</p>\n\
         <table><tr><th>parameter</th><th>fitted</th><th>95 % interval now</th>\
         <th>expected after the run</th></tr>\n",
        text(&run["run"]),
        run["rows"].as_u64().unwrap_or_default(),
        sig(num(&run["sample_period_s"])),
        text(&run["why"])
    );
    let pair = |v: &Value| match (v[0].as_f64(), v[1].as_f64()) {
        (Some(lo), Some(hi)) => format!("{} to {}", sig(lo), sig(hi)),
        _ => "not identified".to_owned(),
    };
    for e in array(&run["expected"]) {
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td class=\"n\">{}</td><td class=\"n\">{}</td><td class=\"n\">{}</td></tr>",
            text(&e["parameter"]),
            sig(num(&e["value"])),
            pair(&e["ci95_now"]),
            pair(&e["ci95_expected"])
        );
    }
    h.push_str("</table>\n");
}

/// How the figures were made.
fn method(h: &mut String, r: &Value) {
    let _ = write!(
        h,
        "<h2 id=\"method\">How</h2>\n<ul class=\"note\">\n<li>Split: {} ({} rows fitted, {} \
         held out).</li>\n<li>Noise: {}.</li>\n<li>Intervals: {}.</li>\n<li>Tracker \
         outliers: {} rows ({}).</li>\n<li>Rows whose solve did not converge under the \
         fitted model: {}.</li>\n</ul>\n",
        text(&r["split"]["method"]),
        r["split"]["fit_rows"].as_u64().unwrap_or_default(),
        r["split"]["heldout_rows"].as_u64().unwrap_or_default(),
        text(&r["noise"]["method"]),
        text(&r["uncertainty_method"]),
        array(&r["outlier_lines"]).len(),
        text(&r["outlier_rule"]),
        r["failed_rows"].as_u64().unwrap_or_default()
    );
}
