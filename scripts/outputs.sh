#!/usr/bin/env bash
# Writes the project's public outputs on the bundled examples (and on the shared
# reference data, tests/data/shared or $CTR_SHARED_DATA) into one directory, so that two
# versions of the code can be compared file by file with scripts/compare_outputs.py:
#
#   bash scripts/outputs.sh /tmp/before          # on the old commit
#   bash scripts/outputs.sh /tmp/after           # on the new one
#   python3 scripts/compare_outputs.py /tmp/before /tmp/after
#
# What it writes: `ctr-cli fk` tips (every robot, both models, with every effect table,
# time effects along runs), `ctr-cli ik` joints (positions and poses, warm and cold),
# `ctr-cli diagnose` reports, fitted robot files, summaries and plots' SVGs,
# `calibrate` and `evaluate`, and, when the `ctr_py` wheel is importable by $PYTHON
# (default python3), the Python results of scripts/outputs.py.
# Environment: CTR_SHARED_DATA (default tests/data/shared, the project's copy), PYTHON, THREADS (default 2).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: outputs.sh OUT_DIR}
mkdir -p "$out"
out=$(cd "$out" && pwd)
shared=${CTR_SHARED_DATA:-tests/data/shared}
threads=${THREADS:-2}
cargo build --release -p ctr-cli 2>&1 | tail -n 1 >&2
cli=$PWD/target/release/ctr-cli
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# a command's stdout, stderr and exit status, all three part of the output
run() {
    local name=$1
    shift
    local status=0
    "$@" > "$out/$name.stdout" 2> "$out/$name.stderr" || status=$?
    echo "$status" > "$out/$name.status"
    # paths of this run's temporary and output directories differ from run to run
    sed -i -e "s|$tmp/||g" -e "s|$out/||g" "$out/$name.stdout" "$out/$name.stderr"
}

# robot files with effect tables: the bundled robots plus one [model.effects] each
robots=(data/robots/liu2023.toml data/robots/nitinol2.toml data/robots/nitinol3.toml)
with_effects() { # name base.toml effects...
    local name=$1 base=$2
    shift 2
    { cat "$base"; printf '\n[model.effects]\n'; printf '%s\n' "$@"; } > "$tmp/$name.toml"
    echo "$tmp/$name.toml"
}
density() { # base.toml -> same with density_kg_m3 on every tube that lacks one
    if grep -q '^density_kg_m3' "$1"; then cat "$1"; else
        sed 's/^\(poisson_ratio.*\)$/\1\ndensity_kg_m3 = 6450.0/' "$1"
    fi
}
# the joint (and t_s, run) columns of a CSV: reference tables and recordings carry tips
joints_only() { # in.csv out.csv
    python3 - "$1" "$2" <<'PY'
import csv, re, sys
rows = list(csv.reader(open(sys.argv[1])))
keep = [i for i, h in enumerate(rows[0]) if re.fullmatch(r"(s|theta)\d+_(mm|deg)|t_s|run|label", h)]
csv.writer(open(sys.argv[2], "w", newline=""), lineterminator="\n").writerows([[r[i] for i in keep] for r in rows])
PY
}
density data/robots/nitinol3.toml > "$tmp/nitinol3-dense.toml"
density data/robots/liu2023.toml > "$tmp/liu2023-dense.toml"
effect_robots=(
    "$(with_effects offsets data/robots/liu2023.toml 'joint_offset = { feed_mm = [0.5, -0.3], rotation_deg = [2.0, -3.0] }')"
    "$(with_effects clearance data/robots/liu2023.toml 'clearance = { max_deflection_deg = [2.5], peak_deg = [205.0] }')"
    "$(with_effects registration data/robots/nitinol3.toml 'registration = { translation_mm = [3.0, -2.0, 5.0], rotation_axis = [0.3, 0.9, 0.3], rotation_deg = 2.0 }' 'sensor_offset = { offset_mm = [0.5, 0.0, 2.0] }')"
    "$(with_effects scaled data/robots/nitinol3.toml 'stiffness = { factor = [1.0, 0.8, 1.2] }' 'precurvature = { radius_factor = [1.0, 1.1, 0.9] }')"
    "$(with_effects gravity "$tmp/nitinol3-dense.toml" 'gravity = { direction_W = [-1.0, 0.0, 0.0], g_m_s2 = 9.81 }')"
    "$(with_effects gravity-offsets "$tmp/liu2023-dense.toml" 'gravity = { direction_W = [0.0, -1.0, 0.0] }' 'joint_offset = { feed_mm = [0.2, 0.1], rotation_deg = [1.0, -1.0] }' 'registration = { translation_mm = [1.0, 0.0, 0.0] }')"
    "$(with_effects time data/robots/liu2023.toml 'latency = { tau_s = 0.3 }' 'friction = { rotation_play_deg = [4.0] }' 'joint_offset = { feed_mm = [0.0, 0.5], rotation_deg = [0.0, 1.0] }')"
)

# joints: the bundled file and, where present, the reference tables (their tips ride along)
joint_files=(data/examples/liu2023-joints.csv)
for r in liu2023 nitinol2 nitinol3; do
    if [ -f "$shared/reference/$r-torsion.csv" ]; then
        joints_only "$shared/reference/$r-torsion.csv" "$tmp/$r-reference.csv"
        joint_files+=("$tmp/$r-reference.csv")
    fi
done
joints_only data/examples/liu2023-recording.csv "$tmp/liu2023-recording-joints.csv"
tubes_of() { grep -c '^\[\[tube\]\]' "$1"; }
joints_for() { # robot.toml -> joint files with its tube count
    local n
    n=$(tubes_of "$1")
    for j in "${joint_files[@]}"; do
        if head -n 1 "$j" | grep -q "s${n}_mm" && ! head -n 1 "$j" | grep -q "s$((n + 1))_mm"; then
            echo "$j"
        fi
    done
}

for robot in "${robots[@]}" "${effect_robots[@]}"; do
    rname=$(basename "$robot" .toml)
    for joints in $(joints_for "$robot"); do
        jname=$(basename "$joints" .csv)
        for model in rigid torsion; do
            if grep -q '^gravity' "$robot" && [ $model = rigid ]; then continue; fi
            if grep -q '^latency' "$robot"; then continue; fi
            run "fk-$rname-$jname-$model" "$cli" fk --robot "$robot" --joints "$joints" --model $model \
                --threads "$threads" --on-error mark -o "$out/fk-$rname-$jname-$model.csv"
        done
    done
done
# time effects along runs: a recording is a joint file with t_s and run
run fk-time-recording "$cli" fk --robot "${effect_robots[6]}" --joints "$tmp/liu2023-recording-joints.csv" \
    --threads "$threads" --on-error mark -o "$out/fk-time-recording.csv"

# inverse kinematics: positions, poses (targets made by fk), warm and cold
poses3=$(joints_for data/robots/nitinol3.toml | tail -n 1)
if [ -n "$poses3" ]; then
    "$cli" fk --robot data/robots/nitinol3.toml --joints "$poses3" -o "$tmp/poses3.csv"
    # the targets: the tips only (the joints would be carried along)
    python3 -c "import csv,sys; r=list(csv.reader(open(sys.argv[1]))); k=[i for i,h in enumerate(r[0]) if h in ('x_mm','y_mm','z_mm','qw','qx','qy','qz')]; csv.writer(open(sys.argv[2],'w',newline=''),lineterminator='\n').writerows([[x[i] for i in k] for x in r[:41]])" "$tmp/poses3.csv" "$tmp/poses3-40.csv"
fi
run ik-liu2023 "$cli" ik --robot data/robots/liu2023.toml --targets data/examples/liu2023-targets.csv \
    --threads "$threads" -o "$out/ik-liu2023.csv"
run ik-liu2023-cold "$cli" ik --robot data/robots/liu2023.toml --targets data/examples/liu2023-targets.csv \
    --cold --threads "$threads" -o "$out/ik-liu2023-cold.csv"
run ik-clearance "$cli" ik --robot "${effect_robots[1]}" --targets data/examples/liu2023-targets.csv \
    --threads "$threads" -o "$out/ik-clearance.csv"
run ik-registration-pose "$cli" ik --robot "${effect_robots[2]}" --targets "$tmp/poses3-40.csv" \
    --threads "$threads" -o "$out/ik-registration-pose.csv"
run ik-nitinol3-pose "$cli" ik --robot data/robots/nitinol3.toml --targets "$tmp/poses3-40.csv" \
    --threads "$threads" -o "$out/ik-nitinol3-pose.csv"
run ik-gravity "$cli" ik --robot "${effect_robots[5]}" --targets data/examples/liu2023-targets.csv \
    --threads "$threads" -o "$out/ik-gravity.csv"

# diagnosis, calibration, evaluation
diagnose() { # name robot recording
    local name=$1 robot=$2 rec=$3
    run "diagnose-$name" "$cli" diagnose --robot "$robot" --recording "$rec" --threads "$threads" \
        --report "$out/diagnose-$name.json" --out "$out/diagnose-$name.toml" --plots "$out/diagnose-$name-plots"
}
diagnose example data/robots/liu2023.toml data/examples/liu2023-recording.csv
if [ -d "$shared/recordings" ]; then
    for truth in "$shared"/recordings/*.truth.json; do
        id=$(basename "$truth" .truth.json)
        robot=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['robot_file'].replace('shared/data/', ''))" "$truth")
        diagnose "$id" "$shared/$robot" "$shared/recordings/$id.csv"
    done
    run calibrate-clearance "$cli" calibrate --robot "$shared/robots/liu2023.toml" \
        --recording "$shared/recordings/dev-clearance.csv" --fit clearance --table 24 \
        --report "$out/calibrate-clearance.json" --out "$out/calibrate-clearance.toml"
    run evaluate "$cli" evaluate --robot "$shared/robots/liu2023.toml" --robot "$out/diagnose-dev-clearance.toml" \
        --recording "$shared/recordings/dev-clearance.csv"
fi

# Python results, where the wheel is installed
py=${PYTHON:-python3}
if "$py" -c 'import ctr_py' 2> /dev/null; then
    "$py" scripts/outputs.py "$out/python" "$shared"
else
    echo "outputs.sh: ctr_py is not importable by $py: Python results skipped" >&2
fi
ls "$out" | wc -l | xargs echo "outputs.sh: files written:" >&2
