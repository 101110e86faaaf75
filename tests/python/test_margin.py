"""The stability margin from Python: `robot.fk(q, margin=True)` equals `ctr-cli fk
--margin` bit for bit, and along a turn of the seed's robot with long transmissions it
falls towards zero before the tip snaps."""

import csv
import re
import subprocess

import numpy as np

import ctr_py
from conftest import REPO


def long_transmissions(tmp_path, extra_mm=100.0):
    text = (REPO / "data" / "robots" / "liu2023.toml").read_text()
    text = re.sub(
        r"length_mm = ([0-9.]+)",
        lambda m: f"length_mm = {float(m.group(1)) + extra_mm}",
        text,
    )
    path = tmp_path / "long.toml"
    path.write_text(text)
    return path


def turn(s1, ahead=40.0, start=180.0, step=2.0):
    """A full turn of tube 2 against tube 1 and back, `step` degrees a row."""
    n = round(360 / step)
    along = list(range(n + 1)) + list(range(n - 1, -1, -1))
    return np.array([[s1, 0.0, s1 + ahead, start + k * step] for k in along])


def test_margin_matches_the_cli_and_falls_before_a_snap(cli, tmp_path):
    path = long_transmissions(tmp_path)
    robot = ctr_py.Robot.from_toml(str(path))
    q = turn(55.0)
    tips, _, margin = robot.fk(q, margin=True)
    assert margin.shape == (len(q),)

    joints = tmp_path / "joints.csv"
    with joints.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["s1_mm", "theta1_deg", "s2_mm", "theta2_deg"])
        w.writerows(q.tolist())
    out = subprocess.run(
        [str(cli), "fk", "--robot", str(path), "--joints", str(joints), "--margin",
         "--threads", "1", "--warn-margin", "0.3"],
        capture_output=True, text=True, stdin=subprocess.DEVNULL, check=True,
    )
    rows = list(csv.DictReader(out.stdout.splitlines()))
    assert [float(r["stability_margin"]) for r in rows] == margin.tolist()
    assert [float(r["x_mm"]) for r in rows] == tips[:, 0].tolist()

    # the tip snaps (a jump of tens of mm in one 2 deg step) once each way, and the
    # margin falls over the three rows before each jump
    steps = np.linalg.norm(np.diff(tips, axis=0), axis=1)
    jumps = np.flatnonzero(steps > 10.0) + 1
    assert len(jumps) == 2, steps.max()
    for j in jumps:
        before = margin[j - 3 : j]
        assert before[0] > before[1] > before[2] > 0.0
        assert before[2] < 0.3
    # one warning per run of rows below 0.3 (the two approaches to a snap), with lines
    warnings = [l for l in out.stderr.splitlines() if "stability margin below 0.3" in l]
    assert len(warnings) == 2, out.stderr
    assert all(re.search(r"joints\.csv:\d+(-\d+)?: ", l) for l in warnings)

    # one row: a float
    _, _, m1 = robot.fk(q[0], margin=True)
    assert isinstance(m1, float) and m1 == margin[0]
