"""Sweeps beyond one machine: FK over a large joint grid in chunks and a diagnosis as
Dask tasks on a LocalCluster of two worker processes (examples/python/dask_sweep.py's
functions) give what the serial calls give."""

import importlib.util
import pickle
import sys
import time

import numpy as np
import pytest

import ctr_py
from conftest import REPO, SHARED

distributed = pytest.importorskip("distributed")

EXAMPLE = REPO / "examples" / "python" / "dask_sweep.py"
NITINOL2 = SHARED / "robots" / "nitinol2.toml"
CLEAN = SHARED / "recordings" / "dev-clean.csv"  # a recording of nitinol2
LIU = REPO / "data" / "robots" / "liu2023.toml"
# values per joint of the liu2023 grid: 18 ** 4 = 104,976 configurations
POINTS = 18
# rows per FK task: not a multiple of the batch's warm-start block of 32 rows, so the
# chunks start from other warm starts than the serial call
CHUNK = 10_000
# ... and one that is: bit for bit
ALIGNED_CHUNK = 32 * 320
# the bound on the tips of a chunked sweep against the serial call, mm
TIP_TOLERANCE_MM = 1e-6


def load_example():
    """The example as module `dask_sweep`, the name `Client.upload_file` gives it on
    the workers (its functions travel by reference)."""
    spec = importlib.util.spec_from_file_location(EXAMPLE.stem, EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    sys.modules[EXAMPLE.stem] = module
    spec.loader.exec_module(module)
    return module


example = load_example()


@pytest.fixture(scope="module")
def client():
    t0 = time.monotonic()
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        with distributed.Client(cluster) as c:
            # the workers import the example's functions from a copy (load=False: the
            # scheduler, in this process, would reload the module from its copy)
            c.upload_file(str(EXAMPLE), load=False)
            print(f"\nLocalCluster of 2 processes up in {time.monotonic() - t0:.1f} s")
            yield c


@pytest.fixture(scope="module")
def liu():
    return ctr_py.Robot.from_toml(LIU)


def chunked_fk(client, robot, grid, chunk):
    """FK of the whole grid as tasks, the robot scattered once: tips, statuses."""
    on_workers = client.scatter(robot, broadcast=True)
    starts = range(0, len(grid), chunk)
    futures = client.map(example.fk_chunk, [on_workers] * len(starts), [grid] * len(starts),
                         starts, [min(s + chunk, len(grid)) for s in starts], pure=False)
    results = sorted(client.gather(futures), key=lambda r: r["start"])
    return (np.concatenate([r["tips"] for r in results]),
            np.concatenate([r["status"] for r in results]))


def test_fk_over_100k_configurations_in_chunks_equals_the_serial_call(client, liu):
    grid = example.make_grid(liu, POINTS)
    assert len(grid) >= 100_000
    t0 = time.monotonic()
    tips, status = chunked_fk(client, liu, grid, CHUNK)
    t_dask = time.monotonic() - t0
    t0 = time.monotonic()
    serial_tips, _, serial_status, _ = liu.fk(grid.rows(0, len(grid)), on_error="mark")
    t_serial = time.monotonic() - t0
    assert tips.shape == (len(grid), 3)
    assert np.array_equal(status, serial_status)
    converged = status == "converged"
    diff = float(np.max(np.abs(tips[converged] - serial_tips[converged])))
    print(f"{len(grid):,} rows in {len(range(0, len(grid), CHUNK))} tasks: {t_dask:.2f} s "
          f"(serial, all cores: {t_serial:.2f} s); {int((~converged).sum())} not converged; "
          f"largest tip difference {diff:.2e} mm")
    assert diff <= TIP_TOLERANCE_MM
    # chunks that start on the batch's warm-start blocks give the serial bits
    aligned, _ = chunked_fk(client, liu, grid, ALIGNED_CHUNK)
    assert np.array_equal(aligned[converged], serial_tips[converged])


def test_a_diagnosis_as_a_task_equals_the_serial_report(client):
    robot = ctr_py.Robot.from_toml(NITINOL2)
    rec = ctr_py.read_recording(CLEAN, robot)
    t0 = time.monotonic()
    remote = client.submit(example.diagnose_task, robot, rec, pure=False).result()
    t_task = time.monotonic() - t0
    serial = ctr_py.diagnose(robot, rec)
    print(f"diagnosis of {CLEAN.name} as a task: {t_task:.2f} s")
    assert remote == serial
    assert remote.to_dict() == serial.to_dict()
    assert remote.summary() == serial.summary()
    assert remote.fitted == serial.fitted
    assert remote.to_html() == serial.to_html()
    # what travelled pickles back to the same report
    assert pickle.loads(pickle.dumps(remote)) == serial


@pytest.mark.parametrize("parquet", [True, False])
def test_results_are_written_as_they_finish(client, liu, tmp_path, monkeypatch, parquet):
    if parquet:
        pq = pytest.importorskip("pyarrow.parquet")
    else:
        monkeypatch.setitem(sys.modules, "pyarrow", None)  # import pyarrow fails
    robot = ctr_py.Robot.from_toml(NITINOL2)
    rec = ctr_py.read_recording(CLEAN, robot)
    grid = example.make_grid(liu, 6)
    lines = []
    done = example.run(client, liu, grid, 500, [(robot, rec)], tmp_path, log=lines.append)
    chunks = len(range(0, len(grid), 500))
    assert done["fk_rows"] == len(grid) and done["fk_chunks"] == chunks
    assert len(lines) == chunks + 1 and lines[-1].count("diagnosis 1/1") == 1
    assert any(f"fk {chunks}/{chunks} chunks, {len(grid):,}/{len(grid):,} rows" in l for l in lines)
    suffix = ".parquet" if parquet else ".csv"
    files = sorted(tmp_path.glob("fk-*" + suffix))
    assert len(files) == chunks
    if parquet:
        tables = [pq.read_table(f) for f in files]
        x = np.concatenate([t.column("x_mm").to_numpy() for t in tables])
        s1 = np.concatenate([t.column("s1_mm").to_numpy() for t in tables])
    else:
        data = [np.genfromtxt(f, delimiter=",", names=True, dtype=None, encoding="utf-8")
                for f in files]
        x = np.concatenate([d["x_mm"] for d in data])
        s1 = np.concatenate([d["s1_mm"] for d in data])
    serial_tips, _ = liu.fk(grid.rows(0, len(grid)))
    assert np.array_equal(s1, grid.rows(0, len(grid))[:, 0])
    assert np.max(np.abs(x - serial_tips[:, 0])) <= TIP_TOLERANCE_MM
    report = done["reports"][rec.file]
    assert (tmp_path / "diagnosis-dev-clean.json").read_text() == report.to_json()
    assert (tmp_path / "diagnosis-dev-clean.html").read_text(encoding="utf-8") == report.to_html()
