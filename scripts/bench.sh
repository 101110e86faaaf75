#!/usr/bin/env bash
# Benchmark of the ctr-cli batch jobs, files to files (not a timed test):
#
#   bash scripts/bench.sh
#
# Builds the release binary, generates joint and target files for the shared 3-tube
# robot nitinol3 (inside its stable ranges: 10 <= s1, s2 - s1, s3 - s2 <= 50 mm, all
# rotations), and times, wall clock, best of RUNS runs (the machine may be shared):
#
#   fk  1,000,000 rows on 2 threads, CSV parsing and writing included (target >= 500,000
#       rows/s): a smooth trajectory (a slow motion sampled at 1 kHz: every row warm
#       starts from a near neighbour, the solve is about 1 us) and scattered rows;
#   ik  a smooth trajectory of 5,000 targets on 1 thread (warm: each from the row before;
#       target <= 100 us per target) and 2,000 scattered targets solved cold on 1 thread
#       (target <= 2 ms per target); then both on 2 threads.
#
# Times are per whole command (process start, robot file, IK seed table, reading,
# solving, writing, fsync and rename included). Needs python3 for the generators.
# Environment: RUNS (default 3), ROWS (default 1000000), KEEP=1 keeps the work directory.
set -euo pipefail
cd "$(dirname "$0")/.."

RUNS=${RUNS:-3}
ROWS=${ROWS:-1000000}
ROBOT=tests/data/shared/robots/nitinol3.toml
[ -f "$ROBOT" ] || ROBOT=data/robots/nitinol3.toml

cargo build --release -p ctr-cli 2>&1 | tail -n 1 >&2
CLI=$PWD/target/release/ctr-cli
WORK=$(mktemp -d "${TMPDIR:-/tmp}/ctr-bench.XXXXXX")
if [ "${KEEP:-0}" = 1 ]; then echo "work directory: $WORK" >&2; else trap 'rm -rf "$WORK"' EXIT; fi

# the robot with its stable ranges as [limits] (for ik)
LIMITED=$WORK/nitinol3-limited.toml
cp "$ROBOT" "$LIMITED"
for _ in 1 2 3; do
    printf '\n[[limits.tube]]\nincrement_mm = [10.0, 50.0]\ntheta_deg = [-180.0, 180.0]\n' >>"$LIMITED"
done

echo "generating $ROWS joint rows (trajectory and scattered) ..." >&2
python3 - "$WORK" "$ROWS" <<'EOF'
import sys
sys.path.insert(0, 'scripts')
from bench_joints import scattered, trajectory, write_csv
work, rows = sys.argv[1], int(sys.argv[2])

def write(name, rows):
    write_csv(f'{work}/{name}', rows)

# fk: 1 kHz samples of a motion with a 20 s period (tip speed about 20 mm/s)
write('fk-trajectory.csv', trajectory(rows, rows / 20000, 170.0))
write('fk-scattered.csv', scattered(rows, 1))
# ik: tips about 0.06 mm apart, as a 1 kHz loop at 60 mm/s
write('ik-trajectory-joints.csv', trajectory(5000, 1, 150.0))
write('ik-scattered-joints.csv', scattered(2000, 2))
EOF

# the ik targets: the tips of those joints (the tip file of ctr-cli fk is a target file)
for kind in trajectory scattered; do
    "$CLI" fk --robot "$LIMITED" --joints "$WORK/ik-$kind-joints.csv" -o "$WORK/ik-$kind-targets.csv"
done

echo "timing ($RUNS runs each) ..." >&2
python3 - "$CLI" "$ROBOT" "$LIMITED" "$WORK" "$RUNS" "$ROWS" <<'EOF'
import csv, os, subprocess, sys, time
cli, robot, limited, work, runs, rows = sys.argv[1:7]
runs, rows = int(runs), int(rows)

def best(args):
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        p = subprocess.run(args, capture_output=True)
        times.append(time.perf_counter() - t0)
        if p.returncode != 0:
            sys.exit(f'{" ".join(args)}: exit {p.returncode}: {p.stderr.decode()}')
    return min(times), sorted(times)[len(times) // 2]

def count(path, column, value):
    with open(path) as f:
        return sum(1 for r in csv.DictReader(f) if r[column] == value)

def ik_targets(kind):
    with open(f'{work}/ik-{kind}-targets.csv') as f:
        return sum(1 for _ in f) - 1

table = []
for kind, extra in [('trajectory', []), ('scattered', ['--on-error', 'mark'])]:
    out = f'{work}/fk-{kind}-tips.csv'
    b, m = best([cli, 'fk', '--robot', robot, '--joints', f'{work}/fk-{kind}.csv',
                 '-o', out, '--threads', '2'] + extra)
    size = os.path.getsize(f'{work}/fk-{kind}.csv') + os.path.getsize(out)
    note = f'{rows:,} rows, {size / 1e6:.0f} MB read + written'
    if extra:
        note += f', {rows - count(out, "status", "converged")} not converged (marked)'
    table.append((f'fk {kind}, 2 threads', f'{rows / b:,.0f} rows/s',
                  f'{rows / m:,.0f} rows/s', '>= 500,000 rows/s', note))

for kind, extra, target in [('trajectory', [], '<= 100 us'), ('scattered', ['--cold'], '<= 2 ms')]:
    n = ik_targets(kind)
    for threads in ['1', '2']:
        out = f'{work}/ik-{kind}-joints-{threads}.csv'
        b, m = best([cli, 'ik', '--robot', limited, '--targets', f'{work}/ik-{kind}-targets.csv',
                     '--position-only', '-o', out, '--threads', threads] + extra)
        reached = count(out, 'status', 'reached')
        mode = 'warm' if kind == 'trajectory' else 'cold'
        table.append((f'ik {kind} ({mode}), {threads} thread{"s" if threads != "1" else ""}',
                      f'{b / n * 1e6:.1f} us/target', f'{m / n * 1e6:.1f} us/target',
                      target if threads == '1' else '',
                      f'{n:,} targets, {reached:,} reached'))

print(f'robot: {robot} (ik: with its stable ranges as [limits]); {os.cpu_count()} cores; '
      f'best and median of {runs} runs, wall clock, whole command')
print()
print('| job | best | median | target | |')
print('|---|---|---|---|---|')
for row in table:
    print('| ' + ' | '.join(row) + ' |')
EOF
