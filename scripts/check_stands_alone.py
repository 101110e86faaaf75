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
    (a `*` matches as a glob; placeholders such as `<id>` are skipped).
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


def tracked() -> list:
    out = subprocess.run(["git", "ls-files", "-s"], cwd=REPO, check=True,
                         capture_output=True, text=True).stdout
    files = []
    for line in out.splitlines():
        meta, path = line.split("\t", 1)
        files.append((meta.split()[0], path))
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
                if re.match(r"^[a-z]+:", target) or target.startswith("#"):
                    continue  # a web address or an anchor
                if not exists_in_repo(target.split("#")[0], path.parent):
                    problems.append(f"{rel}:{n}: link {target} does not resolve in the repository")
            if prose_paths:
                for quoted in BACKTICKED.findall(line):
                    if quoted.startswith(REPO_DIRS) and not exists_in_repo(quoted, REPO):
                        problems.append(f"{rel}:{n}: `{quoted}` is not in the repository")
    if problems:
        print("\n".join(problems), file=sys.stderr)
        print(f"check_stands_alone: {len(problems)} problem(s)", file=sys.stderr)
        sys.exit(1)
    print("check_stands_alone: no reference outside the repository; every link and "
          "quoted path of the docs resolves")


if __name__ == "__main__":
    main()
