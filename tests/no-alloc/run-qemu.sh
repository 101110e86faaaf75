#!/usr/bin/env bash
# Runs the firmware check on a microcontroller: builds this crate for the Cortex-M4F
# (thumbv7em-none-eabihf), runs it on QEMU's mps2-an386 board (qemu-system-arm, output
# over semihosting), where it solves the shared reference configurations of the 3-tube
# robot nitinol3 (rigid, torsion and gravity tables, in f64 and in f32); solves the same
# configurations on the host with ctr-cli fk; and compares (compare.py). The last line
# gives the configurations solved and the largest tip difference from the host in mm.
#
#   tests/no-alloc/run-qemu.sh        # exit 1 if a solve failed or a bound is broken
#
# CTR_CLI: the host's ctr-cli (default target/release/ctr-cli, built if missing);
# CTR_SHARED_DATA: the shared data (default tests/data/shared); QEMU_TIMEOUT_S: how long
# the firmware may run (default 120 s; it takes about 5 s).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
shared="${CTR_SHARED_DATA:-$root/tests/data/shared}"
robot="nitinol3"

command -v qemu-system-arm >/dev/null || {
    echo "run-qemu.sh: qemu-system-arm not found (Debian: apt-get install qemu-system-arm)" >&2
    exit 2
}
(cd "$here" && cargo build --locked --release --target thumbv7em-none-eabihf)
elf="$here/target/thumbv7em-none-eabihf/release/ctr-no-alloc"
cli="${CTR_CLI:-$root/target/release/ctr-cli}"
if [ -z "${CTR_CLI:-}" ] && [ ! -x "$cli" ]; then
    (cd "$root" && cargo build --locked --release -p ctr-cli)
fi

tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

# the firmware: semihosting output to stdout; its exit status is the firmware's
timeout "${QEMU_TIMEOUT_S:-120}" qemu-system-arm -machine mps2-an386 -cpu cortex-m4 \
    -nographic -monitor none -serial none \
    -semihosting-config enable=on,target=native \
    -kernel "$elf" >"$tmp/firmware.txt" || {
    status=$?
    cat "$tmp/firmware.txt"
    echo "run-qemu.sh: the firmware failed (exit status $status; 124: timed out)" >&2
    exit 1
}

# the host: the same joints through ctr-cli fk (gravity as manifest.json's gravity_model,
# the firmware's reference::GRAVITY_* constants)
cp "$shared/robots/$robot.toml" "$tmp/robot.toml"
{
    cat "$shared/robots/$robot.toml"
    printf '\n[model.effects]\ngravity = { direction_W = [-1.0, 0.0, 0.0], g_m_s2 = 9.81 }\n'
} >"$tmp/robot-gravity.toml"
for model in rigid torsion gravity; do
    # the joint columns only: the reference's tip columns would clash with the output's
    cut -d, -f1-6 "$shared/reference/$robot-$model.csv" >"$tmp/joints-$model.csv"
    if [ "$(head -n 1 "$tmp/joints-$model.csv")" != "s1_mm,theta1_deg,s2_mm,theta2_deg,s3_mm,theta3_deg" ]; then
        echo "run-qemu.sh: $shared/reference/$robot-$model.csv: the joint columns are not first" >&2
        exit 2
    fi
    file="$tmp/robot.toml" kind="$model"
    if [ "$model" = gravity ]; then file="$tmp/robot-gravity.toml" kind=torsion; fi
    "$cli" fk --robot "$file" --joints "$tmp/joints-$model.csv" --model "$kind" \
        -o "$tmp/$model.csv"
done

grep -m 3 '^tip ' "$tmp/firmware.txt"
echo "... ($(grep -c '^tip ' "$tmp/firmware.txt") tip lines)"
python3 "$here/compare.py" "$tmp/firmware.txt" "$elf" "$shared" "$tmp"
