//! Kill-safe output: the real binary, killed with SIGKILL after seeded random delays,
//! many times. `fk -o`, `diagnose --out --report --plots` leave every output either as
//! it was before the run or complete (byte for byte a finished run's), never a part;
//! `hw run -o` leaves the recording's path as it was or complete, and every row it had
//! written before the kill in its journal (`RECORDING.csv.XXXXXX.partial`), a valid
//! CSV. Two runs writing one path at once leave one complete file, never an
//! interleaving.
//!
//! Each killing test stops starting runs after [`BUDGET`] (the delays scale with a
//! finished run's duration, measured first, so a loaded machine kills later rather than
//! only before the output is written). Run with `--nocapture` to see the tallies.

mod common;

use common::analysis::{shared, stable_increments, Rng};
use common::{arg, cli, repo, stderr};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Output, Stdio};
use std::time::{Duration, Instant};

/// Seed of the joints and of the kill delays.
const SEED: u64 = 0x18_0003_c0de;
/// Time after which a killing test starts no more runs.
const BUDGET: Duration = Duration::from_secs(14);
/// Most kills a test tries.
const MAX_KILLS: usize = 60;
/// Fewest kills a test must have made within its budget, and fewest of them that must
/// have hit a running process.
const MIN_KILLS: usize = 8;
const MIN_KILLS_WHILE_RUNNING: usize = 5;
/// Kill delays are uniform in [0, LATE x a finished run's duration] (the shorter of
/// two): most land while the run works, some after it ended.
const LATE: f64 = 1.1;
/// Rows of the joint file `fk` solves (about 0.2 s on one core of this machine).
const FK_ROWS: usize = 60_000;
/// Rows of the trajectory `hw run` plays (about 25 ms each at 50x emulated time).
const HW_ROWS: usize = 40;
/// What an output holds before a run that may replace it.
const PREVIOUS: &[u8] = b"previous\n";
/// Longest a run may take before the test fails.
const DEADLINE: Duration = Duration::from_secs(120);

/// Starts `ctr-cli ARGS` with its output discarded.
fn start(args: &[&str]) -> Child {
    cli()
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// Runs `ctr-cli ARGS` to its end twice, checked to succeed; the shorter time.
fn run_ok(args: &[&str]) -> Duration {
    (0..2)
        .map(|_| {
            let t = Instant::now();
            let o = finish(start(args));
            assert_eq!(o.status.code(), Some(0), "{args:?}: {}", stderr(&o));
            t.elapsed()
        })
        .min()
        .unwrap()
}

/// Waits for `child`, failing the test after [`DEADLINE`].
fn finish(child: Child) -> Output {
    common::wait_within(child, DEADLINE, "ctr-cli")
}

/// A delay uniform in [0, LATE x `full`].
fn delay(rng: &mut Rng, full: Duration) -> Duration {
    full.mul_f64(LATE * rng.uniform())
}

/// Kills `child` with SIGKILL and reaps it; whether it was still running.
fn kill(mut child: Child) -> bool {
    let running = child.try_wait().unwrap().is_none();
    // SIGKILL on Unix; an error only if it had exited already
    let _ = child.kill();
    child.wait().unwrap();
    running
}

/// How the outputs were found after the kills.
#[derive(Debug, Default)]
struct Tally {
    kills: usize,
    /// kills that hit a running process
    while_running: usize,
    previous: usize,
    complete: usize,
}

impl Tally {
    fn check(&self, what: &str) {
        eprintln!("{what}: {self:?}");
        assert!(self.kills >= MIN_KILLS, "{what}: only {} kills", self.kills);
        assert!(
            self.while_running >= MIN_KILLS_WHILE_RUNNING,
            "{what}: too few kills came before the run ended: {self:?}"
        );
    }
}

/// Whether the file at `path` is `previous` or `complete`, failing on anything else.
fn whole(path: &Path, previous: &[u8], complete: &[u8], tally: &mut Tally) {
    let got = std::fs::read(path).unwrap();
    if got == previous {
        tally.previous += 1;
    } else if got == complete {
        tally.complete += 1;
    } else {
        panic!(
            "{}: neither the previous file nor the complete one ({} bytes of {})",
            path.display(),
            got.len(),
            complete.len()
        );
    }
}

/// The files of `dir` but the hidden temporary files `.NAME.XXXXXX.tmp` killed runs
/// leave behind, which are removed.
fn files_after_kill(dir: &Path) -> Vec<String> {
    let mut names = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let entry = entry.unwrap();
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') && name.ends_with(".tmp") {
            std::fs::remove_file(entry.path()).unwrap();
        } else {
            names.push(name);
        }
    }
    names.sort();
    names
}

/// A joint file of `rows` random configurations of nitinol3 in its stable ranges.
fn joint_file(path: &Path, rows: usize, rng: &mut Rng) {
    let increments = stable_increments("nitinol3");
    let mut text = String::from("s1_mm,theta1_deg,s2_mm,theta2_deg,s3_mm,theta3_deg\n");
    for _ in 0..rows {
        let mut s = 0.0;
        let cells: Vec<String> = increments
            .iter()
            .flat_map(|[lo, hi]| {
                s += lo + (hi - lo) * rng.uniform();
                let theta = -180.0 + 360.0 * rng.uniform();
                [format!("{s:.4}"), format!("{theta:.3}")]
            })
            .collect();
        text += &cells.join(",");
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

fn fk_args<'a>(joints: &'a Path, out: &'a Path, robot: &'a str) -> Vec<&'a str> {
    vec![
        "fk",
        "--robot",
        robot,
        "--joints",
        arg(joints),
        "--on-error",
        "mark",
        "-o",
        arg(out),
    ]
}

#[test]
fn fk_killed_at_random_leaves_the_previous_or_the_complete_output() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = Rng(SEED);
    let joints = dir.path().join("joints.csv");
    joint_file(&joints, FK_ROWS, &mut rng);
    let robot = shared().join("robots/nitinol3.toml");
    let robot = arg(&robot);
    let reference = dir.path().join("reference.csv");
    let full = run_ok(&fk_args(&joints, &reference, robot));
    let complete = std::fs::read(&reference).unwrap();
    assert_eq!(
        complete.iter().filter(|&&b| b == b'\n').count(),
        FK_ROWS + 1
    );

    let out = dir.path().join("out.csv");
    let mut tally = Tally::default();
    let started = Instant::now();
    while tally.kills < MAX_KILLS && started.elapsed() < BUDGET {
        std::fs::write(&out, PREVIOUS).unwrap();
        let child = start(&fk_args(&joints, &out, robot));
        std::thread::sleep(delay(&mut rng, full));
        tally.while_running += usize::from(kill(child));
        tally.kills += 1;
        whole(&out, PREVIOUS, &complete, &mut tally);
        assert_eq!(
            files_after_kill(dir.path()),
            ["joints.csv", "out.csv", "reference.csv"]
        );
    }
    tally.check("fk");
}

#[test]
fn two_fk_runs_on_one_path_leave_one_complete_file() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = Rng(SEED ^ 2);
    let robot = shared().join("robots/nitinol3.toml");
    let robot = arg(&robot);
    let (a, b) = (dir.path().join("a.csv"), dir.path().join("b.csv"));
    joint_file(&a, FK_ROWS / 2, &mut rng);
    joint_file(&b, FK_ROWS / 2, &mut rng);
    let (ref_a, ref_b) = (dir.path().join("ref-a.csv"), dir.path().join("ref-b.csv"));
    run_ok(&fk_args(&a, &ref_a, robot));
    run_ok(&fk_args(&b, &ref_b, robot));
    let (ref_a, ref_b) = (std::fs::read(ref_a).unwrap(), std::fs::read(ref_b).unwrap());
    assert_ne!(ref_a, ref_b);
    let out = dir.path().join("out.csv");
    let mut winners = [0, 0];
    for _ in 0..5 {
        std::fs::write(&out, PREVIOUS).unwrap();
        let first = start(&fk_args(&a, &out, robot));
        let second = start(&fk_args(&b, &out, robot));
        for o in [finish(first), finish(second)] {
            assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        }
        let got = std::fs::read(&out).unwrap();
        assert!(
            got == ref_a || got == ref_b,
            "{} bytes: not one run's complete output",
            got.len()
        );
        winners[usize::from(got == ref_b)] += 1;
        // both finished: no temporary file is left
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 5);
    }
    eprintln!(
        "two fk runs at once: the last rename was a's {} times, b's {}",
        winners[0], winners[1]
    );
}

/// The outputs of `diagnose` checked after a kill.
struct DiagnoseOutputs {
    report: PathBuf,
    fitted: PathBuf,
    plots: PathBuf,
}

impl DiagnoseOutputs {
    fn args<'a>(&'a self, robot: &'a str, recording: &'a str) -> Vec<&'a str> {
        vec![
            "diagnose",
            "--robot",
            robot,
            "--recording",
            recording,
            "--report",
            arg(&self.report),
            "--out",
            arg(&self.fitted),
            "--plots",
            arg(&self.plots),
        ]
    }

    /// Each file (the report, the fitted robot, each plot) with its path.
    fn files(&self, plots: &[String]) -> Vec<PathBuf> {
        let mut all = vec![self.report.clone(), self.fitted.clone()];
        all.extend(plots.iter().map(|p| self.plots.join(p)));
        all
    }
}

#[test]
fn diagnose_killed_at_random_leaves_each_output_previous_or_complete() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = Rng(SEED ^ 3);
    let (robot, recording) = (
        shared().join("robots/nitinol2.toml"),
        shared().join("recordings/dev-clean.csv"),
    );
    let (robot, recording) = (arg(&robot), arg(&recording));
    let at = |name: &str| DiagnoseOutputs {
        report: dir.path().join(format!("{name}.json")),
        fitted: dir.path().join(format!("{name}.toml")),
        plots: dir.path().join(format!("{name}-plots")),
    };
    let reference = at("reference");
    let full = run_ok(&reference.args(robot, recording));
    let mut plots: Vec<String> = std::fs::read_dir(&reference.plots)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    plots.sort();
    assert!(plots.len() >= 2, "{plots:?}");
    let complete: Vec<Vec<u8>> = reference
        .files(&plots)
        .iter()
        .map(|p| std::fs::read(p).unwrap())
        .collect();

    let out = at("out");
    std::fs::create_dir(&out.plots).unwrap();
    let mut tally = Tally::default();
    let started = Instant::now();
    while tally.kills < MAX_KILLS && started.elapsed() < BUDGET {
        for f in out.files(&plots) {
            std::fs::write(f, PREVIOUS).unwrap();
        }
        let child = start(&out.args(robot, recording));
        std::thread::sleep(delay(&mut rng, full));
        tally.while_running += usize::from(kill(child));
        tally.kills += 1;
        for (f, complete) in out.files(&plots).iter().zip(&complete) {
            whole(f, PREVIOUS, complete, &mut tally);
        }
        assert_eq!(files_after_kill(&out.plots), plots);
    }
    tally.check("diagnose (outputs counted one by one)");
}

// ---- hw run --------------------------------------------------------------------------

/// `ctr-cli hw emulate --tubes 2 --time-scale 50` serving a pseudo-terminal; killed on
/// drop (it also exits when its standard input closes).
struct Emulator {
    child: Child,
    _stdin: ChildStdin,
    port: String,
}

impl Emulator {
    fn start() -> Emulator {
        let mut child = cli()
            .args(["hw", "emulate", "--tubes", "2", "--time-scale", "50"])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap();
        let stdin = child.stdin.take().unwrap();
        let mut port = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut port)
            .unwrap();
        let port = port.trim().to_owned();
        assert!(port.starts_with("/dev/"), "port {port:?}");
        Emulator {
            child,
            _stdin: stdin,
            port,
        }
    }

    /// `hw run` of `trajectory` into `recording`, labelled `label`, with `extra`.
    fn run(&self, trajectory: &Path, recording: &Path, label: &str, extra: &[&str]) -> Child {
        let rig = repo("tests/cli/hw/rig.toml");
        let mut args = vec![
            "hw",
            "run",
            "--port",
            &self.port,
            "--robot",
            arg(&rig),
            "--timeout-ms",
            "250",
            "--joints",
            arg(trajectory),
            "-o",
            arg(recording),
            "--run",
            label,
        ];
        args.extend_from_slice(extra);
        start(&args)
    }
}

impl Drop for Emulator {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A trajectory of [`HW_ROWS`] rows within the rig's limits; its joint rows.
fn trajectory(path: &Path) -> Vec<[f64; 4]> {
    let rows: Vec<[f64; 4]> = (0..HW_ROWS)
        .map(|i| {
            let i = i as f64;
            [
                20.0 + 0.5 * i,
                (i * 37.0) % 360.0 - 180.0,
                70.0 + 0.5 * i,
                (i * 53.0) % 360.0 - 180.0,
            ]
        })
        .collect();
    let mut text = String::from("s1_mm,theta1_deg,s2_mm,theta2_deg\n");
    for r in &rows {
        text += &format!("{},{},{},{}\n", r[0], r[1], r[2], r[3]);
    }
    std::fs::write(path, text).unwrap();
    rows
}

/// Checks a recording's text: the header, whole lines only, the run label on every
/// row and the commanded joints of the trajectory's first rows in order; the rows.
fn recording_rows(text: &str, label: &str, trajectory: &[[f64; 4]]) -> usize {
    assert!(
        text.is_empty() || text.ends_with('\n'),
        "a partial line: {text:?}"
    );
    let mut lines = text.lines();
    let header = ctr_formats::recording_header(2).join(",");
    match lines.next() {
        Some(h) => assert_eq!(h, header),
        None => return 0, // killed before the header was written
    }
    let mut rows = 0;
    for (line, goal) in lines.zip(trajectory) {
        let cells: Vec<&str> = line.split(',').collect();
        assert_eq!(cells.len(), 13, "{line}");
        assert_eq!(cells[1], label, "{line}");
        let commanded: Vec<f64> = cells[2..6].iter().map(|c| c.parse().unwrap()).collect();
        assert_eq!(commanded, goal, "{line}");
        rows += 1;
    }
    assert_eq!(
        rows,
        text.lines().count() - 1,
        "more rows than the trajectory"
    );
    rows
}

/// The journals (`NAME.XXXXXX.partial`) of `recording` and their complete rows.
fn journals(recording: &Path, label: &str, trajectory: &[[f64; 4]]) -> Vec<(PathBuf, usize)> {
    let name = recording.file_name().unwrap().to_str().unwrap();
    let prefix = format!("{name}.");
    let mut found = Vec::new();
    for e in std::fs::read_dir(recording.parent().unwrap()).unwrap() {
        let e = e.unwrap();
        let n = e.file_name().to_string_lossy().into_owned();
        if n.starts_with(&prefix) && n.ends_with(".partial") {
            let text = std::fs::read_to_string(e.path()).unwrap();
            // a row being written as we read: count whole lines only
            let whole = &text[..text.rfind('\n').map_or(0, |i| i + 1)];
            found.push((e.path(), recording_rows(whole, label, trajectory)));
        }
    }
    found
}

#[test]
fn hw_run_killed_at_random_keeps_every_row_it_wrote() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = Rng(SEED ^ 4);
    let path = dir.path().join("trajectory.csv");
    let goals = trajectory(&path);
    let recording = dir.path().join("rec.csv");
    let full = {
        let emulator = Emulator::start();
        let t = Instant::now();
        let o = finish(emulator.run(&path, &recording, "full", &[]));
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let text = std::fs::read_to_string(&recording).unwrap();
        assert_eq!(recording_rows(&text, "full", &goals), HW_ROWS);
        std::fs::remove_file(&recording).unwrap();
        t.elapsed()
    };

    let mut tally = Tally::default();
    let (mut rows_seen, mut rows_kept) = (0, 0);
    let started = Instant::now();
    while tally.kills < MAX_KILLS && started.elapsed() < BUDGET {
        // every other run replaces a previous recording
        let overwrite = tally.kills % 2 == 1;
        if overwrite {
            std::fs::write(&recording, PREVIOUS).unwrap();
        }
        let extra: &[&str] = if overwrite { &["--overwrite"] } else { &[] };
        // a fresh bus each time: a killed run may leave a packet half sent
        let emulator = Emulator::start();
        let child = emulator.run(&path, &recording, "k", extra);
        std::thread::sleep(delay(&mut rng, full));
        // the rows on the disk just before the kill
        let before: usize = journals(&recording, "k", &goals).iter().map(|j| j.1).sum();
        tally.while_running += usize::from(kill(child));
        tally.kills += 1;
        let after = journals(&recording, "k", &goals);
        assert!(after.len() <= 1, "{after:?}");
        let kept = after.first().map_or(0, |j| j.1);
        assert!(
            kept >= before,
            "{before} rows seen before the kill, {kept} after"
        );
        (rows_seen, rows_kept) = (rows_seen + before, rows_kept + kept);
        match std::fs::read(&recording) {
            Ok(text) if text == PREVIOUS => {
                assert!(overwrite);
                tally.previous += 1;
            }
            Ok(text) => {
                let text = String::from_utf8(text).unwrap();
                assert_eq!(recording_rows(&text, "k", &goals), HW_ROWS);
                assert!(after.is_empty(), "a finished run leaves no journal");
                tally.complete += 1;
                std::fs::remove_file(&recording).unwrap();
            }
            Err(e) => {
                assert!(!overwrite, "{e}");
                tally.previous += 1;
            }
        }
        for (journal, _) in after {
            std::fs::remove_file(journal).unwrap();
        }
        let _ = std::fs::remove_file(&recording);
        assert_eq!(files_after_kill(dir.path()), ["trajectory.csv"]);
    }
    eprintln!("hw run: rows in the journal just before the kills {rows_seen}, after {rows_kept}");
    tally.check("hw run");
    assert!(rows_seen > 0, "no kill came after a row was written");
}

#[test]
fn two_hw_runs_on_one_path_never_interleave() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("trajectory.csv");
    let goals = trajectory(&path);
    let recording = dir.path().join("rec.csv");
    let (one, two) = (Emulator::start(), Emulator::start());

    // without --overwrite: one recording; the other run keeps its rows in its journal
    let (a, b) = (
        one.run(&path, &recording, "a", &[]),
        two.run(&path, &recording, "b", &[]),
    );
    let outputs = [finish(a), finish(b)];
    let text = std::fs::read_to_string(&recording).unwrap();
    let winner = if text.contains(",a,") { "a" } else { "b" };
    assert_eq!(recording_rows(&text, winner, &goals), HW_ROWS);
    let loser = if winner == "a" { "b" } else { "a" };
    let lost = &outputs[usize::from(loser == "b")];
    assert_ne!(lost.status.code(), Some(0));
    let err = stderr(lost);
    assert!(err.contains("exists already"), "{err}");
    if err.contains("kept in") {
        // it ran to the end and found the other's recording: its journal is whole
        let kept = journals(&recording, loser, &goals);
        assert_eq!(kept.len(), 1, "{kept:?}");
        assert_eq!(kept[0].1, HW_ROWS);
        std::fs::remove_file(&kept[0].0).unwrap();
    }
    std::fs::remove_file(&recording).unwrap();

    // with --overwrite: both succeed, the last to end wins, whole
    let (a, b) = (
        one.run(&path, &recording, "a", &["--overwrite"]),
        two.run(&path, &recording, "b", &["--overwrite"]),
    );
    let outputs = [finish(a), finish(b)];
    for o in &outputs {
        assert_eq!(o.status.code(), Some(0), "{}", stderr(o));
    }
    let text = std::fs::read_to_string(&recording).unwrap();
    let winner = if text.contains(",a,") { "a" } else { "b" };
    assert_eq!(recording_rows(&text, winner, &goals), HW_ROWS);
    assert_eq!(files_after_kill(dir.path()), ["rec.csv", "trajectory.csv"]);
}
