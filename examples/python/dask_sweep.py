"""Sweeps beyond one machine with Dask: forward kinematics over a large joint grid in
chunks, and a diagnosis per recording, as Dask tasks.

    python examples/python/dask_sweep.py OUT_DIR [--scheduler tcp://host:8786]
        [--robot data/robots/liu2023.toml] [--points 18] [--chunk 10000]
        [--diagnose [ROBOT.toml=]REC.csv ...] [--workers 2]

Without ``--scheduler`` it starts a ``LocalCluster`` (``--workers`` processes of one
thread each); with it, it connects to any running scheduler (``dask scheduler`` on one
machine, ``dask worker tcp://host:8786`` on the others; every worker needs
``pip install ctr-py``). The robot is scattered to the workers once; each FK task
builds its slice of the grid itself (only indices travel) and solves it with one
thread (the workers are the parallelism). Each diagnosis is one task: the recording
travels with it, the report comes back (robots, recordings and reports pickle).

Results are written as they finish, with a progress line per result: the FK chunks as
``fk-00000.parquet`` (``.csv`` without pyarrow: the joints, the tip ``x_mm,y_mm,z_mm``,
``qw,qx,qy,qz`` and the solver's ``status``), each diagnosis as
``diagnosis-<recording>.json`` (the ``--report`` JSON) and ``.html`` (the page
``ctr-cli diagnose --html`` writes).

The grid: every tube's feed increment ``s_i - s_(i-1)`` over its stable range (the
shared manifest's ``valid_ranges`` for the bundled robots, or ``--increments
a:b,c:d,...``) and every rotation over [-180, 180) degrees, ``--points`` values per
joint, so ``points ** (2 n)`` rows. Rows are ordered as ``numpy.unravel_index`` orders
them. A chunk warm-starts afresh, so its tips equal a single serial ``robot.fk`` of all
rows to the solver's tolerance (well below 1e-6 mm), and bit for bit when ``--chunk``
is a multiple of 32 (the batch's warm-start block).
"""

import argparse
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import ctr_py

REPO = Path(__file__).resolve().parents[2]
MANIFEST = REPO / "tests" / "data" / "shared" / "manifest.json"
ROTATION_RANGE_DEG = (-180.0, 180.0)
TIP_COLUMNS = ["x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"]


@dataclass(frozen=True)
class Grid:
    """A regular joint grid: per joint, in file order (``s1_mm, theta1_deg, ...``),
    the values it takes; feeds are given as increments ``s_i - s_(i-1)`` so every row
    nests the tubes. Small: it is what a task receives, not the rows."""

    axes: tuple  # per joint: a tuple of values (feeds: increments, mm; rotations: deg)

    @property
    def shape(self) -> tuple:
        return tuple(len(a) for a in self.axes)

    def __len__(self) -> int:
        return int(np.prod(self.shape))

    def rows(self, start: int, stop: int) -> np.ndarray:
        """Rows ``start..stop`` as joints ``(stop - start, 2 n)`` in file order."""
        index = np.unravel_index(np.arange(start, stop), self.shape)
        q = np.column_stack([np.asarray(a)[i] for a, i in zip(self.axes, index)])
        q[:, 0::2] = np.cumsum(q[:, 0::2], axis=1)  # increments -> feeds s_i
        return q


def stable_increments(robot: ctr_py.Robot) -> list:
    """The robot's stable feed increments from the shared manifest (bundled robots)."""
    manifest = json.loads(MANIFEST.read_text())
    ranges = manifest["robots"].get(robot.name or "", {}).get("valid_ranges")
    if ranges is None:
        raise SystemExit(f"{robot.source}: no stable ranges known; give --increments a:b,...")
    return ranges["increments"]


def make_grid(robot: ctr_py.Robot, points: int, increments=None) -> Grid:
    """``points`` values per joint: feed increments over ``increments`` (per tube,
    ``[lo, hi]`` mm), rotations over [-180, 180) degrees."""
    increments = increments or stable_increments(robot)
    if len(increments) != robot.n_tubes:
        raise SystemExit(f"{len(increments)} increment ranges for {robot.n_tubes} tubes")
    rotations = np.linspace(*ROTATION_RANGE_DEG, points, endpoint=False)
    axes = []
    for lo, hi in increments:
        axes += [tuple(np.linspace(lo, hi, points)), tuple(rotations)]
    return Grid(tuple(axes))


def fk_chunk(robot: ctr_py.Robot, grid: Grid, start: int, stop: int) -> dict:
    """A task: FK of grid rows ``start..stop`` on one thread; joints, tips and status."""
    q = grid.rows(start, stop)
    tips, quats, status, _ = robot.fk(q, on_error="mark", threads=1)
    return {"start": start, "joints": q, "tips": tips, "quats": quats,
            "status": np.asarray(status)}


def diagnose_task(robot: ctr_py.Robot, recording) -> ctr_py.Report:
    """A task: the diagnosis of one recording (a ``ctr_py.Recording`` or a path the
    worker can read), on the worker's one thread."""
    return ctr_py.diagnose(robot, recording, threads=1)


def write_table(path_stem: Path, columns: dict) -> Path:
    """Writes named columns as Parquet when pyarrow is importable, else CSV."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        path = path_stem.with_suffix(".csv")
        names = list(columns)
        data = np.column_stack([np.asarray(columns[n], dtype=object) for n in names])
        with open(path, "w", newline="") as f:
            f.write(",".join(names) + "\n")
            for row in data:
                f.write(",".join(map(str, row)) + "\n")
        return path
    path = path_stem.with_suffix(".parquet")
    pq.write_table(pa.table({n: np.asarray(v) for n, v in columns.items()}), path)
    return path


def write_fk(out: Path, robot: ctr_py.Robot, chunk: int, result: dict) -> Path:
    columns = {name: result["joints"][:, k] for k, name in enumerate(robot.joint_columns)}
    tip = np.column_stack([result["tips"], result["quats"]])
    columns.update({name: tip[:, k] for k, name in enumerate(TIP_COLUMNS)})
    columns["status"] = result["status"]
    return write_table(out / f"fk-{chunk:05d}", columns)


def write_report(out: Path, report: ctr_py.Report) -> list:
    stem = out / f"diagnosis-{Path(report.recording).stem}"
    json_path, html_path = stem.with_suffix(".json"), stem.with_suffix(".html")
    json_path.write_text(report.to_json())
    html_path.write_text(report.to_html(), encoding="utf-8")
    return [json_path, html_path]


def run(client, robot: ctr_py.Robot, grid: Grid, chunk: int, recordings: list, out: Path,
        log=print) -> dict:
    """Submits the FK chunks and the diagnoses, writes each result as it finishes and
    logs progress; returns counts and the reports by recording."""
    from distributed import as_completed

    robot_on_workers = client.scatter(robot, broadcast=True)  # once, to every worker
    starts = list(range(0, len(grid), chunk))
    fk = client.map(fk_chunk, [robot_on_workers] * len(starts), [grid] * len(starts),
                    starts, [min(s + chunk, len(grid)) for s in starts], pure=False)
    kinds = {f.key: ("fk", k) for k, f in enumerate(fk)}
    diagnoses = []
    for r, rec in recordings:
        r_future = robot_on_workers if r is robot else client.scatter(r)
        diagnoses.append(client.submit(diagnose_task, r_future, rec, pure=False))
    kinds.update({f.key: ("diagnosis", k) for k, f in enumerate(diagnoses)})
    done = {"fk_rows": 0, "fk_chunks": 0, "not_converged": 0, "reports": {}}
    t0 = time.monotonic()
    for future in as_completed(fk + diagnoses):
        kind, k = kinds[future.key]
        result = future.result()
        if kind == "fk":
            path = write_fk(out, robot, k, result)
            done["fk_chunks"] += 1
            done["fk_rows"] += len(result["tips"])
            done["not_converged"] += int(np.sum(result["status"] != "converged"))
            what = (f"fk {done['fk_chunks']}/{len(fk)} chunks, "
                    f"{done['fk_rows']:,}/{len(grid):,} rows -> {path.name}")
        else:
            paths = write_report(out, result)
            done["reports"][result.recording] = result
            what = (f"diagnosis {len(done['reports'])}/{len(diagnoses)}: "
                    f"{Path(result.recording).name}: explained={result.explained}, "
                    f"findings {result.effects} -> {paths[1].name}")
        log(f"[{time.monotonic() - t0:6.1f} s] {what}")
        future.release()
    return done


def parse_recordings(robot: ctr_py.Robot, items: list) -> list:
    """``[ROBOT.toml=]REC.csv`` items as (robot, recording) pairs, read here."""
    pairs = []
    for item in items:
        robot_path, _, rec_path = item.rpartition("=")
        r = ctr_py.Robot.from_toml(robot_path) if robot_path else robot
        pairs.append((r, ctr_py.read_recording(rec_path, r)))
    return pairs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path, help="directory for the results (created)")
    ap.add_argument("--scheduler", help="address of a running scheduler, e.g. tcp://host:8786 "
                    "(default: a LocalCluster on this machine)")
    ap.add_argument("--workers", type=int, default=2, help="LocalCluster worker processes")
    ap.add_argument("--robot", default=str(REPO / "data" / "robots" / "liu2023.toml"))
    ap.add_argument("--points", type=int, default=18, help="values per joint (rows: points^(2n))")
    ap.add_argument("--increments", help="feed increment ranges a:b,c:d,... (mm, one per tube)")
    ap.add_argument("--chunk", type=int, default=10_000, help="grid rows per FK task")
    ap.add_argument("--diagnose", nargs="*", metavar="[ROBOT.toml=]REC.csv",
                    default=[str(REPO / "data" / "examples" / "liu2023-recording.csv")],
                    help="recordings to diagnose, each a task (default: the bundled one)")
    args = ap.parse_args()

    from distributed import Client, LocalCluster

    robot = ctr_py.Robot.from_toml(args.robot)
    increments = ([[float(v) for v in r.split(":")] for r in args.increments.split(",")]
                  if args.increments else None)
    grid = make_grid(robot, args.points, increments)
    recordings = parse_recordings(robot, args.diagnose)
    args.out.mkdir(parents=True, exist_ok=True)
    if args.scheduler:
        cluster, client = None, Client(args.scheduler)
    else:
        cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1,
                               processes=True, dashboard_address=None)
        client = Client(cluster)
    try:
        print(f"{client}: {len(grid):,} grid rows of {robot.source} in chunks of {args.chunk:,}, "
              f"{len(recordings)} recording(s) to diagnose; writing to {args.out}",
              file=sys.stderr)
        t0 = time.monotonic()
        done = run(client, robot, grid, args.chunk, recordings, args.out,
                   log=lambda line: print(line, file=sys.stderr))
        print(f"done in {time.monotonic() - t0:.1f} s: {done['fk_rows']:,} rows "
              f"({done['not_converged']} not converged), {len(done['reports'])} diagnoses")
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


if __name__ == "__main__":
    main()
