"""The diagnosis's verdict through ctr_py, on the bundled example only (no shared data):
the example is explained; the same recording with a tracker that creeps in time is not,
and the report places the rest in time and fits a labelled empirical term for it."""

import csv

import pytest

import ctr_py
from conftest import REPO, without_comments

ROBOT = REPO / "data" / "robots" / "liu2023.toml"
EXAMPLE = REPO / "data" / "examples" / "liu2023-recording.csv"
# a tracker frame that creeps, mm/s per axis: about 2 mm over the recording
DRIFT_MM_S = (0.004, -0.003, 0.0)
# what crates/ctr-diagnosis/examples/example_recording.rs concealed in the example
LAG_S = 0.3
KINK_DEG = 2.2


@pytest.fixture(scope="module")
def robot():
    return ctr_py.Robot.from_toml(ROBOT)


@pytest.fixture(scope="module")
def drifted(tmp_path_factory):
    path = tmp_path_factory.mktemp("verdict") / "drifted.csv"
    with open(EXAMPLE, newline="") as f, open(path, "w", newline="") as out:
        rows = csv.DictReader(f)
        w = csv.DictWriter(out, fieldnames=rows.fieldnames)
        w.writeheader()
        for r in rows:
            t = float(r["t_s"])
            for axis, v in zip(("x_mm", "y_mm", "z_mm"), DRIFT_MM_S):
                r[axis] = repr(float(r[axis]) + v * t)
            w.writerow(r)
    return path


def test_the_example_is_explained(robot):
    report = ctr_py.diagnose(robot, ctr_py.read_recording(EXAMPLE, robot))
    assert report.explained is True
    assert report.empirical is None and "empirical" not in report.to_dict()
    assert report.summary().splitlines()[0].split(": ")[1:3] == ["explained", "yes"]


def test_a_drifting_tracker_is_not_explained_and_is_placed_in_time(robot, drifted):
    report = ctr_py.diagnose(robot, ctr_py.read_recording(drifted, robot))
    d = report.to_dict()
    assert report.explained is False and d["explained"] is False
    assert report.summary().splitlines()[0].split(": ")[1:3] == ["explained", "no"]
    # no effect of the vocabulary is established for the drift: whatever is established
    # is one of the example's own (latency, clearance); others may only be predictive
    established = {f["effect"] for f in report.findings if f["grade"] == "established"}
    assert established <= {"latency", "clearance"}
    assert all(f["grade"] == "predictive" for f in report.findings
               if f["effect"] not in {"latency", "clearance"})
    # the time is among the located patterns, and the rest is said to be outside
    assert any(s["feature"] == "time t_s" for s in report.located)
    assert "Outside the vocabulary" in report.unexplained
    emp = report.empirical
    assert emp is not None and emp == d["empirical"]
    # the learned discrepancy: better than the physics held out, with a band that holds
    # most held-out coordinates
    assert 0 < emp["terms"] and emp["heldout_rms_mm"] < report.final["heldout_rms_mm"]
    assert emp["inputs"] and 0.8 <= emp["band"]["heldout_coverage_95"] <= 1.0
    # outliers only where the tracker jumps: none here beyond 2 % of the rows
    assert len(d["outlier_lines"]) <= 0.02 * d["split"]["fit_rows"]



def _leaves(v, path=""):
    """Numbers of a JSON value with their key paths."""
    if isinstance(v, bool):
        return []
    if isinstance(v, (int, float)):
        return [(path, float(v))]
    if isinstance(v, list):
        return [x for i, e in enumerate(v) for x in _leaves(e, f"{path}[{i}]")]
    if isinstance(v, dict):
        return [x for k, e in v.items() for x in _leaves(e, f"{path}.{k}")]
    return []


def test_every_parameter_has_an_interval_that_holds_the_concealed_value(robot):
    report = ctr_py.diagnose(robot, ctr_py.read_recording(EXAMPLE, robot))
    assert report.uncertainty_method.startswith("95 % intervals")
    assert report.identifiability == [] and isinstance(report.correlated, list)
    found = {f["effect"]: f for f in report.findings}
    for f in found.values():
        values = _leaves(f["parameters"])
        ci = f["ci95"]
        for path, v in values:
            # the same keys and shapes: each number replaced by [lo, hi] around it
            node = ci
            for part in path.replace("[", ".[").split(".")[1:]:
                node = node[int(part[1:-1])] if part.startswith("[") else node[part]
            lo, hi = node
            assert lo <= v <= hi, (f["effect"], path, v, node)
    lo, hi = found["latency"]["ci95"]["tau_s"]
    assert lo <= LAG_S <= hi and hi - lo < 0.05
    lo, hi = found["clearance"]["ci95"]["max_deflection_deg"][0]
    assert lo <= KINK_DEG <= hi
    assert "95 % intervals: tau_s" in report.summary()


def test_the_fitted_robot_with_the_empirical_term_is_the_clis(cli, robot, drifted, tmp_path):
    """`Report.fitted_with_empirical` is the file `--with-empirical --out` writes, its fk
    applies the correction (closer to the drifted tips than the physics alone), and it
    pickles; on an explained recording it is `fitted`."""
    import pickle
    import subprocess

    import numpy as np

    rec = ctr_py.read_recording(drifted, robot)
    report = ctr_py.diagnose(robot, rec)
    hybrid = report.fitted_with_empirical
    assert hybrid != report.fitted and "[model.discrepancy]" in hybrid.to_toml()
    out = tmp_path / "fitted.toml"
    p = subprocess.run(
        [str(cli), "diagnose", "--robot", str(ROBOT), "--recording", str(drifted),
         "--with-empirical", "--out", str(out)],
        capture_output=True, text=True, stdin=subprocess.DEVNULL,
    )
    assert p.returncode == 0, p.stderr
    assert without_comments(out.read_text()) == hybrid.to_toml()

    def rms(model):
        err = [model.fk(rec.joints[r], t_s=rec.t_s[r])[0] - rec.tip[r] for _, r in rec.runs]
        return float(np.sqrt(np.mean(np.concatenate(err) ** 2)))

    assert rms(hybrid) < rms(report.fitted)
    # the band (last of fk's results): positive, one per row, and about 95 % of the
    # recorded coordinates inside it (fit and held-out rows together)
    inside, total = 0, 0
    for _, r in rec.runs:
        result = hybrid.fk(rec.joints[r], t_s=rec.t_s[r], band=True)
        tips, band = result[0], result[-1]
        assert band.shape == (len(tips),) and np.all(band > 0)
        inside += int(np.sum(np.abs(tips - rec.tip[r]) <= 1.96 * band[:, None]))
        total += tips.size
    assert 0.85 <= inside / total <= 1.0
    with pytest.raises(ctr_py.InputError):
        report.fitted.fk(rec.joints[rec.runs[0][1]], t_s=rec.t_s[rec.runs[0][1]], band=True)
    # the established physics alone: the file --established-only writes, no predictive
    # finding in it
    p = subprocess.run(
        [str(cli), "diagnose", "--robot", str(ROBOT), "--recording", str(drifted),
         "--established-only", "--out", str(out)],
        capture_output=True, text=True, stdin=subprocess.DEVNULL,
    )
    assert p.returncode == 0, p.stderr
    assert without_comments(out.read_text()) == report.fitted_established.to_toml()
    predictive = [f["effect"] for f in report.findings if f["grade"] == "predictive"]
    for effect in predictive:
        assert f"[model.effects.{effect}]" in report.fitted.to_toml()
        assert f"[model.effects.{effect}]" not in report.fitted_established.to_toml()
    back = pickle.loads(pickle.dumps(report))
    assert back.fitted_with_empirical == hybrid
    explained = ctr_py.diagnose(robot, ctr_py.read_recording(EXAMPLE, robot))
    assert explained.fitted_with_empirical == explained.fitted
