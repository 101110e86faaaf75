#!/usr/bin/env python3
"""Runs every block of the README and the guide marked runnable, as a reader would type
it, on the bundled files: CI's proof that the documented commands work.

    python3 scripts/run_guide.py [--cli target/release/ctr-cli] [--python VENV/bin/python]
                                 [--list] [FILE.md ...]

A block is runnable when its fence's info string says so:

    ```sh runnable          a shell block, run by bash -e -o pipefail
    ```python runnable      a Python block, run by --python (the venv with ctr_py)
    ```rust doctest=PATH    a Rust block that must appear in PATH's `//!` crate doc,
                            whose doctests `cargo test --doc` runs (checked, not run)

Blocks of one page run in order in one scratch directory (a page's later blocks may read
what its earlier ones wrote), which holds a symbolic link to every top-level entry of the
repository: paths read as from the repository root (`data/robots/liu2023.toml`), files a
block writes stay in the scratch directory. `ctr-cli` on the PATH is the binary given by
`--cli` (default: the release build CI's test step made), and a block's
`cargo run --release -p ctr-cli --` runs that binary too (no second build). Each block
must exit 0 within its timeout; output is shown only for a block that fails.

Without FILE arguments: README.md and docs/*.md. Exits 1 when any block fails.
"""

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^```(\S*)(.*)$")
TIMEOUT_S = 120
CARGO_RUN_CLI = re.compile(r"cargo run --release -p ctr-cli --(?=\s)")


class Block:
    def __init__(self, path: Path, line: int, lang: str, info: str, text: str):
        self.path, self.line, self.lang, self.info, self.text = path, line, lang, info, text

    def where(self) -> str:
        return f"{self.path.relative_to(REPO)}:{self.line}"


def blocks(path: Path) -> list:
    """Every fenced block of `path` whose info string marks it runnable or a doctest."""
    found, lines = [], path.read_text(encoding="utf-8").splitlines()
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i].strip())
        if not m or not m.group(1) and not m.group(2):
            i += 1
            continue
        lang, info, start = m.group(1), m.group(2).split(), i + 1
        i += 1
        body = []
        while i < len(lines) and lines[i].strip() != "```":
            body.append(lines[i])
            i += 1
        i += 1
        if "runnable" in info or any(w.startswith("doctest=") for w in info):
            found.append(Block(path, start, lang, " ".join(info), "\n".join(body) + "\n"))
    return found


def doc_lines(rs: Path) -> list:
    """The crate doc of `rs` (its leading `//!` lines), as rustdoc's code sees it."""
    out = []
    for line in rs.read_text(encoding="utf-8").splitlines():
        if not line.startswith("//!"):
            break
        text = line[3:]
        out.append(text[1:] if text.startswith(" ") else text)
    return [l.rstrip() for l in out if not l.lstrip().startswith("# ") and l.strip() != "#"]


def check_doctest(block: Block) -> str:
    """Empty when the block's lines appear, in order and together, in the crate doc."""
    target = next(w.split("=", 1)[1] for w in block.info.split() if w.startswith("doctest="))
    rs = REPO / target
    if not rs.is_file():
        return f"{target} does not exist"
    want = [l.rstrip() for l in block.text.splitlines()]
    have = doc_lines(rs)
    for k in range(len(have) - len(want) + 1):
        if have[k:k + len(want)] == want:
            return ""
    return f"the block is not the doctest of {target}'s crate doc (copy it from there)"


def scratch_dir(root: Path) -> Path:
    """A fresh directory under `root` that reads as the repository root."""
    work = Path(tempfile.mkdtemp(prefix="page-", dir=root))
    for entry in REPO.iterdir():
        if entry.name not in (".git",):
            (work / entry.name).symlink_to(entry)
    return work


def run(block: Block, work: Path, env: dict, python: str) -> tuple:
    if block.lang in ("sh", "bash", "shell"):
        text = CARGO_RUN_CLI.sub("ctr-cli", block.text)
        cmd = ["bash", "-e", "-o", "pipefail", "-c", text]
    elif block.lang == "python":
        cmd = [python, "-c", block.text]
    else:
        return 1, f"runnable blocks are sh or python, not {block.lang!r}"
    try:
        p = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True,
                           timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return 1, f"did not finish within {TIMEOUT_S} s"
    return p.returncode, p.stdout + p.stderr


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cli", default=str(REPO / "target/release/ctr-cli"))
    ap.add_argument("--python", default=os.environ.get("PYTHON"),
                    help="the interpreter of the python blocks, with ctr_py (default: "
                         "$PYTHON, else this one; without either able to import ctr_py "
                         "the python blocks that use it are skipped, with a warning)")
    ap.add_argument("--list", action="store_true", help="list the blocks, run nothing")
    ap.add_argument("files", nargs="*", type=Path)
    args = ap.parse_args()
    files = [f.resolve() for f in args.files] or [REPO / "README.md",
                                                  *sorted((REPO / "docs").glob("*.md"))]
    pages = [(f, blocks(f)) for f in files]
    if args.list:
        for _, bs in pages:
            for b in bs:
                print(f"{b.where()}: {b.lang} {b.info}")
        return
    cli = Path(args.cli).resolve()
    if not cli.is_file():
        sys.exit(f"run_guide: no ctr-cli at {cli} (cargo build --release -p ctr-cli)")
    python, skip_python = args.python or sys.executable, False
    probe = subprocess.run([python, "-c", "import ctr_py"], capture_output=True)
    if probe.returncode != 0 and any(b.lang == "python" for _, bs in pages for b in bs):
        if args.python:
            sys.exit(f"run_guide: {python} cannot import ctr_py: give --python a venv's "
                     "python with `pip install ./crates/ctr-py`")
        skip_python = True
        print(f"run_guide: warning: {python} cannot import ctr_py, so the python blocks "
              "that use it are skipped (give --python a venv's python with ctr_py)",
              file=sys.stderr)
    failed, ran, skipped, started = [], 0, 0, time.monotonic()
    with tempfile.TemporaryDirectory(prefix="ctr-guide-") as tmp:
        root = Path(tmp)
        bin_dir = root / "bin"
        bin_dir.mkdir()
        (bin_dir / "ctr-cli").symlink_to(cli)
        env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}")
        env.pop("CTR_SHARED_DATA", None)
        for path, bs in pages:
            work = scratch_dir(root) if bs else None
            for b in bs:
                t0 = time.monotonic()
                if b.lang == "python" and skip_python and "ctr_py" in b.text:
                    skipped += 1
                    print(f"{b.where()}: python: skipped (no ctr_py)")
                    continue
                if b.lang == "rust":
                    why = check_doctest(b)
                    code, out = (0, "") if not why else (1, why)
                else:
                    code, out = run(b, work, env, python)
                ran += 1
                status = "ok" if code == 0 else f"FAILED (exit {code})"
                print(f"{b.where()}: {b.lang}: {status} ({time.monotonic() - t0:.1f} s)")
                if code != 0:
                    failed.append(b.where())
                    print("    " + "\n    ".join(out.rstrip().splitlines()[-20:]))
            if work:
                shutil.rmtree(work, ignore_errors=True)
    took = time.monotonic() - started
    if failed:
        print(f"run_guide: {len(failed)} of {ran} blocks failed ({took:.1f} s): "
              + ", ".join(failed), file=sys.stderr)
        sys.exit(1)
    note = f", {skipped} python blocks skipped" if skipped else ""
    print(f"run_guide: {ran} blocks passed{note} ({took:.1f} s)")


if __name__ == "__main__":
    main()
