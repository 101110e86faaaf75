//! End-to-end tests of `ctr-cli diagnose`, `calibrate` and `evaluate` on a shared
//! recording: the report, the fitted robot file that `fk` reads as is, the plots, and
//! bad input.

mod common;
use common::*;
use std::path::PathBuf;

/// `rel` in the shared reference data (`tests/data/shared`).
fn shared(rel: &str) -> PathBuf {
    common::analysis::shared().join(rel)
}

#[test]
fn diagnose_writes_report_fitted_model_and_plots() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("report.json");
    let fitted = dir.path().join("fitted.toml");
    let plots = dir.path().join("plots");
    let html = dir.path().join("report.html");
    let robot = shared("robots/liu2023.toml");
    let rec = shared("recordings/dev-clearance.csv");
    let o = run(&[
        "diagnose",
        "--robot",
        arg(&robot),
        "--recording",
        arg(&rec),
        "--report",
        arg(&report),
        "--out",
        arg(&fitted),
        "--plots",
        arg(&plots),
        "--html",
        arg(&html),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("leaves out the clearance between the tubes"),
        "{out}"
    );
    assert!(out.contains("consistent with measurement noise"), "{out}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    for key in ["baseline", "findings", "final", "unexplained"] {
        assert!(r.get(key).is_some(), "report lacks {key}");
    }
    let f = &r["findings"][0];
    assert_eq!(f["effect"], "clearance");
    for key in [
        "explanation",
        "where",
        "parameters",
        "rms_mm_before",
        "rms_mm_after",
        "heldout_rms_mm_before",
        "heldout_rms_mm_after",
    ] {
        assert!(f.get(key).is_some(), "finding lacks {key}");
    }
    let peak = f["parameters"]["peak_deg"][0].as_f64().unwrap();
    let max = f["parameters"]["max_deflection_deg"][0].as_f64().unwrap();
    assert!((peak - 205.0).abs() < 5.0 && (max - 2.5).abs() < 0.2, "{f}");
    assert!(
        r["final"]["heldout_rms_mm"].as_f64().unwrap()
            < 0.25 * r["baseline"]["heldout_rms_mm"].as_f64().unwrap()
    );
    // the plots
    let names: Vec<String> = std::fs::read_dir(&plots)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        names.iter().any(|n| n.starts_with("residual-vs-")),
        "{names:?}"
    );
    assert!(names.iter().any(|n| n == "run-rot-inner.svg"), "{names:?}");
    // the page: the verdict, the finding, every plot inline, the same SVG as the files
    let page = std::fs::read_to_string(&html).unwrap();
    assert!(page.contains("data-explained=\"true\"><strong>Verdict: explained</strong>"));
    assert!(
        page.contains("<h3><code>clearance</code> <span class=\"badge\">established</span></h3>")
    );
    assert_eq!(page.matches("<svg ").count(), names.len());
    let run_plot = std::fs::read_to_string(plots.join("run-rot-inner.svg")).unwrap();
    assert!(page.contains(run_plot.trim_end()));
    // the fitted model is a robot file: evaluate reads it and it is better on every run
    let o = run(&[
        "evaluate",
        "--robot",
        arg(&robot),
        "--robot",
        arg(&fitted),
        "--recording",
        arg(&rec),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let table = String::from_utf8_lossy(&o.stdout).into_owned();
    let all = table.lines().find(|l| l.starts_with("all")).unwrap();
    let nums: Vec<f64> = all
        .split(|c: char| c.is_whitespace() || c == '/')
        .filter_map(|t| t.parse().ok())
        .collect();
    // rows, mean/max before, mean/max after
    assert!(nums[3] < 0.3 * nums[1], "{table}");
    // and fk solves with it
    let joints = dir.path().join("joints.csv");
    std::fs::write(&joints, "s1_mm,theta1_deg,s2_mm,theta2_deg\n35,0,80,205\n").unwrap();
    let o = run(&["fk", "--robot", arg(&fitted), "--joints", arg(&joints)]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn calibrate_fits_the_named_effect_only() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("report.json");
    let o = run(&[
        "calibrate",
        "--robot",
        arg(&shared("robots/nitinol3.toml")),
        "--recording",
        arg(&shared("recordings/dev-registration.csv")),
        "--fit",
        "registration",
        "--report",
        arg(&report),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let f = &r["findings"][0];
    assert_eq!(f["effect"], "registration");
    let t = &f["parameters"]["translation_mm"];
    let want = [3.0, -2.0, 5.0];
    for i in 0..3 {
        assert!((t[i].as_f64().unwrap() - want[i]).abs() < 0.3, "{t}");
    }
    assert!((f["parameters"]["rotation_deg"].as_f64().unwrap() - 2.0).abs() < 0.1);
}

#[test]
fn bad_diagnose_input_exits_2_with_one_line() {
    let robot = shared("robots/liu2023.toml");
    let rec = shared("recordings/dev-clean.csv");
    let dir = tempfile::tempdir().unwrap();
    let untimed = dir.path().join("untimed.csv");
    std::fs::write(
        &untimed,
        "s1_mm,theta1_deg,s2_mm,theta2_deg,x_mm,y_mm,z_mm\n35,0,80,0,1,2,80\n35,0,81,0,1,2,81\n",
    )
    .unwrap();
    // `diagnose --robot ROBOT --recording REC EXTRA...`
    let diagnose = |extra: &[&'static str]| -> Vec<&str> {
        [
            &["diagnose", "--robot", arg(&robot), "--recording", arg(&rec)][..],
            extra,
        ]
        .concat()
    };
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (diagnose(&["--effects", "lag"]), "unknown effect \"lag\""),
        (
            diagnose(&["--warn-margin=-1"]),
            "-1 is not a warning margin",
        ),
        (
            vec![
                "evaluate",
                "--robot",
                arg(&robot),
                "--recording",
                arg(&rec),
                "--warn-margin",
                "nan",
            ],
            "NaN is not a warning margin",
        ),
        (diagnose(&["--holdout", "blocks:1"]), "wanted blocks:K"),
        (
            diagnose(&["--holdout", "runs:nope"]),
            "no run labelled nope",
        ),
        (
            diagnose(&["--report", "/nonexistent/r.json"]),
            "directory /nonexistent does not exist",
        ),
        (
            vec![
                "diagnose",
                "--robot",
                arg(&robot),
                "--recording",
                "/nonexistent.csv",
            ],
            "/nonexistent.csv: cannot read",
        ),
        (
            vec![
                "calibrate",
                "--robot",
                arg(&robot),
                "--recording",
                arg(&untimed),
                "--fit",
                "latency",
            ],
            "no t_s column",
        ),
    ];
    for (args, want) in cases {
        let o = run(&args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        assert!(e.contains(want), "{args:?}: {e}");
        assert_eq!(e.trim_end().lines().count(), 1, "{args:?}: {e}");
    }
}

/// `--suggest-run`: where the data leave parameters poorly pinned (the feed-gain
/// recording's stand-ins for a gain outside the vocabulary), the report names the next run and the file is a joint
/// trajectory `hw run` reads (t_s and the joint columns, inside the recorded ranges);
/// where everything is pinned, no file and a line on stderr.
#[test]
fn diagnose_suggests_the_next_run_as_a_joint_file() {
    let dir = tempfile::tempdir().unwrap();
    let run_csv = dir.path().join("run.csv");
    let report = dir.path().join("report.json");
    let robot = shared("robots/liu2023.toml");
    let rec = shared("recordings/dev-unexplained-feed-gain.csv");
    let o = run(&[
        "diagnose",
        "--robot",
        arg(&robot),
        "--recording",
        arg(&rec),
        "--report",
        arg(&report),
        "--suggest-run",
        arg(&run_csv),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("Next run to record: "), "{out}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let rows = r["suggested_run"]["rows"].as_u64().unwrap() as usize;
    assert!(!r["suggested_run"]["expected"]
        .as_array()
        .unwrap()
        .is_empty());
    let spec = ctr_formats::RobotSpec::from_path(&robot).unwrap();
    let table = ctr_formats::JointTable::from_path(&run_csv, &spec.robot).unwrap();
    assert_eq!(table.len(), rows);
    let text = std::fs::read_to_string(&run_csv).unwrap();
    assert!(
        text.starts_with("t_s,s1_mm,theta1_deg,s2_mm,theta2_deg\n"),
        "{text}"
    );
    let recorded = ctr_formats::Recording::from_path(&rec, 2).unwrap();
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        for (k, q) in v[1..].iter().enumerate() {
            let (lo, hi) = recorded
                .rows
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |a, row| {
                    (a.0.min(row.q[k]), a.1.max(row.q[k]))
                });
            assert!(
                *q >= lo - 1e-9 && *q <= hi + 1e-9,
                "column {k}: {q} outside [{lo}, {hi}]"
            );
        }
    }
    // a recording whose parameters are pinned: nothing written, said why
    let pinned = dir.path().join("none.csv");
    let o = run(&[
        "diagnose",
        "--robot",
        arg(&robot),
        "--recording",
        arg(&shared("recordings/dev-latency.csv")),
        "--suggest-run",
        arg(&pinned),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!pinned.exists());
    assert!(stderr(&o).contains("no run suggested"), "{}", stderr(&o));
}
