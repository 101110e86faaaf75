"""The ctr_py wheel: results equal `ctr-cli`'s bit for bit, bad input raises the right
exception with the CLI's message, robots pickle, any array layout is accepted."""

import csv
import multiprocessing
import pickle
import re
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest

import ctr_py
from conftest import REPO, ROBOTS, spin_while

BAD = REPO / "tests" / "cli" / "bad"
SNAP = REPO / "tests" / "cli" / "snap"
NITINOL3 = REPO / "data" / "robots" / "nitinol3.toml"


# ---------------------------------------------------------------- helpers


def joints_for(robot: ctr_py.Robot, m: int, seed: int = 1) -> np.ndarray:
    """`m` rows inside the core's ranges: half a smooth sweep (warm starts matter), half
    random, feeds nested, every tube at least 5 mm beyond the one around it."""
    text = robot.to_toml()
    lengths = [float(v) for v in re.findall(r"^length_mm = (\S+)", text, re.M)]
    n = robot.n_tubes
    rng = np.random.default_rng(seed)
    q = np.empty((m, 2 * n))
    u = np.linspace(0.0, 1.0, m // 2)
    k = len(u)
    s_prev = np.zeros(m)
    for i in range(n):
        room = (lengths[i] - 5.0 * (n - i)) / n
        sweep = 5.0 + room * (0.2 + 0.6 * u)
        rand = 5.0 + room * rng.uniform(0.1, 0.9, m - k)
        q[:, 2 * i] = s_prev + np.concatenate([sweep, rand])
        s_prev = q[:, 2 * i]
        q[:, 2 * i + 1] = np.concatenate(
            [360.0 * u * (i + 1) - 180.0, rng.uniform(-180.0, 180.0, m - k)]
        )
    return q


def write_joints(path: Path, robot: ctr_py.Robot, q: np.ndarray) -> None:
    """A joint CSV whose cells are Python's shortest round-trip text (exact in Rust)."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(robot.joint_columns)
        w.writerows([[repr(float(v)) for v in row] for row in q])


def run_cli(cli: Path, *args: str, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(cli), *args], cwd=cwd, capture_output=True, text=True, stdin=subprocess.DEVNULL
    )


def read_tips(path: Path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    pos = np.array([[float(r[k]) for k in ("x_mm", "y_mm", "z_mm")] for r in rows])
    quat = np.array([[float(r[k]) for k in ("qw", "qx", "qy", "qz")] for r in rows])
    return rows, pos.reshape(-1, 3), quat.reshape(-1, 4)


def cli_fk(cli, tmp_path, robot_path, robot, q, *extra):
    joints = tmp_path / "joints.csv"
    out = tmp_path / "tips.csv"
    write_joints(joints, robot, q)
    p = run_cli(cli, "fk", "--robot", str(robot_path), "--joints", str(joints), "-o", str(out), *extra)
    assert p.returncode == 0, p.stderr
    return read_tips(out)


def cli_error(cli: Path, case: Path) -> str:
    """The CLI's one-line message for a bad-input case, without `error: `."""
    joints = "joints.parquet" if (case / "joints.parquet").exists() else "joints.csv"
    args = ["fk", "--robot", "robot.toml", "--joints", joints, "-o", "out.csv"]
    p = run_cli(cli, *args, cwd=case)
    assert p.returncode == 2
    line = p.stderr.strip()
    assert line.startswith("error: ") and "\n" not in line, line
    return line[len("error: ") :]


def after_location(message: str) -> str:
    """`robot.toml:3:1: tube 1: ...` -> `tube 1: ...`; `q[3]: ...` -> `...`."""
    return re.sub(r"^(\S+?)(:\d+)*: ", "", message, count=1)


def bits_equal(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and a.tobytes() == b.tobytes()


# ---------------------------------------------------------------- equal to the CLI


@pytest.mark.parametrize("robot_path", ROBOTS, ids=lambda p: p.stem)
@pytest.mark.parametrize("model", [None, "rigid"])
def test_fk_equals_cli_to_the_last_bit(cli, tmp_path, robot_path, model):
    robot = ctr_py.Robot.from_toml(robot_path)
    q = joints_for(robot, 300)
    extra = ["--model", model] if model else []
    _, pos, quat = cli_fk(cli, tmp_path, robot_path, robot, q, *extra)
    p, qu = robot.fk(q, model)
    assert bits_equal(p, pos)
    assert bits_equal(qu, quat)
    # and one thread gives the same bits
    p1, qu1 = robot.fk(q, model, threads=1)
    assert bits_equal(p1, p) and bits_equal(qu1, qu)


def snap_rows():
    """A robot that snaps (three tubes, long transmissions) and random joint rows of
    which some do not converge, with the index of the first such row."""
    robot = ctr_py.Robot.from_toml(SNAP / "robot.toml")
    rng = np.random.default_rng(0)
    m = 600
    s1 = rng.uniform(100.0, 150.0, m)
    s2 = s1 + rng.uniform(1.0, 30.0, m)
    s3 = s2 + rng.uniform(5.0, 40.0, m)
    turn = lambda: rng.uniform(-180, 180, m)  # noqa: E731
    q = np.stack([s1, turn(), s2, turn(), s3, turn()], axis=1)
    status = robot.fk(q, on_error="mark")[2]
    failed = np.flatnonzero(status != "converged")
    if len(failed) == 0:
        pytest.skip("the solver converges on every row: pick a harder robot or rows")
    return robot, q, failed


def test_mark_equals_cli_mark(cli, tmp_path):
    robot, q, failed = snap_rows()
    rows, pos, quat = cli_fk(cli, tmp_path, SNAP / "robot.toml", robot, q, "--on-error", "mark")
    P, Q, status, residual = robot.fk(q, on_error="mark")
    assert bits_equal(P, pos) and bits_equal(Q, quat)
    assert list(status) == [r["status"] for r in rows]
    assert bits_equal(residual, np.array([float(r["residual_per_mm"]) for r in rows]))
    assert set(status[failed]) <= {"iteration_limit", "diverged"}
    # a single row gives scalars; alone, it is solved cold (first of its chunk), as
    # the CLI solves a file of that one row
    i = failed[0]
    _, _, s0, r0 = robot.fk(q[i], on_error="mark")
    _, _, s1, r1 = robot.fk(q[i : i + 1], on_error="mark")
    assert isinstance(s0, str) and isinstance(r0, float)
    assert s0 == s1[0] and r0 == r1[0]


def test_solver_failure_raises_with_the_cli_message(cli, tmp_path):
    robot, q, failed = snap_rows()
    joints = tmp_path / "joints.csv"
    write_joints(joints, robot, q)
    p = run_cli(cli, "fk", "--robot", str(SNAP / "robot.toml"), "--joints", str(joints))
    assert p.returncode == 1
    message = p.stderr.strip()[len("error: ") :]
    with pytest.raises(ctr_py.SolverError) as e:
        robot.fk(q)
    assert isinstance(e.value, RuntimeError) and isinstance(e.value, ctr_py.CtrError)
    # joints.csv line (first failure + 2) is row q[first failure]; the CLI adds a hint
    # after the message
    i = failed[0]
    assert str(e.value).startswith(f"q[{i}]: solve ended with status ")
    assert f"; {len(failed)} of {len(q)} rows failed" in str(e.value)
    assert message.startswith(f"{joints}:{i + 2}: " + after_location(str(e.value)))
    cold = [k for k in failed if robot.fk(q[k], on_error="mark")[2] != "converged"]
    if cold:
        with pytest.raises(ctr_py.SolverError, match=r"^q: solve ended with status "):
            robot.backbone(q[cold[0]])


# ---------------------------------------------------------------- the bad-input corpus


CASES = sorted(
    case
    for case in BAD.iterdir()
    if case.is_dir() and not (case / "args").exists() and not (case / "extra-args").exists()
)
JOINT_VALUE_ERROR = re.compile(
    r'^joints\.csv:\d+: (s\d_mm = |column \w+: "[^"]*" is not a finite number)'
)


def test_corpus_is_found():
    assert len(CASES) >= 80


@pytest.mark.parametrize("case", CASES, ids=lambda p: p.name)
def test_bad_input_corpus(cli, case, monkeypatch):
    """Every `ctr-cli fk` case of `tests/cli/bad`: a bad robot file raises the CLI's
    message exactly; bad joint values (range, order, NaN, infinities) raise it located
    at the row; CSV format errors have no array counterpart (the robot must load)."""
    message = cli_error(cli, case)
    monkeypatch.chdir(case)
    if message.startswith("robot.toml"):
        with pytest.raises(ctr_py.CtrError) as e:
            ctr_py.Robot.from_toml("robot.toml")
        assert str(e.value) == message
        if "cannot read" in message:
            assert type(e.value) is ctr_py.FileError and isinstance(e.value, OSError)
        else:
            assert type(e.value) is ctr_py.InputError and isinstance(e.value, ValueError)
            # the same text given as a string gives the same message
            with pytest.raises(ctr_py.InputError) as e2:
                ctr_py.Robot.from_toml_str((case / "robot.toml").read_text(), "robot.toml")
            assert str(e2.value) == message
        return
    robot = ctr_py.Robot.from_toml("robot.toml")
    if not JOINT_VALUE_ERROR.match(message):
        # a CSV or Parquet format error, or a Parquet file's row
        assert message.startswith(("joints.csv", "joints.parquet")), message
        return
    with open("joints.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    # Python's float() reads what Rust's parser reads, NaN and infinities included
    q = np.array([[float(r[c]) for c in robot.joint_columns] for r in rows])
    line = int(re.match(r"joints\.csv:(\d+): ", message).group(1))
    with pytest.raises(ctr_py.InputError) as e:
        robot.fk(q)
    assert type(e.value) is ctr_py.InputError
    got = str(e.value)
    # rows count from 0 after the header (line 1) where lines count from 1
    assert got.startswith(f"q[{line - 2}]: ")
    # a non-finite cell is quoted as the file has it ("NaN", "-infinity") and as
    # Python prints the value ("nan", "-inf"); everything else is the same text
    norm = lambda s: re.sub(r'"[^"]*" is not a finite', '"?" is not a finite', after_location(s))
    assert norm(got) == norm(message)
    # one row alone: located at the argument
    with pytest.raises(ctr_py.InputError) as e1:
        robot.fk(q[line - 2])
    assert str(e1.value) == "q: " + after_location(got)


# ---------------------------------------------------------------- robot files


@pytest.mark.parametrize("robot_path", ROBOTS, ids=lambda p: p.stem)
def test_robot_file_round_trip(robot_path):
    r = ctr_py.Robot.from_toml(robot_path)
    assert r.source == str(robot_path)
    assert r.joint_columns[:2] == ["s1_mm", "theta1_deg"]
    assert len(r.joint_columns) == 2 * r.n_tubes
    again = ctr_py.Robot.from_toml_str(r.to_toml(), "again.toml")
    assert again == r and again.source == "again.toml"
    assert ctr_py.Robot.from_toml(Path(robot_path)) == r  # os.PathLike
    assert r.model in ("rigid", "torsion")
    assert "Robot(" in repr(r)


def test_unreadable_robot_files(tmp_path):
    with pytest.raises(ctr_py.FileError) as e:
        ctr_py.Robot.from_toml(tmp_path / "missing.toml")
    assert str(e.value) == f"{tmp_path / 'missing.toml'}: cannot read: No such file or directory (os error 2)"
    with pytest.raises(ctr_py.FileError) as e:
        ctr_py.Robot.from_toml(tmp_path)
    assert str(e.value).startswith(f"{tmp_path}: cannot read: ")
    with pytest.raises(TypeError):
        ctr_py.Robot.from_toml(3)


def test_exception_hierarchy():
    assert issubclass(ctr_py.InputError, ValueError)
    assert issubclass(ctr_py.InputTypeError, TypeError)
    assert issubclass(ctr_py.InputTypeError, ctr_py.InputError)
    assert issubclass(ctr_py.FileError, OSError)
    assert issubclass(ctr_py.SolverError, RuntimeError)
    for cls in (ctr_py.InputError, ctr_py.FileError, ctr_py.SolverError):
        assert issubclass(cls, ctr_py.CtrError)
    assert issubclass(ctr_py.CtrError, Exception)


# ---------------------------------------------------------------- shapes, dtypes, layouts


@pytest.fixture(scope="module")
def robot():
    return ctr_py.Robot.from_toml(NITINOL3)


@pytest.fixture(scope="module")
def q(robot):
    return joints_for(robot, 64, seed=7)


def test_single_row_and_batch_shapes(robot, q):
    p, quat = robot.fk(q)
    assert p.shape == (64, 3) and quat.shape == (64, 4)
    assert p.dtype == np.float64 and quat.dtype == np.float64
    assert p.flags.c_contiguous and p.flags.writeable
    p0, q0 = robot.fk(q[0])
    assert p0.shape == (3,) and q0.shape == (4,)
    # row 0 is the first of its chunk (solved cold), as the single row is
    assert bits_equal(p0, p[0]) and bits_equal(q0, quat[0])
    assert np.all(quat[:, 0] >= 0) and np.allclose(np.linalg.norm(quat, axis=1), 1.0)
    e_p, e_q = robot.fk(np.empty((0, 6)))
    assert e_p.shape == (0, 3) and e_q.shape == (0, 4)


def test_any_layout_gives_the_same_bits(robot, q):
    p, quat = robot.fk(q)
    fortran = np.asfortranarray(q)
    assert not fortran.flags.c_contiguous
    assert bits_equal(robot.fk(fortran)[0], p)
    assert bits_equal(robot.fk(q.tolist())[0], p)
    wide = np.zeros((64, 12))
    wide[:, ::2] = q
    assert bits_equal(robot.fk(wide[:, ::2])[0], p)  # column stride 2
    tall = np.repeat(q, 2, axis=0)
    assert bits_equal(robot.fk(tall[::2])[0], p)  # row stride 2
    flipped = q[::-1]
    assert bits_equal(robot.fk(flipped)[0], robot.fk(np.ascontiguousarray(flipped))[0])
    big_endian = q.astype(">f8")
    assert bits_equal(robot.fk(big_endian)[0], p)
    # the input is not modified, nor kept
    before = q.copy()
    robot.fk(q)
    assert bits_equal(q, before)


def test_other_real_dtypes_are_converted(robot):
    qi = np.array([[20, 0, 50, 90, 80, -90], [25, 10, 60, 0, 90, 45]])
    for dtype in (np.int64, np.int32, np.uint16, np.float32, np.float16):
        got = robot.fk(qi.astype(dtype) if dtype != np.uint16 else np.abs(qi).astype(dtype))
        want = robot.fk((qi if dtype != np.uint16 else np.abs(qi)).astype(dtype).astype(np.float64))
        assert bits_equal(got[0], want[0])
    assert bits_equal(robot.fk([20, 0, 50, 90, 80, -90])[0], robot.fk(qi[0].astype(float))[0])


@pytest.mark.parametrize(
    "bad",
    [
        np.ones(6, dtype=bool),
        np.ones(6, dtype=complex),
        np.array(["20"] * 6),
        np.array([object()] * 6, dtype=object),
        None,
        "20,0,50,0,80,0",
    ],
    ids=["bool", "complex", "str", "object", "None", "string"],
)
def test_non_numeric_dtypes_raise_type_errors(robot, bad):
    with pytest.raises(ctr_py.InputTypeError) as e:
        robot.fk(bad)
    assert isinstance(e.value, TypeError)
    assert str(e.value).startswith("q: dtype ")


@pytest.mark.parametrize(
    "shape", [(5,), (7,), (0,), (2, 5), (3, 6, 1), (), (1, 1, 6)], ids=str
)
def test_wrong_shapes_raise_input_errors(robot, shape):
    with pytest.raises(ctr_py.InputError) as e:
        robot.fk(np.full(shape, 10.0))
    assert type(e.value) is ctr_py.InputError
    assert str(e.value).startswith("q: shape (")
    assert "(6,) or (m, 6)" in str(e.value)


def test_ragged_lists_raise_input_errors(robot):
    with pytest.raises(ctr_py.InputError, match=r"^q: not an array of numbers"):
        robot.fk([[20, 0, 50, 0, 80, 0], [1, 2]])


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("column", range(6))
def test_non_finite_values_name_row_and_column(robot, q, value, column):
    bad = q.copy()
    bad[17, column] = value
    with pytest.raises(ctr_py.InputError) as e:
        robot.fk(bad)
    text = {np.nan: "nan", np.inf: "inf", -np.inf: "-inf"}[value] if not np.isnan(value) else "nan"
    assert str(e.value) == f'q[17]: column {robot.joint_columns[column]}: "{text}" is not a finite number'


def test_joint_range_errors(robot):
    cases = {
        (-1, 0, 50, 0, 80, 0): "q: s1_mm = -1 must be >= 0",
        (60, 0, 50, 0, 80, 0): "q: s2_mm = 50 must be >= s1_mm = 60 (inner tubes reach at least as far as outer ones)",
        (20, 0, 50, 0, 300, 0): "q: s3_mm = 300 exceeds tube 3's length_mm = 280",
    }
    for row, message in cases.items():
        for call in (robot.fk, robot.backbone, robot.jacobian):
            with pytest.raises(ctr_py.InputError) as e:
                call(np.array(row, dtype=float))
            assert str(e.value) == message


def test_bad_options(robot, q):
    with pytest.raises(ctr_py.InputError, match=r'^model: "bent" is not a model'):
        robot.fk(q, "bent")
    with pytest.raises(ctr_py.InputError, match=r'^on_error: "skip" is not fail or mark'):
        robot.fk(q, on_error="skip")
    with pytest.raises(ctr_py.InputError, match=r"^threads: -1 is not in 0\.\.=1024"):
        robot.fk(q, threads=-1)
    for call in (robot.fk, robot.jacobian):
        with pytest.raises(ctr_py.InputError, match=r"^threads: 100000 is not in 0\.\.=1024"):
            call(q, threads=100_000)
    with pytest.raises(TypeError):
        robot.fk(q, model=3)


# ---------------------------------------------------------------- pickling


def fk_rows(args):
    robot, rows = args
    return robot.fk(rows, threads=1)


def test_pickle_round_trip(robot, q):
    for protocol in range(2, pickle.HIGHEST_PROTOCOL + 1):
        again = pickle.loads(pickle.dumps(robot, protocol=protocol))
        assert again == robot and again is not robot
        assert again.source == robot.source and again.to_toml() == robot.to_toml()
        for a, b in zip(again.fk(q), robot.fk(q)):
            assert bits_equal(a, b)


def test_pickle_through_multiprocessing(robot):
    q = joints_for(robot, 256, seed=3)
    # chunks of 64 rows start at multiples of 32: the same warm-start chunks as one call
    parts = [(robot, q[i : i + 64]) for i in range(0, 256, 64)]
    with multiprocessing.get_context("spawn").Pool(2) as pool:
        results = pool.map(fk_rows, parts)
    p, quat = robot.fk(q)
    assert bits_equal(np.concatenate([r[0] for r in results]), p)
    assert bits_equal(np.concatenate([r[1] for r in results]), quat)


# ---------------------------------------------------------------- the GIL


def test_batch_fk_releases_the_gil(robot):
    q = np.tile(joints_for(robot, 64), (2000, 1))
    p, counted = spin_while(lambda: robot.fk(q)[0])
    assert p.shape == (128000, 3)
    # with the GIL held for the whole call this loop would barely run
    assert counted > 10_000


def test_concurrent_calls_agree(robot, q):
    want = robot.fk(q)[0]
    out = [None] * 4

    def work(i):
        out[i] = robot.fk(q)[0]

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert all(bits_equal(o, want) for o in out)


# ---------------------------------------------------------------- backbone, Jacobian, IK


def test_backbone_ends_at_the_tip(robot, q):
    b = robot.backbone(q[5])
    assert b.ndim == 2 and b.shape[1] == 3 and b.shape[0] >= 3
    assert np.allclose(b[0], 0.0)
    p, _ = robot.fk(q[5])
    assert np.allclose(b[-1], p, rtol=0, atol=1e-9)
    # the backbone is a path of small steps ending at the tip
    assert np.all(np.linalg.norm(np.diff(b, axis=0), axis=1) > 0)
    with pytest.raises(ctr_py.InputError, match="backbone takes one joint vector"):
        robot.backbone(q[:2])


def test_jacobian_matches_differences_of_fk(robot, q):
    j = robot.jacobian(q[5])
    assert j.shape == (6, 6)
    h = np.array([1e-5, 1e-4] * 3)
    for c in range(6):
        up, down = q[5].copy(), q[5].copy()
        up[c] += h[c]
        down[c] -= h[c]
        dp = (robot.fk(up)[0] - robot.fk(down)[0]) / (2 * h[c])
        assert np.allclose(j[:3, c], dp, rtol=1e-4, atol=1e-6), (c, j[:3, c], dp)
    # rotation of the innermost tube spins the tip: angular velocity per degree
    assert np.linalg.norm(j[3:, 5]) > 0
    jb = robot.jacobian(q[:9])
    assert jb.shape == (9, 6, 6)
    assert bits_equal(jb[5], j)
    assert bits_equal(robot.jacobian(q[:9], threads=1), jb)


def test_ik_returns_to_fk_targets(robot, q):
    p, quat = robot.fk(q[:6])
    joints, residual, status = robot.ik(p)
    assert joints.shape == (6, 6) and residual.shape == (6,) and status.shape == (6,)
    assert list(status) == ["reached"] * 6
    assert np.all(residual <= 1e-4)
    back, _ = robot.fk(joints)
    assert np.all(np.linalg.norm(back - p, axis=1) <= 1e-4)
    # independent of the thread count
    j1, r1, s1 = robot.ik(p, threads=1)
    assert bits_equal(j1, joints) and bits_equal(r1, residual)
    # a pose target
    j, r, s = robot.ik(np.concatenate([p[0], quat[0]]))
    assert s == "reached" and isinstance(r, float) and j.shape == (6,)


def test_ik_starts_and_trajectories(robot, q):
    p, _ = robot.fk(q[:4])
    # a trajectory from a known start: one chain
    j, r, s = robot.ik(p, q0=q[0])
    assert list(s) == ["reached"] * 4 and j.shape == (4, 6)
    # independent targets from one start, or one start each
    _, _, s = robot.ik(p, q0=q[0], cold=True)
    assert list(s) == ["reached"] * 4
    _, _, s = robot.ik(p, q0=q[:4], cold=True)
    assert list(s) == ["reached"] * 4
    with pytest.raises(ctr_py.InputError, match=r"^q0: 3 rows for 4 targets"):
        robot.ik(p, q0=q[:3], cold=True)
    with pytest.raises(ctr_py.InputError, match=r"^q0: one start per target needs cold=True"):
        robot.ik(p, q0=q[:4])
    with pytest.raises(ctr_py.InputError, match=r"^q0: s1_mm = -1 must be >= 0"):
        robot.ik(p[0], q0=[-1, 0, 50, 0, 80, 0])
    with pytest.raises(ctr_py.InputError, match=r"^IK option tolerance_mm = 0 must be > 0"):
        robot.ik(p, tolerance_mm=0.0)
    with pytest.raises(ctr_py.InputError, match=r"^max_iterations: 0 must be >= 1"):
        robot.ik(p, max_iterations=0)


def read_ik_output(path: Path, robot: ctr_py.Robot):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    q = np.array([[float(r[c]) for c in robot.joint_columns] for r in rows])
    residual = np.array([float(r["residual_mm"]) for r in rows])
    return q, residual, [r["status"] for r in rows]


@pytest.mark.parametrize("robot_path", ROBOTS, ids=lambda p: p.stem)
def test_ik_equals_cli_to_the_last_bit(cli, tmp_path, robot_path):
    robot = ctr_py.Robot.from_toml(robot_path)
    q = joints_for(robot, 80, seed=11)[:40]  # the smooth half: a trajectory
    pos, quat = robot.fk(q)
    cases = [
        ("position", pos, [], {}),
        ("pose", np.concatenate([pos, quat], axis=1)[:20], [], {}),
        ("cold", pos[:12], ["--cold"], {"cold": True}),
        ("one-chain", pos[:20], ["--chunk-rows", "0"], {"chunk_rows": 0}),
        ("chunks-of-8", pos, ["--chunk-rows", "8", "--tolerance-mm", "1e-6"],
         {"chunk_rows": 8, "tolerance_mm": 1e-6}),
    ]
    for name, targets, args, kwargs in cases:
        path = tmp_path / f"{name}.csv"
        columns = ["x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"][: targets.shape[1]]
        with open(path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(columns)
            w.writerows([[repr(float(v)) for v in row] for row in targets])
        out = tmp_path / f"{name}-joints.csv"
        p = run_cli(cli, "ik", "--robot", str(robot_path), "--targets", str(path), "-o", str(out), *args)
        assert p.returncode == 0, p.stderr
        want_q, want_r, want_s = read_ik_output(out, robot)
        got_q, got_r, got_s = robot.ik(targets, **kwargs)
        assert bits_equal(got_q, want_q), name
        assert bits_equal(got_r, want_r), name
        assert list(got_s) == want_s, name
        assert bits_equal(robot.ik(targets, threads=1, **kwargs)[0], got_q), name


def test_ik_unreachable_and_bad_targets(robot):
    j, r, s = robot.ik([500.0, 0.0, 0.0])
    assert s == "unreachable" and r > 300
    with pytest.raises(ctr_py.InputError) as e:
        robot.ik([[0, 0, 100], [0, np.nan, 100]])
    assert str(e.value) == 'targets[1]: column y_mm: "nan" is not a finite number'
    with pytest.raises(ctr_py.InputError, match=r"^targets: shape \(4,\) is not \(3,\)"):
        robot.ik([0, 0, 100, 1])
    with pytest.raises(ctr_py.InputError) as e:
        robot.ik([[0, 0, 100, 1, 0, 0, 0], [0, 0, 100, 2, 0, 0, 0]])
    assert str(e.value) == (
        "targets[1]: qw,qx,qy,qz = 2, 0, 0, 0 has norm 2: "
        "expected a unit quaternion (norm 1 within 1e-3)"
    )
    with pytest.raises(ctr_py.InputError, match=r"^targets: qw,qx,qy,qz = 0, 0, 0, 0 has norm 0"):
        robot.ik([0, 0, 100, 0, 0, 0, 0])
    # within 1e-3 of unit: normalised
    _, _, s = robot.ik([0, 0, 100, 1.0005, 0, 0, 0])
    assert s in ("reached", "unreachable")
    with pytest.raises(ctr_py.InputTypeError):
        robot.ik(np.array([1j, 0, 0]))


def test_package_metadata():
    assert re.match(r"^\d+\.\d+\.\d+", ctr_py.__version__)
    pkg = Path(ctr_py.__file__).parent
    assert (pkg / "py.typed").exists() and (pkg / "_ctr.pyi").exists()


# ---------------------------------------------------------------- [model.effects]

LIU = REPO / "data" / "robots" / "liu2023.toml"

STATIC_EFFECTS = (REPO / "tests" / "fixtures" / "static-effects.toml").read_text()

GRAVITY_EFFECTS = """
[model.effects.gravity]
direction_W = [0.0, -1.0, 0.0]

[model.effects.joint_offset]
rotation_deg = [5.0, 0.0]

[model.effects.registration]
translation_mm = [1.0, 2.0, 3.0]
"""

TIME_EFFECTS = """
[model.effects.latency]
tau_s = 0.15

[model.effects.friction]
rotation_play_deg = [6.0]

[model.effects.joint_offset]
feed_mm = [0.2, 0.0]

[model.effects.registration]
translation_mm = [0.5, 0.0, -1.0]
"""

LIU_LIMITS = """
[[limits.tube]]
increment_mm = [20.0, 70.0]
theta_deg = [-180.0, 180.0]

[[limits.tube]]
increment_mm = [25.0, 95.0]
theta_deg = [-180.0, 180.0]
"""


def liu_with(tmp_path: Path, tables: str, name: str = "robot.toml") -> Path:
    path = tmp_path / name
    path.write_text(LIU.read_text() + "\n" + tables)
    return path


def liu_joints(m: int) -> np.ndarray:
    """A smooth motion of liu2023 inside its stable ranges; the rotations reverse."""
    u = np.arange(m) / 10.0
    s1 = 40.0 + 10.0 * np.sin(0.7 * u)
    s2 = s1 + 55.0 + 15.0 * np.sin(0.5 * u + 1.0)
    return np.stack(
        [s1, 60.0 * np.sin(0.9 * u), s2, 150.0 * np.sin(0.6 * u + 0.5)], axis=1
    )


@pytest.mark.parametrize("tables", [STATIC_EFFECTS, GRAVITY_EFFECTS], ids=["static", "gravity"])
def test_fk_with_effects_equals_cli_to_the_last_bit(cli, tmp_path, tables):
    path = liu_with(tmp_path, tables)
    robot = ctr_py.Robot.from_toml(path)
    q = liu_joints(100)
    _, pos, quat = cli_fk(cli, tmp_path, path, robot, q)
    p, qu = robot.fk(q)
    assert bits_equal(p, pos) and bits_equal(qu, quat)
    p1, qu1 = robot.fk(q, threads=1)
    assert bits_equal(p1, p) and bits_equal(qu1, qu)
    # the effects act
    plain, _ = ctr_py.Robot.from_toml(LIU).fk(q)
    assert np.max(np.linalg.norm(p - plain, axis=1)) > 0.1


def test_effects_survive_to_toml_and_pickling(tmp_path):
    robot = ctr_py.Robot.from_toml(liu_with(tmp_path, STATIC_EFFECTS))
    text = robot.to_toml()
    for table in ("joint_offset", "clearance", "stiffness", "precurvature", "sensor_offset", "registration"):
        assert f"[model.effects.{table}]" in text
    again = ctr_py.Robot.from_toml_str(text, "fitted.toml")
    assert again == robot
    q = liu_joints(40)
    assert bits_equal(again.fk(q)[0], robot.fk(q)[0])
    unpickled = pickle.loads(pickle.dumps(robot))
    assert unpickled == robot and bits_equal(unpickled.fk(q)[0], robot.fk(q)[0])
    # the effects are part of the robot: without them it is another robot
    assert robot != ctr_py.Robot.from_toml(LIU)


def test_time_effects_need_times_and_equal_cli(cli, tmp_path):
    path = liu_with(tmp_path, TIME_EFFECTS)
    robot = ctr_py.Robot.from_toml(path)
    q = liu_joints(80)
    t = 0.1 * np.arange(len(q))
    with pytest.raises(ctr_py.InputError, match=r"model\.effects\.latency acts along time: pass t_s="):
        robot.fk(q)
    p, qu = robot.fk(q, t_s=t)
    # ctr-cli fk on the same rows with a t_s column (one run)
    joints = tmp_path / "joints.csv"
    with open(joints, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t_s", *robot.joint_columns])
        w.writerows([[repr(float(ti)), *(repr(float(v)) for v in row)] for ti, row in zip(t, q)])
    out = tmp_path / "tips.csv"
    r = run_cli(cli, "fk", "--robot", str(path), "--joints", str(joints), "-o", str(out))
    assert r.returncode == 0, r.stderr
    _, pos, quat = read_tips(out)
    assert bits_equal(p, pos) and bits_equal(qu, quat)
    # time matters: the static part alone differs
    static = ctr_py.Robot.from_toml(
        liu_with(
            tmp_path,
            "[model.effects.joint_offset]\nfeed_mm = [0.2, 0.0]\n"
            "[model.effects.registration]\ntranslation_mm = [0.5, 0.0, -1.0]\n",
            "static.toml",
        )
    )
    assert np.max(np.linalg.norm(static.fk(q)[0] - p, axis=1)) > 0.1
    # bad times
    with pytest.raises(ctr_py.InputError, match=r"^t_s\[3\]: 0\.1 is earlier than the previous row's 0\.2"):
        bad = t.copy()
        bad[3] = 0.1
        robot.fk(q, t_s=bad)
    with pytest.raises(ctr_py.InputError, match=r"^t_s\[2\]: nan is not a finite number"):
        bad = t.copy()
        bad[2] = np.nan
        robot.fk(q, t_s=bad)
    with pytest.raises(ctr_py.InputError, match=r"^t_s: "):
        robot.fk(q, t_s=t[:-1])
    # one row: a float time
    p0, _ = robot.fk(q[0], t_s=0.0)
    assert p0.shape == (3,)


def test_friction_alone_needs_times_too(tmp_path):
    robot = ctr_py.Robot.from_toml(liu_with(tmp_path, "[model.effects.friction]\nrotation_play_deg = [6.0]\n"))
    q = liu_joints(20)
    with pytest.raises(ctr_py.InputError, match=r"model\.effects\.friction acts along time"):
        robot.fk(q)
    p, _ = robot.fk(q, t_s=np.arange(20.0))
    assert p.shape == (20, 3)
    with pytest.raises(ctr_py.InputError, match=r"model\.effects\.friction: a time effect cannot be inverted"):
        robot.ik(p)


def test_ik_through_static_effects(tmp_path):
    robot = ctr_py.Robot.from_toml(liu_with(tmp_path, STATIC_EFFECTS + LIU_LIMITS))
    q = liu_joints(30)
    targets, _ = robot.fk(q)
    joints, residual, status = robot.ik(targets)
    assert list(status) == ["reached"] * len(q)
    back, _ = robot.fk(joints)
    assert np.max(np.linalg.norm(back - targets, axis=1)) <= 1e-3
    # the Jacobian is the measured tip's
    j = robot.jacobian(q[3])
    h = 1e-5
    up, down = q[3].copy(), q[3].copy()
    up[0] += h
    down[0] -= h
    dp = (robot.fk(up)[0] - robot.fk(down)[0]) / (2 * h)
    assert np.allclose(j[:3, 0], dp, rtol=1e-4, atol=1e-6)


def test_ik_refuses_latency_with_the_cli_message(cli, tmp_path):
    case = BAD / "ik-latency-refused"
    robot = ctr_py.Robot.from_toml(case / "robot.toml")
    p = run_cli(cli, "ik", "--robot", "robot.toml", "--targets", "targets.csv", "-o", str(tmp_path / "o.csv"), cwd=case)
    assert p.returncode == 2
    message = p.stderr.strip()[len("error: ") :]
    with pytest.raises(ctr_py.InputError) as e:
        robot.ik([-5.0, 0.0, 90.0])
    assert str(e.value) == message.replace("robot.toml", str(case / "robot.toml"), 1)


def test_backbone_with_effects(tmp_path):
    robot = ctr_py.Robot.from_toml(
        liu_with(tmp_path, "[model.effects.registration]\ntranslation_mm = [3.0, -2.0, 5.0]\n"
                 "rotation_axis = [0.3, 0.9, 0.3]\nrotation_deg = 2.0\n"
                 "[model.effects.joint_offset]\nrotation_deg = [0.0, 10.0]\n"
                 "[model.effects.stiffness]\nfactor = [1.1, 0.9]\n")
    )
    q = liu_joints(5)[3]
    b = robot.backbone(q)
    p, _ = robot.fk(q)
    assert np.allclose(b[-1], p, rtol=0, atol=1e-9)
    assert np.allclose(b[0], [3.0, -2.0, 5.0], rtol=0, atol=1e-12)
    clearance = ctr_py.Robot.from_toml(
        liu_with(tmp_path, "[model.effects.clearance]\nmax_deflection_deg = [2.5]\npeak_deg = [205.0]\n", "c.toml")
    )
    # the kinks are in the one solve request: the backbone ends at fk's tip
    b = clearance.backbone(q)
    p, _ = clearance.fk(q)
    assert np.allclose(b[-1], p, rtol=0, atol=1e-9)
    assert not np.allclose(b[-1], ctr_py.Robot.from_toml(liu_with(tmp_path, "", "plain.toml")).fk(q)[0])
    friction = ctr_py.Robot.from_toml(
        liu_with(tmp_path, "[model.effects.friction]\nrotation_play_deg = [4.0]\n", "f.toml")
    )
    with pytest.raises(ctr_py.InputError, match=r"model\.effects\.friction: backbone solves one joint vector"):
        friction.backbone(q)
