#!/usr/bin/env bash
# Benchmark of `ctr-cli diagnose` (not a timed test):
#
#   bash scripts/bench_diagnose.sh [RECORDING.csv ROBOT.toml ...]
#
# Builds the release binary and times, wall clock, best of RUNS runs, a whole diagnosis
# (read, split, locate, all ten candidates fitted in every round, report) of each
# recording on 2 threads. Target: a 1,000-row recording in <= 5 s on 2 cores. Without
# arguments it runs the shared recordings (tests/data/shared/recordings, the project's copy) with their robots
# and the bundled example (data/examples/liu2023-recording.csv).
# Environment: RUNS (default 3); CLI (a ctr-cli binary to time instead of building
# this tree's, e.g. an older build for a before/after comparison).
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS=${RUNS:-3}
if [ -z "${CLI:-}" ]; then
    cargo build --release -p ctr-cli 2>&1 | tail -n 1 >&2
    CLI=$PWD/target/release/ctr-cli
fi

pairs=("$@")
if [ ${#pairs[@]} -eq 0 ]; then
    S=${CTR_SHARED_DATA:-tests/data/shared}
    for id in clean clearance friction gravity latency registration unexplained-feed-gain unexplained-drift; do
        f=$S/recordings/dev-$id.csv
        [ -f "$f" ] || continue
        robot=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['robot_file'].replace('shared/data/', ''))" "$S/recordings/dev-$id.truth.json")
        pairs+=("$f" "$S/$robot")
    done
    [ -f data/examples/liu2023-recording.csv ] && pairs+=(data/examples/liu2023-recording.csv data/robots/liu2023.toml)
fi

printf '%-45s %6s %9s  %s\n' recording rows best_s findings
for ((i = 0; i < ${#pairs[@]}; i += 2)); do
    rec=${pairs[i]}
    robot=${pairs[i + 1]}
    rows=$(($(wc -l < "$rec") - 1))
    best=
    for ((r = 0; r < RUNS; r++)); do
        start=$(date +%s.%N)
        "$CLI" diagnose --robot "$robot" --recording "$rec" --threads 2 --report /tmp/ctr-bench-report.json > /dev/null
        end=$(date +%s.%N)
        t=$(echo "$end - $start" | bc)
        if [ -z "$best" ] || (( $(echo "$t < $best" | bc) )); then best=$t; fi
    done
    found=$(python3 -c "import json; print(','.join(f['effect'] for f in json.load(open('/tmp/ctr-bench-report.json'))['findings']) or '-')")
    printf '%-45s %6d %9.2f  %s\n' "$(basename "$rec")" "$rows" "$best" "$found"
done
