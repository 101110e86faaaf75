//! Helpers shared by the end-to-end tests of `ctr-cli`, and ctr-analysis's test set-up
//! (the shared data, the stable ranges, random numbers, the core row by row).
#![allow(dead_code)]

#[path = "../../../ctr-analysis/tests/common/mod.rs"]
pub mod analysis;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

/// A path relative to the repository root.
pub fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

/// `path` as a command line argument.
pub fn arg(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// `-`, standard input in place of an input file.
pub fn stdin_path() -> &'static Path {
    Path::new("-")
}

/// The arguments `fk --robot ROBOT --joints JOINTS EXTRA...`.
pub fn fk_args<'a>(robot: &'a Path, joints: &'a Path, extra: &[&'a str]) -> Vec<&'a str> {
    [
        &["fk", "--robot", arg(robot), "--joints", arg(joints)][..],
        extra,
    ]
    .concat()
}

/// The arguments `ik --robot ROBOT --targets TARGETS EXTRA...`.
pub fn ik_args<'a>(robot: &'a Path, targets: &'a Path, extra: &[&'a str]) -> Vec<&'a str> {
    [
        &["ik", "--robot", arg(robot), "--targets", arg(targets)][..],
        extra,
    ]
    .concat()
}

/// The binary under test.
pub fn cli() -> Command {
    Command::new(env!("CARGO_BIN_EXE_ctr-cli"))
}

/// Starts it with `args`, standard input from `stdin`, standard output and error piped.
pub fn spawn(args: &[&str], stdin: Stdio) -> Child {
    cli()
        .args(args)
        .stdin(stdin)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// Runs it to completion.
pub fn run(args: &[&str]) -> Output {
    cli().args(args).output().unwrap()
}

/// Runs it with `input` on standard input.
pub fn run_stdin(args: &[&str], input: &[u8]) -> Output {
    let mut child = spawn(args, Stdio::piped());
    child.stdin.take().unwrap().write_all(input).unwrap();
    child.wait_with_output().unwrap()
}

/// Its standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Waits for `child` (`what` it runs, for the message), killing it and failing the
/// test if it outlives `deadline`.
pub fn wait_within(child: Child, deadline: std::time::Duration, what: &str) -> Output {
    let pid = child.id();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(child.wait_with_output());
    });
    match rx.recv_timeout(deadline) {
        Ok(output) => output.unwrap(),
        Err(_) => {
            let _ = Command::new("kill").args(["-9", &pid.to_string()]).status();
            panic!("{what} (pid {pid}) did not finish within {deadline:?}");
        }
    }
}

/// A CSV text as header and rows of strings.
pub fn table(text: &str) -> (Vec<String>, Vec<Vec<String>>) {
    let mut rdr = csv::Reader::from_reader(text.as_bytes());
    let header = rdr.headers().unwrap().iter().map(str::to_owned).collect();
    let rows = rdr
        .records()
        .map(|r| r.unwrap().iter().map(str::to_owned).collect())
        .collect();
    (header, rows)
}
