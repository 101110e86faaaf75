#!/usr/bin/env python3
"""The house rules of crates/*/src: no import cycles between the files of a crate, no
source file longer than MAX_LINES lines before its `#[cfg(test)]` module, and no
function longer than MAX_FN_LINES lines (signature to closing brace, before the file's
test module), save at most MAX_LONG_FNS whose line before the signature holds a
`// house: long because ...` comment saying why splitting would hurt reading, and none
of those longer than HARD_FN_LINES.

    python3 scripts/check_house.py         # exit 1 and print what breaks a rule

A file depends on another when it names a module path into it (`use crate::a::B`,
`super::b::c(...)`, a serde `with = "super::b::f"`, ...). A name that a module file
only re-exports (`pub use x::Name` in lib.rs or a mod.rs) counts as the file that
defines it, so a re-export is not a dependency on the re-exporting file. `mod x;`
declarations and test modules (after a top-level `#[cfg(test)]`) do not count.
Crate-level cycles are Cargo's to refuse.
"""

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# Longest source file, lines before its test module.
MAX_LINES = 700
# Longest function, lines.
MAX_FN_LINES = 100
# Functions allowed over MAX_FN_LINES with a `// house: long because` comment, and
# the length none may pass.
MAX_LONG_FNS = 3
HARD_FN_LINES = 150
FN = re.compile(
    r'^\s*(?:pub(?:\([^)]*\))?\s+)?(?:const\s+)?(?:unsafe\s+)?(?:extern\s+"C"\s+)?fn\s+(\w+)'
)
LONG_BECAUSE = "// house: long because"
PATH = re.compile(r"\b(crate|super|self)((?:::(?:\w+|\{[^;]*?\}))+)")
REEXPORT = re.compile(r"pub(?:\([\w:]+\))?\s+use\s+([\w:]+)::\{?([^;]*?)\}?;", re.S)


def module_of(src: Path, f: Path) -> tuple:
    rel = f.relative_to(src).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] in ("lib", "main", "mod"):
        parts = parts[:-1]
    return tuple(parts)


def code_of(f: Path) -> str:
    text = f.read_text()
    cut = re.search(r"^#\[cfg\(test\)\]", text, re.M)
    text = text[: cut.start()] if cut else text
    # comments (doc examples name public paths from outside the crate)
    return re.sub(r"//[^\n]*", "", text)


def expand(tail: str) -> list:
    """`::a::{b, c::d}` -> [[a, b], [a, c, d]] (nested braces included)."""
    tail = tail.strip()
    if tail.startswith("::"):
        tail = tail[2:]
    m = re.match(r"([\w:]*?)(?:::)?\{(.*)\}$", tail, re.S)
    if not m:
        return [[p for p in tail.split("::") if p]]
    head = [p for p in m.group(1).split("::") if p]
    out, depth, cur = [], 0, ""
    for ch in m.group(2) + ",":
        if ch == "," and depth == 0:
            if cur.strip():
                out += [head + sub for sub in expand(cur)]
            cur = ""
            continue
        depth += ch == "{"
        depth -= ch == "}"
        cur += ch
    return out


def crate_graph(src: Path) -> dict:
    files = {module_of(src, f): f for f in src.rglob("*.rs")}
    code = {m: code_of(f) for m, f in files.items()}
    # names each module file re-exports: name -> the path it comes from
    reexports = {}
    for m, text in code.items():
        for base, names in REEXPORT.findall(text):
            for item in expand(base + "::{" + names + "}"):
                name = item[-1].split(" as ")[-1].strip()
                reexports.setdefault(m, {})[name] = item

    def resolve(m: tuple, parts: list, seen=0):
        """The file a path from module m lands in (None: outside the crate)."""
        kind, rest = parts[0], parts[1:]
        if kind == "crate":
            base = ()
        elif kind == "super":
            base = m[:-1]
            while rest and rest[0] == "super":
                base, rest = base[:-1], rest[1:]
        else:
            base = m
        path = base
        for i, p in enumerate(rest):
            if path + (p,) in files:
                path = path + (p,)
                continue
            # an item of `path`: re-exported from elsewhere?
            origin = reexports.get(path, {}).get(p)
            if origin and seen < 8:
                first = origin[0]
                if first in ("crate", "super", "self"):
                    return resolve(path, origin, seen + 1)
                if path + (first,) in files:
                    return resolve(path, ["self"] + origin, seen + 1)
            break
        return path if path in files else None

    graph = {m: set() for m in files}
    for m, text in code.items():
        for kind, tail in PATH.findall(text):
            for parts in expand(tail):
                target = resolve(m, [kind] + parts)
                if target is not None and target != m and target[: len(m)] != m:
                    graph[m].add(target)
    return {str(files[m].relative_to(ROOT)): {str(files[t].relative_to(ROOT)) for t in ts}
            for m, ts in graph.items()}


def cycles(graph: dict) -> list:
    """The strongly connected components with more than one file (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in graph:
        if v not in index:
            visit(v)
    return out


def long_files() -> list:
    """(lines before the test module, path) of every source file over MAX_LINES."""
    out = []
    for f in sorted(ROOT.glob("crates/*/src/**/*.rs")):
        lines = f.read_text().split("\n")
        cut = next((i for i, l in enumerate(lines) if l.startswith("#[cfg(test)]")), len(lines))
        if cut > MAX_LINES:
            out.append((cut, str(f.relative_to(ROOT))))
    return out


def function_lengths(f: Path) -> list:
    """(lines, name, excused) of every function of `f` before its test module: from
    its signature to its closing brace (braces in strings and comments ignored)."""
    lines = f.read_text().split("\n")
    cut = next((i for i, l in enumerate(lines) if l.startswith("#[cfg(test)]")), len(lines))
    lines = lines[:cut]
    out = []
    for i, line in enumerate(lines):
        m = FN.match(line)
        if not m:
            continue
        depth, started = 0, False
        for j in range(i, len(lines)):
            code = re.sub(r"//.*", "", lines[j])
            code = re.sub(r'"(\\.|[^"\\])*"', '""', code)
            code = re.sub(r"'(\\.|[^'\\])'", "''", code)
            if not started and ";" in code and "{" not in code:
                break
            for ch in code:
                if ch == "{":
                    depth += 1
                    started = True
                elif ch == "}":
                    depth -= 1
            if started and depth == 0:
                excused = i > 0 and LONG_BECAUSE in lines[i - 1]
                out.append((j - i + 1, m.group(1), excused))
                break
    return out


def long_functions() -> list:
    """The rule's breaches, in words."""
    out, excused = [], []
    for f in sorted(ROOT.glob("crates/*/src/**/*.rs")):
        for n, name, why in function_lengths(f):
            where = f"{f.relative_to(ROOT)}: fn {name}: {n} lines"
            if n > HARD_FN_LINES:
                out.append(f"{where} (at most {HARD_FN_LINES}, even with a reason)")
            elif n > MAX_FN_LINES and not why:
                out.append(f"{where} (at most {MAX_FN_LINES}; or say why above it: {LONG_BECAUSE} ...)")
            elif n > MAX_FN_LINES:
                excused.append(where)
    if len(excused) > MAX_LONG_FNS:
        out.append(f"{len(excused)} functions excused (at most {MAX_LONG_FNS}): " + "; ".join(excused))
    return out


def main() -> int:
    found = []
    for breach in long_functions():
        found.append(breach)
        print("too long:", breach)
    for n, f in long_files():
        found.append(f)
        print(f"too long: {f}: {n} lines before its tests (at most {MAX_LINES})")
    for src in sorted(ROOT.glob("crates/*/src")):
        graph = crate_graph(src)
        for comp in cycles(graph):
            found.append(comp)
            print("cycle:", " <-> ".join(comp))
            for a in comp:
                for b in sorted(graph[a] & set(comp)):
                    print(f"  {a} -> {b}")
    if not found:
        print(
            f"no import cycles between files; no source file over {MAX_LINES} lines; "
            f"no function over {MAX_FN_LINES} lines"
        )
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
