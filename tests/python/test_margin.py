"""The stability margin from Python: `robot.fk(q, margin=True)` equals `ctr-cli fk
--margin` bit for bit, and along a turn of the seed's robot with long transmissions it
falls towards zero before the tip snaps; `robot.ik(..., min_margin=)` never returns
joints below the floor and equals `ctr-cli ik --min-margin` bit for bit; `diagnose` and
`evaluate` mark the rows of a recording where it does (`Report.stability`, as
`ctr-cli diagnose` and `evaluate`)."""

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


def pinned(tmp_path, feeds=(55.0, 95.0)):
    """The long-transmission robot with both feeds pinned: a target fixes the relative
    angle of the tubes, so its margin."""
    path = long_transmissions(tmp_path)
    text = path.read_text()
    for s in feeds:
        text += f"\n[[limits.tube]]\ns_mm = [{s}, {s}]\n"
    path.write_text(text)
    return path


def test_ik_min_margin_keeps_the_margin_and_equals_the_cli(cli, tmp_path):
    path = pinned(tmp_path)
    robot = ctr_py.Robot.from_toml(str(path))
    rng = np.random.default_rng(19)
    rows = 60
    # half the relative angles 13-20 deg from the opposed curvatures, where the margin
    # falls before the pair snaps (below 0.4 from about 16 deg solved cold)
    near = rng.choice([-1.0, 1.0], rows) * rng.uniform(13, 20, rows)
    rel = np.where(np.arange(rows) % 2 == 0, near, rng.uniform(-180, 180, rows))
    theta1 = rng.uniform(-90, 90, rows)
    theta2 = (theta1 + rel + 180.0) % 360.0 - 180.0
    q = np.column_stack([np.full(rows, 55.0), theta1, np.full(rows, 95.0), theta2])
    # one row a call: each solved cold
    made = [robot.fk(row, margin=True) for row in q]
    tips = np.array([t for t, _, _ in made])
    margin = np.array([m for _, _, m in made])

    floor = 0.4
    joints, residual, status = robot.ik(tips, cold=True, min_margin=floor)
    for k, row in enumerate(joints):
        _, _, m = robot.fk(row, margin=True)
        assert m >= floor, (k, row, m)
    below = margin < floor
    comfortable = margin >= floor + 0.1
    assert below.sum() >= 5 and comfortable.sum() >= rows // 3
    assert set(status[below]) == {"unreachable_with_margin"}
    assert np.all(residual[below] > 1e-4)
    assert set(status[comfortable]) == {"reached"}
    # without the floor those targets are reached, below it
    free_q, _, free_status = robot.ik(tips, cold=True)
    assert set(free_status) == {"reached"}
    assert min(robot.fk(free_q[k], margin=True)[2] for k in np.flatnonzero(below)) < floor

    # the CLI's --min-margin, to the last bit
    targets = tmp_path / "targets.csv"
    with targets.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["x_mm", "y_mm", "z_mm"])
        w.writerows([[repr(float(v)) for v in t] for t in tips])
    out = tmp_path / "joints.csv"
    p = subprocess.run(
        [str(cli), "ik", "--robot", str(path), "--targets", str(targets), "-o", str(out),
         "--cold", "--min-margin", str(floor)],
        capture_output=True, text=True, stdin=subprocess.DEVNULL,
    )
    assert p.returncode == 0, p.stderr
    with out.open(newline="") as f:
        written = list(csv.DictReader(f))
    want = np.array([[float(r[c]) for c in robot.joint_columns] for r in written])
    assert want.tobytes() == joints.tobytes()
    assert [r["status"] for r in written] == list(status)


def test_ik_min_margin_is_checked(tmp_path):
    robot = ctr_py.Robot.from_toml(str(pinned(tmp_path)))
    with pytest.raises(ctr_py.InputError, match=r"min_margin = NaN must be a finite number"):
        robot.ik([0.0, 0.0, 100.0], min_margin=float("nan"))
    with pytest.raises(ctr_py.InputError, match=r"min_margin = 100: none of the 256 joint vectors"):
        robot.ik([0.0, 0.0, 100.0], min_margin=100.0)
    with pytest.raises(TypeError):
        robot.ik([0.0, 0.0, 100.0], min_margin="high")


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
    # the default warning margin (fk's, 0.05: about a degree) marks only the last rows
    # before each jump of a 1 deg path, inside the ranges 0.3 marks
    default = ctr_py.diagnose(robot, str(rec))
    assert default.stability["warn_margin"] == 0.05
    near = default.stability["fitted"]["near_snap"]
    assert [r["lines"][1] for r in near] == before, near
    wide = s["fitted"]["near_snap"]
    assert all(r["rows"] <= 2 and r["rows"] < w["rows"] for r, w in zip(near, wide))

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
