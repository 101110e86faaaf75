"""Compares two directories written by scripts/outputs.sh (before and after a change).

    python3 scripts/compare_outputs.py BEFORE AFTER [--tolerance REL]

Every file is compared byte for byte. Where two files differ, they are compared again
token by token: text must match exactly, numbers may differ by at most REL relative to
the larger magnitude (default 0: report only). Prints one line per file that is
missing, differs in text, or differs in numbers (with the largest absolute and
relative difference and where), then a summary line. Exit status 0 when every file
is byte-identical or within the tolerance, 1 otherwise.
"""

import argparse
import math
import re
import sys
from pathlib import Path

NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|NaN|-?inf")


def tokens(text: str):
    """Splits text into (kind, value) tokens: numbers as floats, everything else as
    text runs."""
    out = []
    pos = 0
    for m in NUMBER.finditer(text):
        if m.start() > pos:
            out.append(("t", text[pos : m.start()]))
        out.append(("n", float(m.group())))
        pos = m.end()
    if pos < len(text):
        out.append(("t", text[pos:]))
    return out


def compare(a: bytes, b: bytes):
    """None if the token streams differ in text or length, else (max abs, max rel,
    token index of the max rel)."""
    try:
        ta, tb = tokens(a.decode()), tokens(b.decode())
    except UnicodeDecodeError:
        return None
    if len(ta) != len(tb):
        return None
    worst = (0.0, 0.0, -1)
    for i, ((ka, va), (kb, vb)) in enumerate(zip(ta, tb)):
        if ka != kb:
            return None
        if ka == "t":
            if va != vb:
                return None
            continue
        if va == vb or (math.isnan(va) and math.isnan(vb)):
            continue
        d = abs(va - vb)
        rel = d / max(abs(va), abs(vb))
        if rel > worst[1]:
            worst = (max(worst[0], d), rel, i)
        else:
            worst = (max(worst[0], d), worst[1], worst[2])
    return worst


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    ap.add_argument("--tolerance", type=float, default=0.0)
    args = ap.parse_args()
    names = sorted(
        {p.relative_to(args.before) for p in args.before.rglob("*") if p.is_file()}
        | {p.relative_to(args.after) for p in args.after.rglob("*") if p.is_file()}
    )
    same = differ = 0
    ok = True
    for name in names:
        a, b = args.before / name, args.after / name
        if not a.exists() or not b.exists():
            print(f"missing in {'before' if not a.exists() else 'after'}: {name}")
            ok = False
            continue
        x, y = a.read_bytes(), b.read_bytes()
        if x == y:
            same += 1
            continue
        differ += 1
        c = compare(x, y)
        if c is None:
            print(f"text differs: {name}")
            ok = False
            continue
        abs_d, rel_d, _ = c
        within = rel_d <= args.tolerance
        ok &= within
        print(f"numbers differ: {name}: max abs {abs_d:.3g}, max rel {rel_d:.3g}")
    print(f"{same} identical, {differ} differ, {len(names)} files")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
