#!/usr/bin/env bash
# What fk's default snap warning (--warn-margin 0.05) costs: ctr-cli fk with the
# defaults against --warn-margin 0 (no margins at all), side by side in one run (not a
# timed test):
#
#   bash scripts/bench_warning.sh
#
# Generates, for the shared 3-tube robot nitinol3 (inside its stable ranges:
# 10 <= s1, s2 - s1, s3 - s2 <= 50 mm, all rotations), ROWS rows (default 200,000) of a
# smooth trajectory (scripts/bench.sh's: a slow motion sampled at 1 kHz) and ROWS random
# rows (seeded), then
#
#   1. times `ctr-cli fk --threads 1` on each, defaults and --warn-margin 0 alternated,
#      RUNS runs each (default 5), and prints the best times and their ratio (the
#      median ratio beside it: the machine may be shared);
#   2. times the defaults on 2 threads (rows/s, best of RUNS);
#   3. counts instructions with valgrind --tool=callgrind (if installed; CALLGRIND=0
#      skips it) on the first CG_TRAJ (40,000: one period of the trajectory's slowest
#      joint) and CG_RANDOM (20,000) rows, --threads 1: the noise-free ratio.
#
# Whole commands: process start, reading, solving, writing the CSV. Needs python3.
# Environment: ROWS, RUNS, CALLGRIND, CG_TRAJ, CG_RANDOM, CLI (a ctr-cli to time instead
# of building this tree's), KEEP=1 keeps the work directory.
set -euo pipefail
cd "$(dirname "$0")/.."

ROWS=${ROWS:-200000}
RUNS=${RUNS:-5}
CG_TRAJ=${CG_TRAJ:-40000}
CG_RANDOM=${CG_RANDOM:-20000}
ROBOT=tests/data/shared/robots/nitinol3.toml
[ -f "$ROBOT" ] || ROBOT=data/robots/nitinol3.toml

if [ -z "${CLI:-}" ]; then
    cargo build --release -p ctr-cli 2>&1 | tail -n 1 >&2
    CLI=$PWD/target/release/ctr-cli
fi
WORK=$(mktemp -d "${TMPDIR:-/tmp}/ctr-bench-warning.XXXXXX")
if [ "${KEEP:-0}" = 1 ]; then echo "work directory: $WORK" >&2; else trap 'rm -rf "$WORK"' EXIT; fi

echo "generating $ROWS rows each (trajectory and random) ..." >&2
python3 - "$WORK" "$ROWS" <<'EOF'
import sys
sys.path.insert(0, 'scripts')
from bench_joints import scattered, trajectory, write_csv
work, rows = sys.argv[1], int(sys.argv[2])

def write(name, rows):
    write_csv(f'{work}/{name}', rows)

# 1 kHz samples of a motion with a 20 s period (as scripts/bench.sh)
write('trajectory.csv', trajectory(rows, rows / 20000, 170.0))
write('random.csv', scattered(rows, 1))
EOF

echo "timing ($RUNS runs each) ..." >&2
python3 - "$CLI" "$ROBOT" "$WORK" "$RUNS" "$ROWS" <<'EOF'
import subprocess, sys, time
cli, robot, work, runs, rows = sys.argv[1:6]
runs, rows = int(runs), int(rows)

def once(args):
    t0 = time.perf_counter()
    p = subprocess.run(args, capture_output=True)
    if p.returncode != 0:
        sys.exit(f'{" ".join(args)}: exit {p.returncode}: {p.stderr.decode()}')
    return time.perf_counter() - t0

print(f'ctr-cli fk, nitinol3, {rows:,} rows, --threads 1 (best of {runs}, alternated)')
print(f'{"rows":<12} {"defaults":>10} {"--warn-margin 0":>16} {"ratio":>7} {"median ratio":>13}')
for kind in ['trajectory', 'random']:
    base = [cli, 'fk', '--robot', robot, '--joints', f'{work}/{kind}.csv',
            '-o', f'{work}/tips.csv', '--threads', '1', '--on-error', 'mark']
    warn, off = [], []
    for _ in range(runs):
        warn.append(once(base))
        off.append(once(base + ['--warn-margin', '0']))
    med = lambda v: sorted(v)[len(v) // 2]
    print(f'{kind:<12} {min(warn):>9.3f}s {min(off):>15.3f}s {min(warn) / min(off):>6.3f}x'
          f' {med(warn) / med(off):>12.3f}x')
print(f'\nctr-cli fk with the defaults, --threads 2 (best of {runs})')
for kind in ['trajectory', 'random']:
    args = [cli, 'fk', '--robot', robot, '--joints', f'{work}/{kind}.csv',
            '-o', f'{work}/tips.csv', '--threads', '2', '--on-error', 'mark']
    best = min(once(args) for _ in range(runs))
    print(f'{kind:<12} {best:.3f}s  {rows / best:,.0f} rows/s')
EOF

if [ "${CALLGRIND:-1}" != 0 ] && command -v valgrind >/dev/null; then
    head -n $((CG_TRAJ + 1)) "$WORK/trajectory.csv" >"$WORK/cg-trajectory.csv"
    head -n $((CG_RANDOM + 1)) "$WORK/random.csv" >"$WORK/cg-random.csv"
    echo
    echo "instructions (valgrind --tool=callgrind, --threads 1)"
    printf '%-24s %15s %17s %7s\n' rows defaults "--warn-margin 0" ratio
    for kind in trajectory random; do
        count() {
            valgrind --tool=callgrind --callgrind-out-file=/dev/null "$CLI" fk \
                --robot "$ROBOT" --joints "$WORK/cg-$kind.csv" -o "$WORK/tips.csv" \
                --threads 1 --on-error mark "$@" 2>&1 | sed -n 's/.*Collected : //p'
        }
        warn=$(count)
        off=$(count --warn-margin 0)
        n=$(($(wc -l <"$WORK/cg-$kind.csv") - 1))
        python3 -c "import sys; w, o = int(sys.argv[1]), int(sys.argv[2]); print(f'{sys.argv[3] + \" (\" + format(int(sys.argv[4]), \",\") + \")\":<24} {w:>15,} {o:>17,} {w / o:>6.3f}x')" \
            "$warn" "$off" "$kind" "$n"
    done
fi
