//! The report's HTML page and plots (`ctr_diagnosis::Page`): everything the page must
//! show is there, strings from files are escaped, nothing is fetched.

use ctr_analysis::model::ModelSpec;
use ctr_diagnosis::{diagnose, EffectId, Options, Page};
use ctr_formats::{Recording, RobotSpec};
use std::path::Path;

fn repo(rel: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

/// A run label and a robot name that would be markup if written as they are.
const HOSTILE_LABEL: &str = "<script>alert('run')</script>&feed";
const HOSTILE_NAME: &str = "liu<b>2023</b> & \"friends\"";

/// The bundled example with its first run's label and the robot's name made hostile.
fn hostile_example() -> (RobotSpec, Recording) {
    let toml = std::fs::read_to_string(repo("data/robots/liu2023.toml")).unwrap();
    let toml = toml.replace(
        "name = \"liu2023\"",
        &format!("name = {}", toml_string(HOSTILE_NAME)),
    );
    let spec = RobotSpec::from_toml_str(&toml, "liu2023.toml").unwrap();
    let csv = std::fs::read_to_string(repo("data/examples/liu2023-recording.csv")).unwrap();
    let csv = csv.replace(",feed,", &format!(",{HOSTILE_LABEL},"));
    let rec = Recording::read(csv.as_bytes(), "rec<1>.csv", 2).unwrap();
    assert_eq!(rec.runs[0].label, HOSTILE_LABEL);
    (spec, rec)
}

fn toml_string(s: &str) -> String {
    format!("\"{}\"", s.replace('\\', "\\\\").replace('"', "\\\""))
}

/// Markup and references that would make the page fetch something or run code.
const FORBIDDEN: [&str; 8] = [
    "<script", "src=", "href=", "<link", "@import", "url(", "<iframe", "<object",
];

fn check_self_contained(html: &str) {
    let lower = html.to_ascii_lowercase();
    for bad in FORBIDDEN {
        assert!(!lower.contains(bad), "the page holds {bad}");
    }
    // the only URL is the SVG namespace, which names, not fetches
    let urls = lower.matches("http").count();
    let namespaces = lower
        .matches("xmlns=\"http://www.w3.org/2000/svg\"")
        .count();
    assert_eq!(urls, namespaces);
}

#[test]
fn the_page_shows_verdict_findings_plots_runs_and_the_fitted_file() {
    let (spec, rec) = hostile_example();
    let d = diagnose(&ModelSpec::from_spec(&spec), &rec, &Options::default()).unwrap();
    assert!(d.report.explained);
    let page = Page::new(&d.report, &rec, &spec, &d.fitted_spec(&spec)).unwrap();
    let html = page.to_html().unwrap();
    check_self_contained(&html);
    assert!(html.contains(
        "<p id=\"verdict\" class=\"verdict explained\" data-explained=\"true\"><strong>Verdict: explained</strong>"
    ));
    // the findings with their parameters and intervals
    for f in &d.report.findings {
        assert!(html.contains(&format!(
            "<h3><code>{}</code> <span class=\"badge\">{}</span></h3>",
            f.effect.as_str(),
            f.grade.as_str()
        )));
    }
    assert!(
        html.contains("<tr><td>tau_s</td><td class=\"n\">0.300"),
        "latency's row"
    );
    assert!(html.contains("95 % interval"));
    // one plot for the error by run, one of the residual, one per run
    let plots = page.plots().unwrap();
    assert_eq!(plots.len(), 2 + rec.runs.len());
    assert_eq!(html.matches("<svg ").count(), plots.len());
    assert_eq!(plots[0].file_name, "error-by-run.svg");
    assert!(plots[1].file_name.starts_with("residual-vs-"));
    assert_eq!(
        plots[2].file_name,
        "run-_script_alert__run____script__feed.svg"
    );
    // what is left, where, and the fitted file, as `--out` writes it
    assert!(html.contains("<h2 id=\"unexplained\">What is left, and where</h2>"));
    assert!(html.contains("<table id=\"located\">"));
    let fitted = ctr_diagnosis::fitted_file(&d.fitted_spec(&spec), &d.graded(false), false);
    assert!(html.contains(&ctr_diagnosis::escape_html(&fitted)));
    assert!(html.contains("[model.effects.latency]"));
    // strings from files are escaped, in the page and in the plots
    assert!(!html.contains(HOSTILE_LABEL) && !html.contains("<b>2023"));
    assert!(html.contains("&lt;script&gt;alert(&#39;run&#39;)&lt;/script&gt;&amp;feed"));
    assert!(html.contains("&lt;script&gt;alert(&apos;run&apos;)&lt;/script&gt;&amp;feed"));
    assert!(html.contains("<title>Diagnosis of rec&lt;1&gt;.csv</title>"));
    assert!(html.contains(
        "# Fitted by ctr-cli from liu&lt;b&gt;2023&lt;/b&gt; &amp; &quot;friends&quot;: latency"
    ));
    // drawn from the report's JSON: the same page from the text
    let json = serde_json::to_string(&d.report).unwrap();
    let again = Page::from_json(&json, &rec, &spec, &d.fitted_spec(&spec)).unwrap();
    assert_eq!(again.to_html().unwrap(), html);
}

#[test]
fn an_unexplained_report_shows_the_rest_the_empirical_term_and_a_suggested_run() {
    let spec = RobotSpec::from_path(&repo("data/robots/liu2023.toml")).unwrap();
    let rec = Recording::from_path(&repo("data/examples/liu2023-recording.csv"), 2).unwrap();
    // latency alone leaves the clearance unexplained
    let options = Options {
        candidates: vec![EffectId::Latency],
        ..Options::default()
    };
    let d = diagnose(&ModelSpec::from_spec(&spec), &rec, &options).unwrap();
    assert!(!d.report.explained);
    let mut report = serde_json::to_value(&d.report).unwrap();
    // a suggested run, with a label to escape
    report["suggested_run"] = serde_json::json!({
        "run": "turn tube 2 <alone>", "rows": 120, "sample_period_s": 0.5,
        "why": "the play is poorly pinned", "expected": [{
            "parameter": "tau_s", "value": 0.3, "ci95_now": [0.2, 0.4],
            "ci95_expected": [0.29, 0.31]}, {
            "parameter": "k", "value": 1.0, "ci95_now": [null, null],
            "ci95_expected": [0.9, 1.1]}]
    });
    let json = report.to_string();
    let page = Page::from_json(&json, &rec, &spec, &d.fitted_spec(&spec)).unwrap();
    let html = page.to_html().unwrap();
    check_self_contained(&html);
    assert!(html.contains(
        "<p id=\"verdict\" class=\"verdict unexplained\" data-explained=\"false\"><strong>Verdict: not explained</strong>"
    ));
    let empirical = d
        .report
        .empirical
        .as_ref()
        .expect("an empirical term when unexplained");
    assert!(html.contains(&format!(
        ") leaves {:.3} mm held out",
        empirical.heldout_rms_mm
    )));
    assert!(html.contains(&ctr_diagnosis::escape_html(&d.report.unexplained)));
    assert!(html.contains(
        "<p id=\"suggested-run\">turn tube 2 &lt;alone&gt; (120 rows, one every 0.5000 s"
    ));
    assert!(
        html.contains("<td class=\"n\">not identified</td><td class=\"n\">0.9000 to 1.100</td>")
    );
}
