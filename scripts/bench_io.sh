#!/usr/bin/env bash
# Benchmark of ctr-cli fk's reading and writing, whole commands side by side in one run
# (not a timed test):
#
#   bash scripts/bench_io.sh                 # 1M rows; RUNS=3 best of; BIG=1 adds 10M
#
# Builds the release binary, generates a joint file of a smooth nitinol3 trajectory
# (scripts/bench.sh's: a slow motion sampled at 1 kHz, a text label) as CSV and, with
# pyarrow, as Parquet, and prints:
#
#   1. rows/s of `fk` on 1 and 2 threads, with the default snap warning and with
#      `--warn-margin 0`, CSV in and out and Parquet in and out (best of RUNS, wall
#      clock, whole command; every output removed before its run, so that no run pays
#      for freeing the previous run's output);
#   2. where the time goes (`fk --profile`, CSV, --warn-margin 0): setting up, the
#      reader, the workers, the writer, finishing; wall and CPU seconds; the part that
#      does not shrink with threads as a share of the 1-thread time, and Amdahl's
#      prediction for 16 threads;
#   3. peak resident memory (/usr/bin/time -v) of Parquet in and out for 1M and 3M rows
#      (and 10M with BIG=1): it does not grow with the rows.
#
# Needs python3 (the generator), and pyarrow for the Parquet rows (skipped without).
# Environment: RUNS (default 3), ROWS (default 1000000), KEEP=1 keeps the work directory.
set -euo pipefail
cd "$(dirname "$0")/.."

RUNS=${RUNS:-3}
ROWS=${ROWS:-1000000}
ROBOT=tests/data/shared/robots/nitinol3.toml

cargo build --release -p ctr-cli 2>&1 | tail -n 1 >&2
CLI=$PWD/target/release/ctr-cli
WORK=$(mktemp -d "${TMPDIR:-/tmp}/ctr-bench-io.XXXXXX")
if [ "${KEEP:-0}" = 1 ]; then echo "work directory: $WORK" >&2; else trap 'rm -rf "$WORK"' EXIT; fi

echo "generating joint files ..." >&2
python3 - "$WORK" "$ROWS" "${BIG:-0}" <<'EOF'
import sys
sys.path.insert(0, 'scripts')
from bench_joints import COLUMNS as header, trajectory, write_csv
work, rows, big = sys.argv[1], int(sys.argv[2]), sys.argv[3] == "1"

def rows_of(n):
    # 1 kHz samples of a motion with a 20 s period, as scripts/bench.sh's
    return enumerate(trajectory(n, n / 20000, 170.0))

write_csv(f'{work}/joints.csv', trajectory(rows, rows / 20000, 170.0))
try:
    import pyarrow as pa, pyarrow.parquet as pq
except ImportError:
    sys.exit(0)
chunk = 500_000
for name, n in [('joints', rows), ('joints-3x', 3 * rows)] + ([('joints-10x', 10 * rows)] if big else []):
    schema = pa.schema([('label', pa.string())] + [(c, pa.float64()) for c in header[1:]])
    with pq.ParquetWriter(f'{work}/{name}.parquet', schema) as w:
        batch = []
        for k, row in rows_of(n):
            batch.append((f'r{k}', row))
            if len(batch) == chunk or k == n - 1:
                cols = {'label': [b[0] for b in batch]}
                for j, c in enumerate(header[1:]):
                    cols[c] = [b[1][j] for b in batch]
                w.write_table(pa.table(cols, schema=schema))
                batch = []
EOF

echo "timing ($RUNS runs each) ..." >&2
python3 - "$CLI" "$ROBOT" "$WORK" "$RUNS" "$ROWS" <<'EOF'
import os, re, subprocess, sys, time
cli, robot, work, runs, rows = sys.argv[1:6]
runs, rows = int(runs), int(rows)

def run(args, out):
    if os.path.exists(out):
        os.remove(out)
    t0 = time.perf_counter()
    p = subprocess.run(args + ['-o', out], capture_output=True, text=True)
    dt = time.perf_counter() - t0
    if p.returncode != 0:
        sys.exit(f'{" ".join(args)}: exit {p.returncode}: {p.stderr}')
    return dt, p.stderr

def best(args, out):
    return min(run(args, out)[0] for _ in range(runs))

fk = [cli, 'fk', '--robot', robot]
parquet = os.path.exists(f'{work}/joints.parquet')
print(f'fk of {rows:,} rows of a smooth nitinol3 trajectory; {os.cpu_count()} cores; '
      f'best of {runs}, wall clock, whole command')
print()
print('| files | threads | default warning | --warn-margin 0 |')
print('|---|---|---|---|')
for kind, ext in [('CSV in and out', 'csv')] + ([('Parquet in and out', 'parquet')] if parquet else []):
    for threads in ['1', '2']:
        cells = []
        for warn in [[], ['--warn-margin', '0']]:
            b = best(fk + ['--joints', f'{work}/joints.{ext}', '--threads', threads] + warn,
                     f'{work}/tips.{ext}')
            cells.append(f'{rows / b:,.0f} rows/s ({b:.2f} s)')
        print(f'| {kind} | {threads} | ' + ' | '.join(cells) + ' |')

# where the time goes
print()
profiles = {}
for threads in ['1', '2']:
    best_wall, best_text = None, ''
    for _ in range(runs):
        _, err = run(fk + ['--joints', f'{work}/joints.csv', '--threads', threads,
                           '--warn-margin', '0', '--profile'], f'{work}/tips.csv')
        wall = float(re.search(r'wall ([\d.]+) s', err).group(1))
        if best_wall is None or wall < best_wall:
            best_wall, best_text = wall, err
    profiles[threads] = best_text
    print('```')
    print(best_text.strip())
    print('```')

def stage(text, name):
    line = next(l for l in text.splitlines() if name in l)
    nums = re.findall(r'(\d+\.\d+|-)\s*', line.split(')')[-1])
    wall = float(nums[0])
    cpu = float(nums[1]) if len(nums) > 1 and nums[1] != '-' else None
    return wall, cpu

p1, p2 = profiles['1'], profiles['2']
t1 = float(re.search(r'wall ([\d.]+) s', p1).group(1))
setup, finish = stage(p1, 'setting up')[0], stage(p1, 'finishing')[0]
work_cpu = stage(p2, 'workers')[1]
reader_cpu, writer_cpu = stage(p2, 'reader')[1], stage(p2, 'writer')[1]
serial = setup + finish
print()
print(f'1 thread: {t1:.3f} s. Does not shrink with threads (setting up + finishing): '
      f'{serial:.3f} s = {100 * serial / t1:.1f} % of it.')
print(f'Serial stages beside the workers (2 threads, CPU): reader {reader_cpu:.3f} s, '
      f'writer {writer_cpu:.3f} s = {100 * max(reader_cpu, writer_cpu) / t1:.1f} % of the '
      f'1-thread time: the floor no thread count goes below.')
for n in [2, 16]:
    t = serial + work_cpu / n
    print(f'Amdahl, {n} threads: {serial:.3f} + {work_cpu:.3f} / {n} = {t:.3f} s '
          f'({t1 / t:.1f}x); the reader and writer keep up when {work_cpu / n:.3f} s >= '
          f'{max(reader_cpu, writer_cpu):.3f} s')
EOF

if [ -f "$WORK/joints.parquet" ]; then
    echo
    echo "| Parquet in and out, 2 threads | wall | peak RSS |"
    echo "|---|---|---|"
    for name in joints joints-3x joints-10x; do
        [ -f "$WORK/$name.parquet" ] || continue
        rm -f "$WORK/tips.parquet"
        /usr/bin/time -v "$CLI" fk --robot "$ROBOT" --joints "$WORK/$name.parquet" \
            -o "$WORK/tips.parquet" --threads 2 --warn-margin 0 2>"$WORK/time.txt"
        n=$(python3 -c "import pyarrow.parquet as pq; print(f'{pq.ParquetFile(\"$WORK/$name.parquet\").metadata.num_rows:,}')")
        wall=$(grep 'Elapsed' "$WORK/time.txt" | awk '{print $NF}')
        rss=$(grep 'Maximum resident' "$WORK/time.txt" | awk '{printf "%.0f MB", $NF / 1024}')
        echo "| $n rows | $wall | $rss |"
    done
fi
