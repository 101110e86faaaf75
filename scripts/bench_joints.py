"""The joint rows the bench scripts time (scripts/bench.sh, bench_warning.sh,
bench_io.sh): a smooth three-tube trajectory and scattered configurations inside the
stable ranges of nitinol3 (every feed increment 10-50 mm), with a text label column.

    import bench_joints as bj
    bj.write_csv("fk.csv", bj.trajectory(1_000_000, 50, 170.0))
"""
import math
import random

# feed increment range of every tube, mm
INCREMENTS_MM = [(10.0, 50.0)] * 3
COLUMNS = ['label', 's1_mm', 'theta1_deg', 's2_mm', 'theta2_deg', 's3_mm', 'theta3_deg']


def trajectory(n, cycles, turn_deg):
    """n rows along which every joint is a sinusoid: `cycles` periods of the slowest
    feed over the rows, rotations within +/- turn_deg."""
    for k in range(n):
        t = 2 * math.pi * cycles * k / n
        s, row = 0.0, []
        for i, (lo, hi) in enumerate(INCREMENTS_MM):
            f = 1.0 + i
            s += 0.5 * (lo + hi) + 0.4 * (hi - lo) * math.sin(f * t + 0.3 * f)
            row += [s, turn_deg * math.sin(0.5 * f * t + f)]
        yield row


def scattered(n, seed):
    """n configurations drawn uniformly over the increments and full turns."""
    rnd = random.Random(seed)
    for _ in range(n):
        s, row = 0.0, []
        for lo, hi in INCREMENTS_MM:
            s += lo + (hi - lo) * rnd.random()
            row += [s, 360.0 * rnd.random() - 180.0]
        yield row


def write_csv(path, rows):
    """The rows as a joint CSV file, labelled r0, r1, ..."""
    with open(path, 'w') as f:
        f.write(','.join(COLUMNS) + '\n')
        for k, row in enumerate(rows):
            f.write(f'r{k},' + ','.join(repr(v) for v in row) + '\n')
