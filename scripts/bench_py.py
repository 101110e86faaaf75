"""Benchmark of the ctr_py wheel: 1,000,000 forward kinematics of nitinol3 in one call.

    python scripts/bench_py.py [--rows 1000000] [--threads 0] [--repeat 3]

Rows follow a smooth path through the robot's stable range (10 <= s1, s2 - s1,
s3 - s2 <= 50 mm, all rotations), as a sweep or a trajectory would; with `--random`
they are drawn at random in that range instead (no warm start to help). Prints the
best of `--repeat` calls: wall time and rows per second, and the time of turning the
joints into a float64 array is not counted. The issue's target: <= 1 s on 2 cores.
Not a test: nothing is asserted.

Measured (2026-11, the 2-core development VM, another build running beside it at
times; wheel built by `pip install ./crates/ctr-py`, release):
    path,   threads=2: best 0.65 s (1.5 M rows/s); 0.77 s with another build running
    path,   threads=1: 1.13 s
    random, threads=2: 1.48 s (cold-like solves; the core's cost, not the wheel's)
"""

import argparse
import os
import time
from pathlib import Path

import numpy as np

import ctr_py

REPO = Path(__file__).resolve().parents[1]


def joints(rows: int, random: bool) -> np.ndarray:
    if random:
        rng = np.random.default_rng(0)
        inc = rng.uniform(10.0, 50.0, (rows, 3))
        theta = rng.uniform(-180.0, 180.0, (rows, 3))
    else:
        u = np.linspace(0.0, 1.0, rows)
        inc = np.stack([30 + 20 * np.sin(2 * np.pi * k * u + k) for k in (3, 5, 7)], axis=1)
        theta = np.stack([180 * np.sin(2 * np.pi * k * u) for k in (11, 13, 17)], axis=1)
    s = np.cumsum(inc, axis=1)
    q = np.empty((rows, 6))
    q[:, 0::2] = s
    q[:, 1::2] = theta
    return q


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=1_000_000)
    ap.add_argument("--threads", type=int, default=0, help="0 = all cores")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--random", action="store_true")
    args = ap.parse_args()

    robot = ctr_py.Robot.from_toml(REPO / "data" / "robots" / "nitinol3.toml")
    q = joints(args.rows, args.random)
    # random rows include a few that do not converge: mark them rather than fail (the
    # status array costs about 0.05 s per million rows)
    on_error = "mark" if args.random else "fail"
    best = float("inf")
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        out = robot.fk(q, threads=args.threads, on_error=on_error)
        best = min(best, time.perf_counter() - t0)
    failed = int((out[2] != "converged").sum()) if args.random else 0
    print(
        f"ctr_py {ctr_py.__version__}: {args.rows} FK of nitinol3 "
        f"({'random' if args.random else 'path'}) in one call, "
        f"threads={args.threads or os.cpu_count()}: best {best:.3f} s "
        f"({args.rows / best:,.0f} rows/s), {failed} not converged"
    )


if __name__ == "__main__":
    main()
