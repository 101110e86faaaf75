"""ctr_py's recordings, diagnosis, calibration and evaluation: the same report, fitted
robot file, summary and messages as `ctr-cli diagnose`, `calibrate` and `evaluate` on
a shared recording; recordings and reports pickle; bad input raises CtrError
subclasses with the CLI's messages."""

import csv
import json
import pickle
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

import ctr_py
from conftest import REPO, SHARED, spin_while, without_comments

LIU = SHARED / "robots" / "liu2023.toml"
CLEARANCE = SHARED / "recordings" / "dev-clearance.csv"
NITINOL3 = REPO / "data" / "robots" / "nitinol3.toml"

pytestmark = pytest.mark.skipif(
    not CLEARANCE.exists(), reason=f"shared data not found at {SHARED} (set CTR_SHARED_DATA)"
)



def run_cli(cli: Path, *args) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(cli), *map(str, args)], capture_output=True, text=True, stdin=subprocess.DEVNULL
    )


def cli_error(cli: Path, *args) -> str:
    """The CLI's one-line message, without `error: ` (and clap's help hint)."""
    p = run_cli(cli, *args)
    assert p.returncode == 2, p.stdout + p.stderr
    line = p.stderr.strip()
    assert line.startswith("error: ") and "\n" not in line, line
    return line[len("error: ") :].removesuffix(" (see ctr-cli --help)")


def read_csv(path: Path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def fitted_tips(robot: ctr_py.Robot, rec: ctr_py.Recording) -> np.ndarray:
    """The robot's tips along the recording: one fk call per run, with its times."""
    tips = np.empty((len(rec), 3))
    t_s, q = rec.t_s, rec.joints
    for _, rows in rec.runs:
        tips[rows] = robot.fk(q[rows], t_s=t_s[rows], on_error="mark")[0]
    return tips


# ---------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def liu():
    return ctr_py.Robot.from_toml(LIU)


@pytest.fixture(scope="module")
def rec(liu):
    return ctr_py.read_recording(CLEARANCE, liu)


@pytest.fixture(scope="module")
def report(liu, rec):
    return ctr_py.diagnose(liu, rec)


@pytest.fixture(scope="module")
def cli_diagnosis(cli, tmp_path_factory):
    """`ctr-cli diagnose` on the same robot and recording: report, fitted file, stdout,
    HTML page."""
    d = tmp_path_factory.mktemp("cli-diagnose")
    p = run_cli(
        cli, "diagnose", "--robot", LIU, "--recording", CLEARANCE,
        "--report", d / "report.json", "--out", d / "fitted.toml", "--html", d / "report.html",
    )
    assert p.returncode == 0, p.stderr
    return (
        (d / "report.json").read_text(),
        (d / "fitted.toml").read_text(),
        p.stdout,
        (d / "report.html").read_text(encoding="utf-8"),
    )


# ---------------------------------------------------------------- recordings


def test_recording_columns_are_the_files(rec):
    rows = read_csv(CLEARANCE)
    assert len(rec) == len(rows) == 984
    assert rec.n_tubes == 2 and rec.has_time and rec.file == str(CLEARANCE)
    assert rec.joint_columns == ["s1_mm", "theta1_deg", "s2_mm", "theta2_deg"]
    want = lambda cols: np.array([[float(r[c]) for c in cols] for r in rows])
    assert np.array_equal(rec.joints, want(rec.joint_columns))
    assert np.array_equal(rec.tip, want(["x_mm", "y_mm", "z_mm"]))
    assert np.array_equal(rec.t_s, want(["t_s"])[:, 0])
    assert rec.joints.dtype == rec.tip.dtype == rec.t_s.dtype == np.float64
    assert rec.joints.shape == (984, 4) and rec.tip.shape == (984, 3) and rec.t_s.shape == (984,)
    assert list(rec.run) == [r["run"] for r in rows]
    assert [label for label, _ in rec.runs] == ["feed", "feed-b", "rot-inner", "rot-outer", "scatter"]
    assert all((rec.run[rows] == label).all() for label, rows in rec.runs)
    assert sum(s.stop - s.start for _, s in rec.runs) == len(rec)
    assert list(rec.lines[:3]) == [2, 3, 4]
    assert rec.force_n is None and rec.quaternion is None and rec.tangent is None


def test_recording_optional_columns_and_n_tubes(tmp_path):
    path = tmp_path / "weights.csv"
    path.write_text(
        "s1_mm,theta1_deg,x_mm,y_mm,z_mm,qw,qx,qy,qz,tx,ty,tz,fx_n,fy_n,fz_n,note\n"
        "10,0,0,0,10,1,0,0,0,0,0,1,0,0,-0.1,a\n"
        "11,5,0.5,0,11,1,0,0,0,0.6,0,0.8,0,0,-0.2,b\n"
    )
    rec = ctr_py.read_recording(path, n_tubes=1)
    assert len(rec) == 2 and not rec.has_time
    assert list(rec.t_s) == [0.0, 1.0]  # the row index stands for time
    assert [(label, s.start, s.stop) for label, s in rec.runs] == [("all", 0, 2)]
    assert np.array_equal(rec.force_n, [[0, 0, -0.1], [0, 0, -0.2]])
    assert np.array_equal(rec.quaternion, [[1, 0, 0, 0], [1, 0, 0, 0]])
    again = pickle.loads(pickle.dumps(rec))
    assert again == rec and np.array_equal(again.force_n, rec.force_n)
    assert np.array_equal(again.quaternion, rec.quaternion)
    assert np.array_equal(rec.tangent, [[0, 0, 1], [0.6, 0, 0.8]])
    assert np.array_equal(again.tangent, rec.tangent)


def test_recording_refuses_a_tangent_that_is_not_unit(tmp_path):
    path = tmp_path / "tangent.csv"
    path.write_text("s1_mm,theta1_deg,x_mm,y_mm,z_mm,tx,ty,tz\n10,0,0,0,10,0,0,1\n11,0,0,0,11,0,0.5,1\n")
    with pytest.raises(ctr_py.InputError) as e:
        ctr_py.read_recording(path, n_tubes=1)
    assert str(e.value).startswith(f"{path}:3: tx,ty,tz = 0, 0.5, 1 has norm 1.118")


def test_recording_pickles_exactly(rec):
    for protocol in range(2, pickle.HIGHEST_PROTOCOL + 1):
        again = pickle.loads(pickle.dumps(rec, protocol=protocol))
        assert again == rec and again is not rec
        for name in ("t_s", "joints", "tip", "run", "lines"):
            a, b = getattr(again, name), getattr(rec, name)
            assert a.shape == b.shape and (a == b).all()
        assert again.runs == rec.runs and again.file == rec.file


def test_a_static_set_pickles_and_its_noise_comes_from_its_frames(liu):
    # the bundled static set: 60 poses of 20 frames averaged (n_frames, spread_mm)
    path = REPO / "data" / "examples" / "liu2023-static.csv"
    robot = ctr_py.Robot.from_toml(REPO / "data" / "robots" / "liu2023.toml")
    static = ctr_py.read_recording(path, robot)
    for protocol in range(2, pickle.HIGHEST_PROTOCOL + 1):
        again = pickle.loads(pickle.dumps(static, protocol=protocol))
        assert again == static
    report = ctr_py.diagnose(robot, static)
    assert report.noise["method"].startswith("from the averaged frames"), report.noise
    assert "static configuration set" in report.to_dict()["split"]["method"]
    _, (state,) = static.__reduce__()
    bad = list(state)
    tangents, poses, frames = bad[11]
    bad[11] = (tangents, poses[:-1], frames)  # poses that do not cover the rows
    with pytest.raises(ctr_py.InputError, match="the poses do not cover"):
        ctr_py.Recording._from_state(tuple(bad))


def test_recording_state_is_checked(rec):
    _, (state,) = rec.__reduce__()
    bad = list(state)
    bad[10] = [("all", 0, 5)]  # runs that do not cover the rows
    with pytest.raises(ctr_py.InputError, match="Recording state"):
        ctr_py.Recording._from_state(tuple(bad))
    bad = list(state)
    bad[6] = bad[6][:-1]
    with pytest.raises(ctr_py.InputError, match="Recording state"):
        ctr_py.Recording._from_state(tuple(bad))


def test_read_recording_needs_the_tube_count(liu):
    with pytest.raises(ctr_py.InputError, match="give the robot"):
        ctr_py.read_recording(CLEARANCE)
    for n in (0, 5, -1):
        with pytest.raises(ctr_py.InputError, match=rf"n_tubes: {n} is not in 1..=4"):
            ctr_py.read_recording(CLEARANCE, n_tubes=n)
    with pytest.raises(ctr_py.InputError, match="but the robot has 2 tubes"):
        ctr_py.read_recording(CLEARANCE, liu, n_tubes=3)
    assert ctr_py.read_recording(CLEARANCE, liu, n_tubes=2) == ctr_py.read_recording(
        CLEARANCE, n_tubes=2
    )
    with pytest.raises(ctr_py.InputTypeError):
        ctr_py.read_recording(CLEARANCE, "liu2023.toml")


BAD_RECORDINGS = {
    "not_a_number": lambda t: t.replace("-6.434702431", "abc", 1),
    "not_finite": lambda t: t.replace("0,feed,45,0,75", "0,feed,NaN,0,75", 1),
    "ragged": lambda t: t.replace(",74.6812287\n", "\n", 1),
    "backwards": lambda t: t.replace("0.5,feed,45", "-0.5,feed,45", 1),
    "missing_column": lambda t: t.replace(",z_mm", ",zz_mm", 1),
    "duplicate_column": lambda t: t.replace("x_mm,", "y_mm,", 1),
    "empty": lambda t: "",
    "header_only": lambda t: t.splitlines()[0] + "\n",
    "not_utf8": lambda t: t.replace("feed-b", "feed-\udcff", 1),
}


@pytest.mark.parametrize("case", sorted(BAD_RECORDINGS))
def test_bad_recordings_raise_the_cli_message(cli, tmp_path, liu, case):
    path = tmp_path / f"{case}.csv"
    path.write_bytes(
        BAD_RECORDINGS[case](CLEARANCE.read_text()).encode("utf-8", "surrogateescape")
    )
    message = cli_error(cli, "evaluate", "--robot", LIU, "--recording", path)
    with pytest.raises(ctr_py.CtrError) as e:
        ctr_py.read_recording(path, liu)
    assert str(e.value) == message
    assert type(e.value) is ctr_py.InputError and isinstance(e.value, ValueError)
    # the same through diagnose (a path is read with the robot's columns)
    with pytest.raises(ctr_py.InputError) as e:
        ctr_py.diagnose(liu, path)
    assert str(e.value) == message


def test_unreadable_recordings_raise_file_errors(cli, tmp_path, liu):
    for path in (tmp_path / "missing.csv", tmp_path):
        message = cli_error(cli, "evaluate", "--robot", LIU, "--recording", path)
        with pytest.raises(ctr_py.FileError) as e:
            ctr_py.read_recording(path, liu)
        assert str(e.value) == message and isinstance(e.value, OSError)


def test_recording_of_another_robot(cli, liu):
    # a 3-tube robot wants columns the 2-tube recording lacks: the CLI's message
    message = cli_error(cli, "diagnose", "--robot", NITINOL3, "--recording", CLEARANCE)
    nitinol3 = ctr_py.Robot.from_toml(NITINOL3)
    with pytest.raises(ctr_py.InputError) as e:
        ctr_py.read_recording(CLEARANCE, nitinol3)
    assert str(e.value) == message
    with pytest.raises(ctr_py.InputError) as e:
        ctr_py.diagnose(nitinol3, str(CLEARANCE))
    assert str(e.value) == message
    # read for one tube, diagnosed with two
    one = ctr_py.read_recording(CLEARANCE, n_tubes=1)
    for call in (
        lambda: ctr_py.diagnose(liu, one),
        lambda: ctr_py.calibrate(liu, one, ["clearance"]),
        lambda: ctr_py.evaluate([liu], one),
    ):
        with pytest.raises(ctr_py.InputError, match="2 tubes, but the recording .* was read for 1"):
            call()


# ---------------------------------------------------------------- diagnose


def test_diagnosis_finds_clearance_at_the_noise_floor(report):
    truth = json.loads(CLEARANCE.with_suffix(".truth.json").read_text())
    assert report.effects == truth["expected_findings"] == ["clearance"]
    assert [f["effect"] for f in report.findings] == ["clearance"]
    assert report.final["heldout_rms_mm"] <= 1.25 * truth["noise_floor_rms_mm"]
    assert report.final["heldout_rms_mm"] < 0.25 * report.baseline["heldout_rms_mm"]
    p = report.findings[0]["parameters"]
    assert abs(p["peak_deg"][0] - 205.0) < 5.0 and abs(p["max_deflection_deg"][0] - 2.5) < 0.2
    assert "consistent with measurement noise" in report.unexplained


def test_report_equals_the_cli_report(report, cli_diagnosis):
    text, fitted, stdout, _ = cli_diagnosis
    assert report.to_dict() == json.loads(text)
    assert report.to_json() == text
    assert json.loads(report.to_json(indent=False)) == json.loads(text)
    # the fitted robot file, without the CLI's comment lines (what fitted it, and the
    # findings by grade)
    header, rest = fitted.split("\n", 1)
    assert header.startswith("# Fitted by ctr-cli")
    assert "# established (physics the data show): clearance\n" in fitted
    rest = without_comments(fitted)
    assert report.fitted.to_toml() == rest
    assert report.fitted == ctr_py.Robot.from_toml_str(rest)
    assert report.summary() == stdout


def test_report_attributes_are_the_contract_fields(report):
    d = report.to_dict()
    assert {"baseline", "findings", "final", "unexplained"} <= set(d)
    for key in ("baseline", "findings", "final", "unexplained", "noise", "split",
                "located", "tried", "failed_rows", "explained", "uncertainty_method",
                "identifiability", "correlated", "suggested_run", "stability"):
        assert getattr(report, key) == d[key], key
    # the seed's robot stays far from a snap on this recording: no row marked
    assert report.stability == {
        "warn_margin": 0.05,
        "nominal": {"near_snap": [], "unstable": []},
        "fitted": {"near_snap": [], "unstable": []},
        "outlier_lines_near_snap": [],
    }
    # the recording is explained: no empirical term, in the JSON or here
    assert report.explained is True and "empirical" not in d and report.empirical is None
    f = report.findings[0]
    assert f["grade"] == "established" and "passes every check" in f["grade_reason"]
    assert set(f) == {"effect", "grade", "grade_reason", "explanation", "where",
                      "parameters", "rms_mm_before",
                      "rms_mm_after", "heldout_rms_mm_before", "heldout_rms_mm_after",
                      "empirical_heldout_rms_mm", "ci95", "equally_explained_by"}
    assert f["equally_explained_by"] == []
    # plain Python values, fresh on every access
    assert type(report.final["rms_mm"]) is float and type(report.failed_rows) is int
    report.findings.clear()
    assert report.effects == ["clearance"] and report.recording == str(CLEARANCE)
    assert "clearance" in repr(report)
    # a candidate never fitted has null figures, as in the JSON
    assert all(t["rms_mm"] is None or isinstance(t["rms_mm"], float) for t in report.tried)


def test_fitted_robot_reproduces_the_report(report, rec, liu):
    fitted = report.fitted
    assert fitted.n_tubes == liu.n_tubes and fitted.source.endswith("(fitted)")
    m = len(rec)
    split = report.split
    assert split["fit_rows"] + split["heldout_rows"] == m
    for robot, figures in ((liu, report.baseline), (fitted, report.final)):
        e2 = ((fitted_tips(robot, rec) - rec.tip) ** 2).sum(axis=1)
        want = (figures["rms_mm"] ** 2 * split["fit_rows"]
                + figures["heldout_rms_mm"] ** 2 * split["heldout_rows"]) / m
        assert abs(e2.mean() / want - 1.0) < 1e-9
        assert np.sqrt(e2.max()) >= figures["max_mm"] - 1e-9


def test_report_pickles(report, rec):
    for protocol in range(2, pickle.HIGHEST_PROTOCOL + 1):
        again = pickle.loads(pickle.dumps(report, protocol=protocol))
        assert again == report and again is not report
        assert again.to_dict() == report.to_dict()
        assert again.summary() == report.summary()
        assert again.fitted == report.fitted and again.fitted.source == report.fitted.source
    with pytest.raises(ctr_py.InputError, match="Report state"):
        ctr_py.Report._from_state("[1]", "", report.fitted, "x", report.fitted, rec)


def test_report_html_is_the_clis_page(report, rec, cli_diagnosis):
    html = cli_diagnosis[3]
    assert report.to_html() == html
    # a pickled report keeps its robot and recording: the same page
    assert pickle.loads(pickle.dumps(report)).to_html() == html
    assert 'data-explained="true"><strong>Verdict: explained</strong>' in html
    # error by run, the residual, one per run
    assert html.count("<svg ") == 2 + len(rec.runs)
    assert "<script" not in html.lower()


def test_spreadsheet_files_read_as_the_plain_ones(tmp_path, liu, rec):
    """A byte-order mark and CRLF line ends (a spreadsheet's "CSV UTF-8")."""
    bom = b"\xef\xbb\xbf"
    for src, name in ((LIU, "robot.toml"), (CLEARANCE, "rec.csv")):
        (tmp_path / name).write_bytes(bom + src.read_bytes().replace(b"\n", b"\r\n"))
    robot = ctr_py.Robot.from_toml(tmp_path / "robot.toml")
    assert robot == liu
    again = ctr_py.read_recording(tmp_path / "rec.csv", robot)
    assert again.runs == rec.runs
    for column in ("joints", "tip", "t_s"):
        assert np.array_equal(getattr(again, column), getattr(rec, column))


def test_diagnose_options_equal_the_cli(cli, tmp_path, liu, rec, report):
    out = tmp_path / "report.json"
    p = run_cli(cli, "diagnose", "--robot", LIU, "--recording", CLEARANCE,
                "--holdout", "runs:scatter,feed-b", "--effects", "registration,clearance",
                "--threads", "1", "--report", out)
    assert p.returncode == 0, p.stderr
    r = ctr_py.diagnose(liu, rec, holdout="runs:scatter,feed-b",
                        effects=["registration", "clearance"], threads=1)
    assert r.to_dict() == json.loads(out.read_text())
    assert r.split["heldout_rows"] == 401
    assert {t["effect"] for t in r.tried} <= {"registration", "clearance"}
    # a comma-separated str as the CLI's, and a path for the recording
    again = ctr_py.diagnose(liu, str(CLEARANCE), holdout="runs:scatter,feed-b",
                            effects="registration, clearance")
    assert again.to_dict() == r.to_dict()
    # the thread count changes nothing
    assert ctr_py.diagnose(liu, rec, threads=1).to_dict() == report.to_dict()


def test_diagnosis_releases_the_gil(liu, rec):
    r, counted = spin_while(
        lambda: ctr_py.diagnose(liu, rec, effects=["clearance", "registration"])
    )
    assert r.effects == ["clearance"]
    assert counted > 10_000


@pytest.mark.parametrize("holdout", ["blocks:1", "blocks:x", "blocks:", "runs:", "runs: ", "folds:3", "4"])
def test_bad_holdout_strings(cli, liu, rec, holdout):
    message = cli_error(cli, "diagnose", "--robot", LIU, "--recording", CLEARANCE,
                        f"--holdout={holdout}")
    want = re.sub(r"^invalid value '.*' for '--holdout <SPLIT>': ", "holdout: ", message)
    for call in (lambda: ctr_py.diagnose(liu, rec, holdout=holdout),
                 lambda: ctr_py.calibrate(liu, rec, ["clearance"], holdout=holdout)):
        with pytest.raises(ctr_py.InputError) as e:
            call()
        assert str(e.value) == want and isinstance(e.value, ValueError)


def test_holdout_runs_the_recording_lacks(cli, liu, rec):
    message = cli_error(cli, "diagnose", "--robot", LIU, "--recording", CLEARANCE,
                        "--holdout", "runs:feed,nope")
    with pytest.raises(ctr_py.InputError) as e:
        ctr_py.diagnose(liu, rec, holdout="runs:feed,nope")
    assert str(e.value) == message


@pytest.mark.parametrize("effects", ["lag", "clearance,lag", "", "Clearance"])
def test_unknown_effect_ids(cli, liu, rec, effects):
    message = cli_error(cli, "diagnose", "--robot", LIU, "--recording", CLEARANCE,
                        f"--effects={effects}")
    bad = effects.split(",")[-1]
    want = re.sub(r"^invalid value '.*' for '--effects <IDS>': ", "effects: ", message)
    assert want.startswith(f'effects: unknown effect "{bad}"')
    with pytest.raises(ctr_py.InputError) as e:
        ctr_py.diagnose(liu, rec, effects=effects)
    assert str(e.value) == want
    with pytest.raises(ctr_py.InputError) as e:
        ctr_py.diagnose(liu, rec, effects=effects.split(","))
    assert str(e.value) == want
    with pytest.raises(ctr_py.InputError) as e:
        ctr_py.calibrate(liu, rec, effects.split(","))
    assert str(e.value) == want.replace("effects: ", "fit: ", 1)


def test_arguments_of_the_wrong_type(liu, rec):
    for kwargs in ({"effects": 3}, {"effects": [1]}, {"effects": [b"clearance"]},
                   {"holdout": 4}, {"holdout": ["blocks:4"]}):
        with pytest.raises(ctr_py.InputTypeError):
            ctr_py.diagnose(liu, rec, **kwargs)
    with pytest.raises(ctr_py.InputTypeError):
        ctr_py.diagnose(liu, 3.5)
    with pytest.raises(TypeError):
        ctr_py.diagnose("robot.toml", rec)
    for threads in (-1, 5000):
        with pytest.raises(ctr_py.InputError, match="threads: "):
            ctr_py.diagnose(liu, rec, threads=threads)


# ---------------------------------------------------------------- calibrate, evaluate


@pytest.mark.parametrize("table", [None, 12])
def test_calibrate_equals_the_cli(cli, tmp_path, liu, rec, table):
    out, fitted = tmp_path / "report.json", tmp_path / "fitted.toml"
    extra = ["--table", table] if table else []
    p = run_cli(cli, "calibrate", "--robot", LIU, "--recording", CLEARANCE, "--fit", "clearance",
                "--report", out, "--out", fitted, *extra)
    assert p.returncode == 0, p.stderr
    r = ctr_py.calibrate(liu, rec, ["clearance"], table=table)
    assert r.to_dict() == json.loads(out.read_text())
    assert r.fitted.to_toml() == without_comments(fitted.read_text())
    assert r.summary() == p.stdout
    assert r.effects == ["clearance"] and r.tried == []
    assert r.final["heldout_rms_mm"] < 0.3 * r.baseline["heldout_rms_mm"]


def test_calibrate_bad_input(cli, tmp_path, liu, rec):
    with pytest.raises(ctr_py.InputError, match="fit: no effect ids"):
        ctr_py.calibrate(liu, rec, [])
    for table in (2, 73, -1):
        message = cli_error(cli, "calibrate", "--robot", LIU, "--recording", CLEARANCE,
                            "--fit", "clearance", f"--table={table}")
        want = re.sub(r"^invalid value '.*' for '--table <N>': ", "table: ", message)
        with pytest.raises(ctr_py.InputError) as e:
            ctr_py.calibrate(liu, rec, ["clearance"], table=table)
        assert str(e.value) == want
    # an effect the recording cannot show: latency without t_s
    rows = read_csv(CLEARANCE)
    no_time = tmp_path / "no-time.csv"
    with open(no_time, "w", newline="") as f:
        w = csv.DictWriter(f, [k for k in rows[0] if k != "t_s"], extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    message = cli_error(cli, "calibrate", "--robot", LIU, "--recording", no_time,
                        "--fit", "latency")
    with pytest.raises(ctr_py.InputError) as e:
        ctr_py.calibrate(liu, str(no_time), "latency")
    assert str(e.value) == message


def test_evaluate_equals_the_cli(cli, tmp_path, liu, rec, report):
    fitted = tmp_path / "fitted.toml"
    fitted.write_text(report.fitted.to_toml())
    p = run_cli(cli, "evaluate", "--robot", LIU, "--robot", fitted, "--recording", CLEARANCE)
    assert p.returncode == 0, p.stderr
    table = ctr_py.evaluate([liu, report.fitted], rec)
    lines = p.stdout.strip().splitlines()[1:]
    assert [r["run"] for r in table] == [label for label, _ in rec.runs] + ["all"]
    assert len(lines) == len(table)
    for line, r in zip(lines, table):
        want = [r["run"], str(r["rows"])]
        for mean, mx in zip(r["mean_mm"], r["max_mm"]):
            want += [f"{mean:.3f}", "/", f"{mx:.3f}"]
        assert line.split() == want
    assert table[-1]["rows"] == len(rec)
    assert table[-1]["mean_mm"][1] < 0.3 * table[-1]["mean_mm"][0]
    # one robot alone, a path for the recording
    per_model = ("mean_mm", "max_mm", "lowest_margin", "near_snap", "unstable")
    assert ctr_py.evaluate(liu, str(CLEARANCE)) == [
        {**r, **{k: r[k][:1] for k in per_model}} for r in table
    ]
    assert all(r["near_snap"] == [[], []] and 0.05 < min(r["lowest_margin"]) for r in table)


def test_evaluate_bad_input(cli, liu, rec):
    nitinol3 = ctr_py.Robot.from_toml(NITINOL3)
    message = cli_error(cli, "evaluate", "--robot", LIU, "--robot", NITINOL3,
                        "--recording", CLEARANCE)
    with pytest.raises(ctr_py.InputError) as e:
        ctr_py.evaluate([liu, nitinol3], rec)
    assert str(e.value) == message
    with pytest.raises(ctr_py.InputError, match="no robots"):
        ctr_py.evaluate([], rec)
    for robots in (3, [liu, "x"]):
        with pytest.raises(ctr_py.InputTypeError):
            ctr_py.evaluate(robots, rec)


def test_the_stubs_document_every_name():
    stub = (Path(ctr_py.__file__).parent / "_ctr.pyi").read_text()
    for name in ctr_py.__all__:
        if not name.endswith("Error") and not name.startswith("__"):
            assert re.search(rf"^(class|def) {name}\b", stub, re.M), name
