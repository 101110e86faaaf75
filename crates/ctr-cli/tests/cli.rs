//! End-to-end tests of `ctr-cli fk`: the bad-input corpus, numbers bit for bit equal to
//! the core, carry-through, thread-count independence, atomic output, exit codes.

use ctr_analysis::batch::WARM_CHUNK_ROWS;
use ctr_core::{Joints, Model, Request, Robot, Solver, TubeParams};

use std::path::PathBuf;
use std::process::Stdio;

mod common;
use common::analysis::core_rows;
use common::{arg, cli, fk_args, repo, run, run_stdin, stderr, stdin_path};

/// Every case under `tests/cli/bad/`: `robot.toml`, `joints.csv` or `joints.parquet`
/// (`targets.csv` or `.parquet` for the `ik-*` cases), `expected.txt` (a stable part of the one-line message), optionally
/// `args` (the whole argument list, one per line) or `extra-args` (appended to
/// `fk --robot robot.toml --joints joints.csv -o OUT`, or for `ik-*` cases to
/// `ik --robot robot.toml --targets targets.csv -o OUT`). Runs in the case's directory;
/// must exit 2 with one line on stderr and write nothing.
#[test]
fn bad_input_corpus_exits_2_with_one_line() {
    let root = repo("tests/cli/bad");
    let mut cases: Vec<PathBuf> = std::fs::read_dir(&root)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_dir())
        .collect();
    cases.sort();
    assert!(cases.len() >= 50, "only {} cases", cases.len());
    let out_dir = tempfile::tempdir().unwrap();
    let mut failures = Vec::new();
    for case in &cases {
        let name = case.file_name().unwrap().to_string_lossy().into_owned();
        let out = out_dir.path().join(format!("{name}.csv"));
        let lines = |file: &str| -> Option<Vec<String>> {
            let text = std::fs::read_to_string(case.join(file)).ok()?;
            Some(text.lines().map(str::to_owned).collect())
        };
        // the input: `joints.csv` (`targets.csv`), or the case's Parquet file
        let input = |stem: &str| {
            let parquet = format!("{stem}.parquet");
            if case.join(&parquet).exists() {
                parquet
            } else {
                format!("{stem}.csv")
            }
        };
        let command: Vec<String> = if name.starts_with("ik-") {
            [
                "ik",
                "--robot",
                "robot.toml",
                "--targets",
                input("targets").as_str(),
                "-o",
            ]
            .map(str::to_owned)
            .to_vec()
        } else {
            [
                "fk",
                "--robot",
                "robot.toml",
                "--joints",
                input("joints").as_str(),
                "-o",
            ]
            .map(str::to_owned)
            .to_vec()
        };
        let args: Vec<String> = match lines("args") {
            Some(a) => a,
            None => command
                .iter()
                .map(|s| s.to_string())
                .chain([arg(&out).to_owned()])
                .chain(lines("extra-args").unwrap_or_default())
                .collect(),
        };
        let expected = std::fs::read_to_string(case.join("expected.txt")).unwrap();
        let expected = expected.trim();
        let o = cli()
            .args(&args)
            .current_dir(case)
            .stdin(Stdio::null())
            .output()
            .unwrap();
        let err = stderr(&o);
        let problems = [
            (
                o.status.code() != Some(2),
                format!("exit {:?}", o.status.code()),
            ),
            (err.lines().count() != 1, "stderr is not one line".into()),
            (!err.starts_with("error: "), "no `error: ` prefix".into()),
            (!err.contains(expected), format!("expected `{expected}`")),
            (out.exists(), "output written".into()),
        ];
        for (bad, what) in problems {
            if bad {
                failures.push(format!("{name}: {what}; stderr: {err}"));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}

/// The tip columns of an output file (the last 7 columns), as f64.
fn tips(csv_text: &str) -> Vec<[f64; 7]> {
    let mut rdr = csv::Reader::from_reader(csv_text.as_bytes());
    let n = rdr.headers().unwrap().len();
    assert_eq!(
        rdr.headers()
            .unwrap()
            .iter()
            .skip(n - 7)
            .collect::<Vec<_>>(),
        ["x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"]
    );
    rdr.records()
        .map(|r| {
            let r = r.unwrap();
            core::array::from_fn(|k| r[n - 7 + k].parse().unwrap())
        })
        .collect()
}

fn params(spec_toml: &str) -> Vec<TubeParams<f64>> {
    ctr_formats::RobotSpec::from_path(&repo(spec_toml))
        .unwrap()
        .robot
        .tube_params()
}

/// The core, called row by row with a fresh solver every `WARM_CHUNK_ROWS` rows, for a
/// two-tube robot: positions and quaternions.
fn core_tips(robot: &str, joints: &[[f64; 4]], model: Model) -> Vec<[f64; 7]> {
    let p: [TubeParams<f64>; 2] = params(robot).try_into().unwrap();
    let robot = Robot::new(p).unwrap();
    core_rows(&robot, joints.as_flattened(), model, WARM_CHUNK_ROWS)
        .iter()
        .map(|r| {
            let ([x, y, z], [w, i, j, k]) = (r.position, r.quaternion);
            [x, y, z, w, i, j, k]
        })
        .collect()
}

fn example_joints() -> Vec<[f64; 4]> {
    let mut rdr = csv::Reader::from_path(repo("data/examples/liu2023-joints.csv")).unwrap();
    rdr.records()
        .map(|r| {
            let r = r.unwrap();
            core::array::from_fn(|k| r[k + 1].parse().unwrap())
        })
        .collect()
}

fn bits(rows: &[[f64; 7]]) -> Vec<u64> {
    rows.iter().flatten().map(|v| v.to_bits()).collect()
}

#[test]
fn fk_output_equals_the_core_bit_for_bit() {
    let joints = example_joints();
    assert!(joints.len() > WARM_CHUNK_ROWS, "spans several chunks");
    for (model, flag) in [(Model::Torsion, None), (Model::Rigid, Some("rigid"))] {
        let mut args = vec![
            "fk",
            "--robot",
            "data/robots/liu2023.toml",
            "--joints",
            "data/examples/liu2023-joints.csv",
        ];
        if let Some(m) = flag {
            args.extend(["--model", m]);
        }
        let o = cli().args(&args).current_dir(repo("")).output().unwrap();
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        assert!(o.stderr.is_empty(), "{}", stderr(&o));
        let got = tips(std::str::from_utf8(&o.stdout).unwrap());
        let want = core_tips("data/robots/liu2023.toml", &joints, model);
        assert_eq!(got.len(), joints.len());
        assert_eq!(bits(&got), bits(&want), "{model:?}");
    }
}

#[test]
fn model_kind_in_the_robot_file_is_used_and_overridden() {
    let dir = tempfile::tempdir().unwrap();
    let robot = dir.path().join("rigid.toml");
    let text = std::fs::read_to_string(repo("data/robots/liu2023.toml")).unwrap();
    std::fs::write(&robot, format!("{text}\n[model]\nkind = \"rigid\"\n")).unwrap();
    let joints = repo("data/examples/liu2023-joints.csv");
    let liu2023 = repo("data/robots/liu2023.toml");
    let from_file = run(&fk_args(&robot, &joints, &[]));
    let rigid = run(&fk_args(&liu2023, &joints, &["--model", "rigid"]));
    let torsion = run(&fk_args(&robot, &joints, &["--model", "torsion"]));
    assert_eq!(from_file.stdout, rigid.stdout);
    assert_ne!(from_file.stdout, torsion.stdout);
}

#[test]
fn three_tube_robot_matches_the_core_too() {
    let mut csv_text = String::from("s1_mm,theta1_deg,s2_mm,theta2_deg,s3_mm,theta3_deg\n");
    let mut joints = Vec::new();
    for i in 0..70 {
        let t = i as f64;
        let row = [
            10.0 + 0.5 * t,
            -180.0 + 5.0 * t,
            30.0 + 0.6 * t,
            90.0 - 3.0 * t,
            50.0 + t,
            2.0 * t,
        ];
        csv_text += &row.map(|v| v.to_string()).join(",");
        csv_text += "\n";
        joints.push(row);
    }
    let robot = repo("data/robots/nitinol3.toml");
    let o = run_stdin(&fk_args(&robot, stdin_path(), &[]), csv_text.as_bytes());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let got = tips(std::str::from_utf8(&o.stdout).unwrap());
    let p: [TubeParams<f64>; 3] = params("data/robots/nitinol3.toml").try_into().unwrap();
    let robot = Robot::new(p).unwrap();
    let mut solver = Solver::<f64, 3>::default();
    for (i, (q, g)) in joints.iter().zip(&got).enumerate() {
        if i % WARM_CHUNK_ROWS == 0 {
            solver = Solver::default();
        }
        let q = Joints::from_mm_deg([q[0], q[2], q[4]], [q[1], q[3], q[5]]);
        let sol = solver
            .solve(&robot, Request::new(q, Model::Torsion))
            .unwrap();
        let p = sol.tip.position;
        assert_eq!([g[0], g[1], g[2]], [p.x, p.y, p.z], "row {i}");
        let w = sol.tip.orientation();
        let s = if w.w < 0.0 { -1.0 } else { 1.0 };
        assert_eq!(
            [g[3], g[4], g[5], g[6]],
            [s * w.w, s * w.i, s * w.j, s * w.k]
        );
    }
}

#[test]
fn extra_columns_are_carried_through_untouched() {
    let input = "label,s1_mm,note,theta1_deg,s2_mm,theta2_deg,t_s\n\
                 \"a, quoted\", 30.0 ,\"say \"\"hi\"\"\",0,80,0,0.5\n\
                 ünïcödé,40,,90,100,-45,1e3\n\
                 plain,45,x,-0.0,105,180,\n";
    let robot = repo("data/robots/liu2023.toml");
    let o = run_stdin(
        &fk_args(&robot, stdin_path(), &["-o", "-"]),
        input.as_bytes(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = String::from_utf8(o.stdout).unwrap();
    let mut a = csv::Reader::from_reader(input.as_bytes());
    let mut b = csv::Reader::from_reader(out.as_bytes());
    let ha: Vec<String> = a.headers().unwrap().iter().map(String::from).collect();
    let hb: Vec<String> = b.headers().unwrap().iter().map(String::from).collect();
    assert_eq!(hb[..ha.len()], ha[..]);
    assert_eq!(hb.len(), ha.len() + 7);
    let ra: Vec<csv::StringRecord> = a.records().map(Result::unwrap).collect();
    let rb: Vec<csv::StringRecord> = b.records().map(Result::unwrap).collect();
    assert_eq!(ra.len(), rb.len());
    for (x, y) in ra.iter().zip(&rb) {
        assert_eq!(
            y.iter().take(x.len()).collect::<Vec<_>>(),
            x.iter().collect::<Vec<_>>()
        );
    }
    // the raw text of plain fields is unchanged
    assert!(out.contains("\n\"a, quoted\", 30.0 ,\"say \"\"hi\"\"\",0,80,0,0.5,"));
    assert!(out.contains("\nplain,45,x,-0.0,105,180,,"));
}

#[test]
fn output_does_not_depend_on_thread_count() {
    let mut input = String::from("s1_mm,theta1_deg,s2_mm,theta2_deg\n");
    for i in 0..250 {
        let t = i as f64;
        let s1 = 20.0 + (t * 0.37) % 50.0;
        input += &format!(
            "{s1},{},{},{}\n",
            (t * 7.3) % 360.0 - 180.0,
            s1 + 25.0 + (t * 0.91) % 70.0,
            (t * 11.1) % 360.0 - 180.0
        );
    }
    let robot = repo("data/robots/liu2023.toml");
    let outputs: Vec<Vec<u8>> = ["1", "2", "3", "16"]
        .iter()
        .map(|n| {
            let args = fk_args(&robot, stdin_path(), &["--threads", n]);
            let o = run_stdin(&args, input.as_bytes());
            assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
            o.stdout
        })
        .collect();
    for o in &outputs[1..] {
        assert!(o == &outputs[0]);
    }
    assert_eq!(outputs[0].iter().filter(|b| **b == b'\n').count(), 251);
}

#[test]
fn failing_runs_leave_an_existing_output_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("tips.csv");
    std::fs::write(&out, "precious\n").unwrap();
    let robot = repo("data/robots/liu2023.toml");
    // bad input in the last row
    let joints = dir.path().join("joints.csv");
    std::fs::write(
        &joints,
        "s1_mm,theta1_deg,s2_mm,theta2_deg\n30,0,80,0\n40,0,90,0\n50,0,40,0\n",
    )
    .unwrap();
    let o = run(&fk_args(&robot, &joints, &["-o", arg(&out)]));
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("joints.csv:4: s2_mm = 40 must be >= s1_mm = 50"));
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "precious\n");
    // solver failure
    let snap = repo("tests/cli/snap");
    let (snap_robot, snap_joints) = (snap.join("robot.toml"), snap.join("joints.csv"));
    let o = run(&fk_args(&snap_robot, &snap_joints, &["-o", arg(&out)]));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "precious\n");
    // no temporary files left behind
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");
    // and a successful run replaces it
    std::fs::write(&joints, "s1_mm,theta1_deg,s2_mm,theta2_deg\n30,0,80,0\n").unwrap();
    let o = run(&fk_args(&robot, &joints, &["-o", arg(&out)]));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(o.stdout.is_empty());
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.starts_with("s1_mm,theta1_deg,s2_mm,theta2_deg,x_mm,"));
    assert_eq!(text.lines().count(), 2);
}

#[test]
fn solver_failures_exit_1_or_are_skipped_or_marked() {
    let snap = repo("tests/cli/snap");
    let (robot, joints) = (snap.join("robot.toml"), snap.join("joints.csv"));
    let base = fk_args(&robot, &joints, &[]);
    let o = run(&base);
    assert_eq!(o.status.code(), Some(1));
    let err = stderr(&o);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("joints.csv:5: solve ended with status iteration_limit (residual_per_mm = "),
        "{err}"
    );
    assert!(err.contains("1 of 6 rows failed"), "{err}");
    assert!(o.stdout.is_empty());

    let o = run(&[&base[..], &["--on-error", "skip"]].concat());
    assert_eq!(o.status.code(), Some(0));
    assert!(stderr(&o).contains("joints.csv:5: skipped: solve ended with status iteration_limit"));
    let out = String::from_utf8(o.stdout).unwrap();
    assert_eq!(out.lines().count(), 6);

    let o = run(&[&base[..], &["--on-error", "mark"]].concat());
    assert_eq!(o.status.code(), Some(0));
    assert!(stderr(&o).contains("joints.csv:5: marked:"));
    let out = String::from_utf8(o.stdout).unwrap();
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 7);
    assert!(lines[0].ends_with(",qz,status,residual_per_mm"));
    assert!(lines[4].contains(",iteration_limit,"));
    assert_eq!(out.matches(",converged,").count(), 5);
}

#[test]
fn header_only_gives_an_empty_table() {
    let robot = repo("data/robots/liu2023.toml");
    let o = run_stdin(
        &fk_args(&robot, stdin_path(), &[]),
        b"label,s1_mm,theta1_deg,s2_mm,theta2_deg\n",
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(
        String::from_utf8(o.stdout).unwrap(),
        "label,s1_mm,theta1_deg,s2_mm,theta2_deg,x_mm,y_mm,z_mm,qw,qx,qy,qz\n"
    );
}

#[test]
fn robot_from_stdin() {
    let robot = std::fs::read(repo("data/robots/liu2023.toml")).unwrap();
    let joints = repo("data/examples/liu2023-joints.csv");
    let a = run_stdin(&fk_args(stdin_path(), &joints, &[]), &robot);
    let b = run(&fk_args(&repo("data/robots/liu2023.toml"), &joints, &[]));
    assert_eq!(a.status.code(), Some(0), "{}", stderr(&a));
    assert_eq!(a.stdout, b.stdout);
    // errors in it are named <stdin>
    let o = run_stdin(
        &fk_args(stdin_path(), &joints, &[]),
        b"[[tube]]\nouter_diameter_mm = 1\n",
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).starts_with("error: <stdin>:1:1: tube 1: missing field"));
}

#[test]
fn help_shows_an_example() {
    for args in [&["--help"][..], &["fk", "--help"], &["help", "fk"]] {
        let o = run(args);
        assert_eq!(o.status.code(), Some(0), "{args:?}");
        let text = String::from_utf8(o.stdout).unwrap();
        assert!(text.contains("Example:"), "{args:?}: {text}");
        assert!(text.contains("ctr-cli fk --robot"), "{args:?}");
    }
    let text = String::from_utf8(run(&["fk", "--help"]).stdout).unwrap();
    for opt in [
        "--robot",
        "--joints",
        "--output",
        "--model",
        "--on-error",
        "--threads",
    ] {
        assert!(text.contains(opt), "{opt}");
    }
    let o = run(&["--version"]);
    assert_eq!(o.status.code(), Some(0));
}

#[test]
fn quiet_on_success_when_stderr_is_not_a_terminal() {
    let (robot, joints) = (
        repo("data/robots/liu2023.toml"),
        repo("data/examples/liu2023-joints.csv"),
    );
    let o = run(&fk_args(&robot, &joints, &[]));
    assert_eq!(o.status.code(), Some(0));
    assert!(o.stderr.is_empty(), "{}", stderr(&o));
}
