#!/usr/bin/env python3
"""Compares the firmware's tips (run-qemu.sh) with the host's and with the reference.

    compare.py FIRMWARE.txt FIRMWARE.elf SHARED_DIR HOST_DIR

FIRMWARE.txt: what the firmware printed over semihosting (`tip <f64|f32> <model> <row>
<x> <y> <z> <qw> <qx> <qy> <qz> <status>` lines, the stack line, `done ...`).
HOST_DIR/<model>.csv: `ctr-cli fk` of the same joints (x_mm,y_mm,z_mm columns).
SHARED_DIR/reference/nitinol3-<model>.csv: the independent simulator's tips.

Prints the tips, the worst differences per table and precision, the stack high-water
mark and the firmware's flash and RAM sizes (from the ELF's section headers), and last
one line: the configurations solved and the largest f64 tip difference from the host, in
mm. Exits 1 when a firmware solve failed, a row is missing, or a difference is over its
bound (F64_BOUND_MM for f64 against the host, F32_BOUND_MM for f32 against the
reference).
"""

import csv
import math
import struct
import sys
from pathlib import Path

ROBOT = "nitinol3"
MODELS = ("rigid", "torsion", "gravity")
# f64 on the microcontroller against f64 on the host: the same arithmetic but for the
# math library (libm against the host's), mm
F64_BOUND_MM = 1e-6
# f32 on the microcontroller against the reference tables (and the host's f64), mm
F32_BOUND_MM = 0.05
# ELF section flag: occupies memory at run time
SHF_ALLOC = 0x2
# ELF section type: no bits in the file (.bss)
SHT_NOBITS = 8


def read_tips(path):
    """{(precision, model): {row: (x, y, z)}} and the other lines of the firmware."""
    tips, other, failures = {}, [], []
    for line in Path(path).read_text().splitlines():
        words = line.split()
        if words[:1] == ["tip"] and len(words) == 12:
            prec, model, row = words[1], words[2], int(words[3])
            tips.setdefault((prec, model), {})[row] = tuple(map(float, words[4:7]))
            if words[11] != "Converged":
                failures.append(line)
        else:
            if words[:1] in (["error"], ["panic:"]):
                failures.append(line)
            other.append(line)
    return tips, other, failures


def read_table(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return [tuple(float(r[k]) for k in ("x_mm", "y_mm", "z_mm")) for r in rows]


def worst(tips, table):
    """Largest distance between the firmware's tips and a table's, and its row."""
    if len(tips) != len(table) or sorted(tips) != list(range(len(table))):
        return math.inf, None
    return max((math.dist(tips[r], table[r]), r) for r in range(len(table)))


def elf_sizes(path):
    """(flash, ram) bytes of a 32-bit little-endian ELF: flash holds every allocated
    section with bits in the file (vector table, code, read-only data, .data's initial
    values), RAM every allocated section at a RAM address (.data, .bss, .uninit); the
    stack comes on top of RAM."""
    data = Path(path).read_bytes()
    if data[:4] != b"\x7fELF" or data[4] != 1 or data[5] != 1:
        sys.exit(f"{path}: not a 32-bit little-endian ELF file")
    shoff, = struct.unpack_from("<I", data, 0x20)
    shentsize, shnum = struct.unpack_from("<HH", data, 0x2E)
    flash = ram = 0
    for i in range(shnum):
        _, kind, flags, addr, _, size = struct.unpack_from("<IIIIII", data, shoff + i * shentsize)
        if not flags & SHF_ALLOC or size == 0:
            continue
        if kind != SHT_NOBITS:
            flash += size
        if addr >= 0x2000_0000:  # memory.x: RAM at 0x20000000
            ram += size
    return flash, ram


def main():
    firmware, elf, shared, host = sys.argv[1:5]
    tips, other, failures = read_tips(firmware)
    for line in other:
        print(f"firmware: {line}")
    bad = list(failures)
    results = {}
    solved = {p: sum(len(t) for k, t in tips.items() if k[0] == p) for p in ("f64", "f32")}
    print(f"{'table':18} {'rows':>5} {'vs host f64, mm':>16} {'vs reference, mm':>17}")
    for prec in ("f64", "f32"):
        for model in MODELS:
            name = f"{prec} {model}"
            ours = tips.get((prec, model), {})
            host_table = read_table(Path(host) / f"{model}.csv")
            ref_table = read_table(Path(shared) / "reference" / f"{ROBOT}-{model}.csv")
            (vs_host, row_h), (vs_ref, _) = worst(ours, host_table), worst(ours, ref_table)
            results[(prec, model)] = (vs_host, vs_ref)
            print(f"{name:18} {len(ours):5} {vs_host:16.3e} {vs_ref:17.3e}")
            if row_h is None:
                bad.append(f"{name}: {len(ours)} rows, the table has {len(host_table)}")
            elif prec == "f64" and vs_host > F64_BOUND_MM:
                bad.append(f"{name}: row {row_h} is {vs_host:.3e} mm from the host (bound {F64_BOUND_MM})")
            elif prec == "f32" and vs_ref > F32_BOUND_MM:
                bad.append(f"{name}: {vs_ref:.3e} mm from the reference (bound {F32_BOUND_MM})")
    flash, ram = elf_sizes(elf)
    print(f"firmware size: flash {flash} bytes, static RAM {ram} bytes (+ the stack)")
    for b in bad:
        print(f"FAIL: {b}")
    f64_host = max(v[0] for k, v in results.items() if k[0] == "f64")
    f32_host = max(v[0] for k, v in results.items() if k[0] == "f32")
    f32_ref = max(v[1] for k, v in results.items() if k[0] == "f32")
    print(
        f"qemu mps2-an386: {solved['f64'] + solved['f32']} configurations solved "
        f"({solved['f64']} f64 + {solved['f32']} f32), "
        f"largest tip difference vs host: f64 {f64_host:.3e} mm (bound {F64_BOUND_MM:g}); "
        f"f32 {f32_host:.3e} mm vs host f64, {f32_ref:.3e} mm vs reference (bound {F32_BOUND_MM:g})"
        + ("" if not bad else f"; {len(bad)} FAILED")
    )
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
