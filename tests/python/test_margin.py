"""The stability margin from Python: `robot.fk(q, margin=True)` equals `ctr-cli fk
--margin` bit for bit, and along a turn of the seed's robot with long transmissions it
falls towards zero before the tip snaps; `diagnose` and `evaluate` mark the rows of a
recording where it does (`Report.stability`, as `ctr-cli diagnose` and `evaluate`)."""

import csv
import json
import re
import subprocess

import numpy as np
import pytest

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


def recording_of(path, robot, q, seed=1, sigma_mm=0.2):
    """A recording of `robot` moved through the rows `q` (one run, 0.5 s apart): the tips
    as `fk` solves them row after row (so they jump where the robot snaps) plus tracker
    noise."""
    tips, _ = robot.fk(q)
    tips = tips + np.random.default_rng(seed).normal(0.0, sigma_mm, tips.shape)
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t_s", "run", "s1_mm", "theta1_deg", "s2_mm", "theta2_deg",
                    "x_mm", "y_mm", "z_mm"])
        for k, (qk, p) in enumerate(zip(q.tolist(), tips.tolist())):
            w.writerow([0.5 * k, "turn", *qk, *p])
    jumps = np.flatnonzero(np.linalg.norm(np.diff(tips, axis=0), axis=1) > 10.0) + 1
    return path, jumps


def test_diagnose_and_evaluate_mark_the_rows_before_a_snap(cli, tmp_path):
    robot_path = long_transmissions(tmp_path)
    robot = ctr_py.Robot.from_toml(str(robot_path))
    rec, jumps = recording_of(tmp_path / "snapping.csv", robot, turn(55.0, step=1.0))
    assert len(jumps) == 2
    # CSV lines: the header is line 1, row k is line k + 2
    before = [int(j) - 1 + 2 for j in jumps]

    report = ctr_py.diagnose(robot, str(rec), warn_margin=0.3)
    s = report.stability
    assert s == report.to_dict()["stability"]
    assert s["warn_margin"] == 0.3
    for model in ("nominal", "fitted"):
        near = s[model]["near_snap"]
        assert [r["lines"][1] for r in near] == before, near
        assert all(0.0 < r["lowest_margin"] < 0.3 and r["run"] == "turn" for r in near)
        assert s[model]["unstable"] == []
    assert "Near a snap: the user's and the fitted model are within 0.3 of a snap" in (
        report.summary()
    )
    # the CLI says the same
    out = tmp_path / "report.json"
    p = subprocess.run(
        [str(cli), "diagnose", "--robot", str(robot_path), "--recording", str(rec),
         "--warn-margin", "0.3", "--report", str(out)],
        capture_output=True, text=True, stdin=subprocess.DEVNULL,
    )
    assert p.returncode == 0, p.stderr
    assert json.loads(out.read_text())["stability"] == s
    assert p.stdout == report.summary()
    # the default warning margin (fk's, 0.05) does not reach the rows of a 1 deg path
    default = ctr_py.diagnose(robot, str(rec))
    assert default.stability["warn_margin"] == 0.05
    assert default.stability["fitted"]["near_snap"] == []

    # evaluate: per run and per model, and the CLI's line after its table
    table = ctr_py.evaluate([robot], str(rec), warn_margin=0.3)
    assert table[0]["near_snap"] == [s["nominal"]["near_snap"]]
    assert table[0]["lowest_margin"][0] == min(r["lowest_margin"] for r in s["nominal"]["near_snap"])
    p = subprocess.run(
        [str(cli), "evaluate", "--robot", str(robot_path), "--recording", str(rec),
         "--warn-margin", "0.3"],
        capture_output=True, text=True, stdin=subprocess.DEVNULL,
    )
    assert p.returncode == 0, p.stderr
    last = p.stdout.strip().splitlines()[-1]
    first = s["nominal"]["near_snap"][0]
    assert last.startswith(
        f"Near a snap: long.toml is within 0.3 of a snap at lines {first['lines'][0]}-"
        f"{first['lines'][1]} of run 'turn'"
    ), last

    # a calm turn marks nothing, and bad margins are refused
    calm, calm_jumps = recording_of(tmp_path / "calm.csv", robot, turn(15.0, step=1.0))
    assert len(calm_jumps) == 0
    assert ctr_py.evaluate(robot, str(calm), warn_margin=0.3)[-1]["near_snap"] == [[]]
    for bad in (-1.0, float("nan")):
        with pytest.raises(ctr_py.InputError, match="is not a warning margin"):
            ctr_py.evaluate(robot, str(calm), warn_margin=bad)
    with pytest.raises(ctr_py.InputTypeError):
        ctr_py.diagnose(robot, str(calm), warn_margin="0.3")
