//! End to end: files saved by a spreadsheet ("CSV UTF-8": a byte-order mark, CRLF line
//! ends) give `ctr-cli` the same outputs as the plain files (issue 17, part 4).

mod common;
use common::*;
use std::path::Path;

/// The UTF-8 encoding of U+FEFF.
const BOM: &[u8] = b"\xEF\xBB\xBF";

/// `text` as a spreadsheet saves it: a byte-order mark, then CRLF line ends.
fn spreadsheet(text: &[u8]) -> Vec<u8> {
    let mut out = BOM.to_vec();
    for &b in text {
        if b == b'\n' {
            out.push(b'\r');
        }
        out.push(b);
    }
    out
}

/// Copies the repository files `files` into `dir` under their own names, as they are
/// (`as_spreadsheet` false) or as a spreadsheet saves them.
fn copy_into(dir: &Path, files: &[&str], as_spreadsheet: bool) {
    for rel in files {
        let text = std::fs::read(repo(rel)).unwrap();
        let name = Path::new(rel).file_name().unwrap();
        let bytes = if as_spreadsheet {
            spreadsheet(&text)
        } else {
            text
        };
        std::fs::write(dir.join(name), bytes).unwrap();
    }
}

/// Runs `args` in `dir` and returns standard output and the files it wrote (`written`).
fn outputs(dir: &Path, args: &[&str], written: &[&str]) -> (Vec<u8>, Vec<Vec<u8>>) {
    let o = cli().current_dir(dir).args(args).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let files = written
        .iter()
        .map(|f| std::fs::read(dir.join(f)).unwrap())
        .collect();
    (o.stdout, files)
}

#[test]
fn fk_and_diagnose_give_the_same_outputs_for_spreadsheet_files() {
    // dev-clean is a recording of nitinol2
    let inputs = [
        "data/robots/liu2023.toml",
        "data/robots/nitinol2.toml",
        "data/examples/liu2023-joints.csv",
        "tests/data/shared/recordings/dev-clean.csv",
    ];
    let plain = tempfile::tempdir().unwrap();
    let saved = tempfile::tempdir().unwrap();
    copy_into(plain.path(), &inputs, false);
    copy_into(saved.path(), &inputs, true);
    assert!(std::fs::read(saved.path().join("dev-clean.csv"))
        .unwrap()
        .starts_with(BOM));

    let fk = [
        "fk",
        "--robot",
        "liu2023.toml",
        "--joints",
        "liu2023-joints.csv",
    ];
    let (fk_plain, _) = outputs(plain.path(), &fk, &[]);
    let (fk_saved, _) = outputs(saved.path(), &fk, &[]);
    assert!(!fk_plain.is_empty());
    assert_eq!(String::from_utf8(fk_saved), String::from_utf8(fk_plain));

    let diagnose = [
        "diagnose",
        "--robot",
        "nitinol2.toml",
        "--recording",
        "dev-clean.csv",
        "--report",
        "report.json",
        "--out",
        "fitted.toml",
    ];
    let written = ["report.json", "fitted.toml"];
    let (summary_plain, files_plain) = outputs(plain.path(), &diagnose, &written);
    let (summary_saved, files_saved) = outputs(saved.path(), &diagnose, &written);
    assert_eq!(
        String::from_utf8(summary_saved),
        String::from_utf8(summary_plain)
    );
    for (name, (a, b)) in written.iter().zip(files_saved.iter().zip(&files_plain)) {
        assert!(a == b, "{name} differs");
    }
}
