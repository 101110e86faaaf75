#!/usr/bin/env bash
# The re-framing proof on a recording (issue 40): the recording diagnosed as it is,
# then transformed so that the true change to the model is exact and diagnosed again
# (a turned tracker, a moved encoder zero, commands shifted in time, glitches, runs
# reordered, rows thinned; ctr_diagnosis::synth::Reframe), one Markdown line per
# transformation: what was recovered against the truth, the grade of the effect
# changed, the held-out RMS against the unmodified diagnosis's and whether the other
# findings held.
#
#   bash scripts/reframe.sh ROBOT.toml REC.csv [--holdout SPLIT] [--draws N] [--seed S] [--fixed]
#
# --fixed runs issue 40's four transformations first; --draws (default 20) seeded draws
# of the family follow. Hold whole runs out (--holdout runs:LABEL) for a split that does
# not move when the runs are reordered. The public real recording (docs/real-robots.md)
# is run this way for the guide's table; it is not kept in the repository.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ $# -lt 2 ]; then
    sed -n '2,16p' "$0" >&2
    exit 2
fi
robot=$(realpath "$1")
rec=$(realpath "$2")
shift 2
cargo build --release -q -p ctr-diagnosis --example reframe
exec target/release/examples/reframe "$robot" "$rec" --threads 2 "$@"
