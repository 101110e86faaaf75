"""Fixtures of the ctr_py suite: the repository, the robots, and the `ctr-cli` binary
the wheel's results are compared with (built with cargo if needed)."""

import json
import os
import shutil
import subprocess
import threading
from pathlib import Path

import pytest
from hypothesis import settings

# The property tests (hypothesis) draw the same examples on every run, as the Rust ones
# do (a seed derived from each test; no example database carried between runs): two
# runs of one commit, CI's included, test the same inputs. HYPOTHESIS_PROFILE=explore
# draws fresh ones (scripts/explore_properties.sh; HYPOTHESIS_MAX_EXAMPLES for more);
# a failure prints the falsifying example to keep as an @example of its test.
settings.register_profile("ci", derandomize=True, database=None, print_blob=True)
settings.register_profile("explore", derandomize=False, database=None, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

REPO = Path(__file__).resolve().parents[2]
ROBOTS = sorted((REPO / "data" / "robots").glob("*.toml"))
# the project's copy of the shared reference data, as the Rust tests find it (CTR_SHARED_DATA
# overrides): the shared robots and the recordings with their truth files
SHARED = Path(os.environ.get("CTR_SHARED_DATA") or REPO / "tests" / "data" / "shared")


def spin_while(work):
    """Runs `work()` on another thread and counts the turns of a busy loop on this one
    until it returns: `(its result, the count)`. A call that holds the GIL throughout
    leaves the loop barely any turns."""
    done = threading.Event()
    result = {}

    def run():
        try:
            result["value"] = work()
        finally:
            done.set()

    counted = 0
    t = threading.Thread(target=run)
    t.start()
    while not done.is_set():
        counted += 1
    t.join()
    return result["value"], counted


@pytest.fixture(scope="session")
def cli() -> Path:
    """Path of `ctr-cli`: $CTR_CLI, or the workspace's release build (built now, a
    no-op when it is up to date)."""
    if os.environ.get("CTR_CLI"):
        return Path(os.environ["CTR_CLI"])
    cargo = shutil.which("cargo")
    if cargo is None:
        pytest.skip("cargo not found: set CTR_CLI to compare with ctr-cli")
    subprocess.run(
        [cargo, "build", "--release", "--locked", "-q", "-p", "ctr-cli"],
        cwd=REPO,
        check=True,
    )
    meta = subprocess.run(
        [cargo, "metadata", "--format-version", "1", "--no-deps", "--locked"],
        cwd=REPO,
        check=True,
        capture_output=True,
        text=True,
    )
    exe = Path(json.loads(meta.stdout)["target_directory"]) / "release" / "ctr-cli"
    assert exe.exists(), exe
    return exe


def without_comments(text):
    """A fitted robot file without its header comment lines (what fitted, and the
    findings by grade)."""
    lines = text.splitlines(keepends=True)
    while lines and lines[0].startswith("#"):
        lines.pop(0)
    return "".join(lines)
