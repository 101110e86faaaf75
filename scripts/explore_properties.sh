#!/usr/bin/env bash
# Explores the property tests beyond CI's cases. CI (and a plain `cargo test`) draws
# every property's cases from one fixed seed (tests/support/props.rs): the same cases
# every run. This script runs the same properties with fresh seeds and many more cases,
# to find what CI's cases miss:
#
#   scripts/explore_properties.sh                  # every suite, 5000 cases, one seed
#   PROPTEST_CASES=20000 scripts/explore_properties.sh core ik
#   ROUNDS=3 scripts/explore_properties.sh formats hw
#   PYTHON=venv/bin/python scripts/explore_properties.sh python
#
# Suites: core (ctr-core's properties), ik (the IK's), formats (the parser fuzzers),
# hw (the Dynamixel frame fuzzers), python (the hypothesis tests of ctr_py: needs
# PYTHON, an interpreter with ctr_py, hypothesis and pytest installed; skipped without).
# Default: all. PROPTEST_CASES sets the cases per property (default 5000; ctr-core's at
# 5000 take about a minute on 2 cores, the IK's about 4), ROUNDS the fresh seeds per
# suite (default 1), HYPOTHESIS_MAX_EXAMPLES the Python examples per test (default
# 2000).
#
# A property that fails appends its shrunk case to its regression file,
# `proptest-regressions/<test file>/<property>.txt` beside the test: commit it (with the
# fix, or the property restated), and every run, CI's included, replays it. The
# failure names the seed: `PROPTEST_RNG_SEED=<seed> PROPTEST_CASES=<n> cargo test
# --release -p <crate> --test <test>` runs the same cases again. A Python failure prints
# its falsifying example: keep it as an `@example` of its test.
#
# Exit status 1 when any property failed.
set -uo pipefail
cd "$(dirname "$0")/.."

cases="${PROPTEST_CASES:-5000}"
rounds="${ROUNDS:-1}"
examples="${HYPOTHESIS_MAX_EXAMPLES:-2000}"
suites=("$@")
[ ${#suites[@]} -eq 0 ] && suites=(core ik formats hw python)

# suite -> "crate test"
rust_suite() {
    case "$1" in
        core) echo "ctr-core properties" ;;
        ik) echo "ctr-analysis ik_properties" ;;
        formats) echo "ctr-formats fuzz_parsers" ;;
        hw) echo "ctr-hw fuzz_frames" ;;
        *) return 1 ;;
    esac
}

for s in "${suites[@]}"; do
    if [ "$s" != python ] && ! rust_suite "$s" >/dev/null; then
        echo "unknown suite '$s' (core, ik, formats, hw, python)" >&2
        exit 2
    fi
done

failed=()
log_dir="$(mktemp -d)"
for s in "${suites[@]}"; do
    for round in $(seq 1 "$rounds"); do
        seed="$(od -An -N8 -tu8 /dev/urandom | tr -d ' ')"
        if [ "$s" = python ]; then
            if [ -z "${PYTHON:-}" ] || ! "$PYTHON" -c "import ctr_py, hypothesis, pytest" 2>/dev/null; then
                echo "==> python: skipped (set PYTHON to an interpreter with ctr_py, hypothesis and pytest)"
                break
            fi
            echo "==> python, hypothesis seed $seed, $examples examples per test"
            if ! HYPOTHESIS_PROFILE=explore HYPOTHESIS_MAX_EXAMPLES="$examples" \
                "$PYTHON" -m pytest -c crates/ctr-py/pyproject.toml -q -p no:cacheprovider \
                --hypothesis-seed="$seed" tests/python/test_properties.py; then
                failed+=("python (--hypothesis-seed=$seed)")
            fi
            continue
        fi
        read -r crate test <<<"$(rust_suite "$s")"
        log="$log_dir/$s-$round.log"
        echo "==> $s ($crate --test $test), seed $seed, $cases cases per property"
        start=$SECONDS
        if PROPTEST_RNG_SEED="$seed" PROPTEST_CASES="$cases" \
            cargo test --release --locked -q -p "$crate" --test "$test" >"$log" 2>&1; then
            echo "    passed in $((SECONDS - start)) s"
        else
            echo "    FAILED in $((SECONDS - start)) s:"
            grep -E "^property |^cc |^test result|^error" "$log" | sed 's/^/    /' | cut -c1-400
            failed+=("$s (PROPTEST_RNG_SEED=$seed PROPTEST_CASES=$cases)")
        fi
    done
done

echo
if [ ${#failed[@]} -eq 0 ]; then
    echo "explore: every property passed"
    rm -rf "$log_dir"
    exit 0
fi
echo "explore: failures in ${failed[*]}"
echo "full logs in $log_dir; the cases found were appended to:"
git status --short -- '*proptest-regressions*' | sed 's/^/    /'
exit 1
