#!/usr/bin/env bash
# Benchmark of `ctr-cli diagnose` (not a timed test):
#
#   bash scripts/bench_diagnose.sh [RECORDING.csv ROBOT.toml ...]
#
# Builds the release binary and times, wall clock, best of RUNS runs, a whole diagnosis
# (read, split, locate, candidate search, acceptance tests, intervals, report) of each
# recording on 2 threads, then prints the worst and median seconds and their ratio to
# `ctr-cli fk` over 1,000,000 rows timed in the same run (machines are noisy: the ratio is
# the figure to compare). Targets (issue 16): a ~1,000-row recording <= 5 s, 10,000 rows
# <= 30 s, worst <= 5 x fk of 1M rows.
# Without arguments it runs the shared recordings (tests/data/shared/recordings, the
# project's copy) with their robots, the bundled example (data/examples/) and the
# generated ones of `cargo run --release -p ctr-diagnosis --example bench_recordings`
# (a 10,000-row recording; ~1,000-row ones whose cause lies outside the vocabulary).
# Environment: RUNS (default 3); CLI (a ctr-cli binary to time instead of building this
# tree's, e.g. an older build for a before/after comparison); OUT (a directory to keep
# each report in, as OUT/<recording>.json, for comparing findings and parameters).
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS=${RUNS:-3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
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
    cargo run --release -q -p ctr-diagnosis --example bench_recordings -- "$work/gen" 2>/dev/null > "$work/gen.txt"
    while read -r rec robot; do pairs+=("$rec" "$robot"); done < "$work/gen.txt"
fi

# best of RUNS wall-clock seconds of a command
best_of() {
    local best= start end t
    for ((r = 0; r < RUNS; r++)); do
        start=$(date +%s.%N)
        # stderr too: fk warns where the random rows come near a snap
        "$@" > /dev/null 2>&1
        end=$(date +%s.%N)
        t=$(echo "$end - $start" | bc)
        if [ -z "$best" ] || (( $(echo "$t < $best" | bc) )); then best=$t; fi
    done
    echo "$best"
}

# the yardstick: fk over 1,000,000 rows of the seed's robot on 2 threads
python3 - "$work/fk1m.csv" <<'EOF'
import random, sys
random.seed(1)
with open(sys.argv[1], "w") as f:
    f.write("s1_mm,theta1_deg,s2_mm,theta2_deg\n")
    for _ in range(1_000_000):
        s1 = random.uniform(20, 70)
        f.write(f"{s1:.4f},{random.uniform(-180, 180):.3f},"
                f"{s1 + random.uniform(25, 95):.4f},{random.uniform(-180, 180):.3f}\n")
EOF
fk=$(best_of "$CLI" fk --robot data/robots/liu2023.toml --joints "$work/fk1m.csv" -o "$work/tips.csv" --threads 2)
printf 'ctr-cli fk, 1,000,000 rows, 2 threads: %.2f s\n\n' "$fk"

printf '%-45s %6s %9s %7s  %s\n' recording rows best_s x_fk1M findings
: > "$work/times.txt"
for ((i = 0; i < ${#pairs[@]}; i += 2)); do
    rec=${pairs[i]}
    robot=${pairs[i + 1]}
    rows=$(($(wc -l < "$rec") - 1))
    report=$work/report.json
    best=$(best_of "$CLI" diagnose --robot "$robot" --recording "$rec" --threads 2 --report "$report")
    [ -n "${OUT:-}" ] && mkdir -p "$OUT" && cp "$report" "$OUT/$(basename "$rec" .csv).json"
    found=$(python3 -c "import json,sys; r=json.load(open(sys.argv[1])); print(','.join(f['effect'] for f in r['findings']) or '-', 'explained' if r.get('explained') else 'unexplained')" "$report")
    printf '%-45s %6d %9.2f %7.2f  %s\n' "$(basename "$rec")" "$rows" "$best" "$(echo "$best / $fk" | bc -l)" "$found"
    echo "$rows $best" >> "$work/times.txt"
done

python3 - "$work/times.txt" "$fk" <<'EOF'
import statistics, sys
rows_times = [tuple(map(float, l.split())) for l in open(sys.argv[1]) if l.strip()]
fk = float(sys.argv[2])
small = [t for n, t in rows_times if n <= 2000]
large = [t for n, t in rows_times if n > 2000]
every = [t for _, t in rows_times]
print()
print(f"~1,000-row recordings: worst {max(small):.2f} s, median {statistics.median(small):.2f} s (target <= 5 s)")
if large:
    print(f"10,000-row recordings: worst {max(large):.2f} s (target <= 30 s)")
print(f"worst / fk of 1M rows: {max(small) / fk:.2f} x for ~1,000 rows, {max(every) / fk:.2f} x over all (target <= 5 x)")
EOF
