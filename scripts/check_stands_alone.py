#!/usr/bin/env python3
"""CI check that the repository stands alone: a clone with nothing beside it passes
`bash .ci/run`, and no test, script, example or doc reads or points outside it.

    python3 scripts/check_stands_alone.py

Over every file git tracks (text files; the shared data's own files, `tests/data/shared/`,
are data as given and only its README is read):
  - no reference to a path outside the repository: `../shared`, the workplace's
    `shared/spec/` or `shared/data/` (the project's copies are `docs/formats.md` and
    `tests/data/shared/`), `.parent / "shared"` in Python, absolute `/work/` paths;
  - no symbolic link whose target leaves the repository;
  - every relative Markdown link resolves to a file or directory in the repository;
  - every repository path quoted in backticks in README.md, docs/ and data/*.md exists
    (a `*` matches as a glob; placeholders such as `<id>` are skipped);
  - every link to a heading (`page.md#heading`, `#heading`) names a heading of that page
    (GitHub's anchors: lower case, punctuation dropped, spaces as hyphens);
  - every table of measured figures in README.md and docs/ (a cell with a number in mm,
    deg, rad, s, ms, us, rows/s, MB or KB) says which command produced it and when: each
    row, with the paragraph above the table, holds a date (YYYY-MM-DD) and a command in
    backticks (`cargo ...`, `bash ...`, `python ...`, `ctr-cli ...`, `scripts/...`), so
    that no figure is left without the way to measure it again and its age.
Files git does not track yet but would add (not ignored) are checked as tracked ones.
Exits 1 with one line per problem (file:line: what).
"""

import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

# Files left as they are for now, with the reason (keep this list short and dated).
ALLOWED: dict[str, str] = {}

OUTSIDE = [
    (re.compile(r"\.\./shared\b"), "../shared is outside the repository"),
    (re.compile(r"(?<![\w/.-])/work/"), "an absolute path of the workplace"),
    (re.compile(r"\.parents?(\[\d+\])?\s*/\s*[\"']shared[\"']"),
     "the shared directory beside the repository"),
    (re.compile(r"(?<![\w/.-])shared/spec/"),
     "the workplace's spec: the project's copy is docs/formats.md"),
    # not inside a string literal: code that strips this prefix from the truth files'
    # robot paths (data as given) quotes it
    (re.compile(r"(?<![\w/.'\"-])shared/data\b"),
     "the workplace's data: the project's copy is tests/data/shared"),
]
MARKDOWN_LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
BACKTICKED = re.compile(r"`([^`\s]+)`")
REPO_DIRS = ("crates/", "data/", "docs/", "tests/", "scripts/", "examples/", "benches/",
             ".ci/")
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
# a measured figure: a number with a unit of length, angle, time, rate or size
FIGURE = re.compile(r"\d(?:[\d,.]*\d)?(?:e-?\d+)?\s?(?:mm|deg|rad|s|ms|us|rows/s|MB|KB)\b")
DATE = re.compile(r"\b20\d\d-\d\d-\d\d\b")
COMMAND = re.compile(r"`(?:[A-Z_]+=\S+ )*(?:cargo|bash|python3?|ctr-cli|taskset|scripts/|tests/no-alloc/)[^`]*`")


def tracked() -> list:
    out = subprocess.run(["git", "ls-files", "-s"], cwd=REPO, check=True,
                         capture_output=True, text=True).stdout
    files = []
    for line in out.splitlines():
        meta, path = line.split("\t", 1)
        files.append((meta.split()[0], path))
    # files not committed yet (a new page of the guide) are checked as they will be
    new = subprocess.run(["git", "ls-files", "--others", "--exclude-standard"], cwd=REPO,
                         check=True, capture_output=True, text=True).stdout
    for path in new.splitlines():
        files.append(("120000" if (REPO / path).is_symlink() else "100644", path))
    return files


def inside(path: Path) -> bool:
    try:
        path.resolve().relative_to(REPO)
        return True
    except ValueError:
        return False


def read_text(path: Path):
    try:
        return path.read_text(encoding="utf-8")
    except (UnicodeDecodeError, IsADirectoryError, FileNotFoundError):
        return None


def exists_in_repo(rel: str, base: Path) -> bool:
    if any(c in rel for c in "<>{}") or "..." in rel:
        return True  # a placeholder, not a path
    target = (base / rel).resolve() if not rel.startswith("/") else Path(rel)
    if not inside(target):
        return False
    if "*" in rel:
        return any(REPO.glob(str(target.relative_to(REPO))))
    return target.exists()


def slug(heading: str) -> str:
    """GitHub's anchor of a Markdown heading."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def anchors(path: Path) -> set:
    """The anchors of every heading of the Markdown file `path` (outside code blocks)."""
    found, seen, in_code = set(), {}, False
    for line in (read_text(path) or "").splitlines():
        if line.lstrip().startswith("```"):
            in_code = not in_code
        m = None if in_code else HEADING.match(line)
        if m:
            base = slug(m.group(2))
            n = seen.get(base, 0)
            seen[base] = n + 1
            found.add(base if n == 0 else f"{base}-{n}")
    return found


def link_problem(target: str, page: Path):
    """Why the relative link `target` of `page` does not resolve, or None."""
    file, _, anchor = target.partition("#")
    if file and not exists_in_repo(file, page.parent):
        return f"link {target} does not resolve in the repository"
    dest = (page.parent / file).resolve() if file else page
    if anchor and dest.suffix == ".md" and dest.is_file() and anchor not in anchors(dest):
        return f"link {target}: no heading #{anchor} in {dest.relative_to(REPO)}"
    return None


def figure_tables(rel: str, text: str) -> list:
    """Tables of measured figures in `text` without a command or a date for some row."""
    problems, lines = [], text.splitlines()
    in_code, n = False, 0
    while n < len(lines):
        if lines[n].lstrip().startswith("```"):
            in_code = not in_code
        if in_code or not lines[n].startswith("|"):
            n += 1
            continue
        start = n
        while n < len(lines) and lines[n].startswith("|"):
            n += 1
        body = lines[start + 2:n]
        if not any(FIGURE.search(row) for row in body):
            continue
        k = start - 1
        while k >= 0 and not lines[k].strip():
            k -= 1
        caption = []
        while k >= 0 and lines[k].strip() and not lines[k].startswith("|"):
            caption.insert(0, lines[k])
            k -= 1
        caption = " ".join(caption)
        for offset, row in enumerate(body):
            context = caption + " " + row
            missing = [what for what, pattern in (("a date", DATE), ("a command", COMMAND))
                       if not pattern.search(context)]
            if missing:
                problems.append(f"{rel}:{start + 3 + offset}: a table of measured figures "
                                f"whose row and caption lack {' and '.join(missing)}")
    return problems


def main() -> None:
    problems = []
    for mode, rel in tracked():
        path = REPO / rel
        if mode == "120000":
            if not inside(path):
                problems.append(f"{rel}: a symbolic link out of the repository")
            continue
        if rel.startswith("tests/data/shared/") and rel != "tests/data/shared/README.md":
            continue
        if rel in ALLOWED or rel == "scripts/check_stands_alone.py":
            continue
        text = read_text(path)
        if text is None:
            continue
        markdown = rel.endswith(".md")
        prose_paths = markdown and (rel == "README.md" or rel.startswith(("docs/", "data/")))
        in_code_block = False
        for n, line in enumerate(text.splitlines(), 1):
            for pattern, why in OUTSIDE:
                if pattern.search(line):
                    problems.append(f"{rel}:{n}: {why}: {line.strip()[:100]}")
            if not markdown:
                continue
            if line.lstrip().startswith("```"):
                in_code_block = not in_code_block
            if in_code_block:
                continue
            for target in MARKDOWN_LINK.findall(line):
                if re.match(r"^[a-z]+:", target):
                    continue  # a web address
                why = link_problem(target, path)
                if why:
                    problems.append(f"{rel}:{n}: {why}")
            if prose_paths:
                for quoted in BACKTICKED.findall(line):
                    if quoted.startswith(REPO_DIRS) and not exists_in_repo(quoted, REPO):
                        problems.append(f"{rel}:{n}: `{quoted}` is not in the repository")
        if markdown and (rel == "README.md" or rel.startswith("docs/")):
            problems += figure_tables(rel, text)
    if problems:
        print("\n".join(problems), file=sys.stderr)
        print(f"check_stands_alone: {len(problems)} problem(s)", file=sys.stderr)
        sys.exit(1)
    print("check_stands_alone: no reference outside the repository; every link, anchor "
          "and quoted path of the docs resolves; every figure table says how and when")


if __name__ == "__main__":
    main()
