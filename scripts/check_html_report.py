#!/usr/bin/env python3
"""CI check of the HTML report (`ctr-cli diagnose --html`): renders it in headless
Chromium with the network cut off, takes a screenshot and dumps the DOM, and checks
that the page shows the verdict and the plots.

    python scripts/check_html_report.py --cli target/release/ctr-cli [--keep DIR]

Checks, each failing with a one-line reason:
  - the file fetches nothing and runs nothing (no script, src=, href=, link, url(),
    @import; the only URL is the SVG namespace);
  - the DOM Chromium built (`--dump-dom`) has the verdict (`#verdict`, its words and
    `data-explained`), the sections, and one drawn <svg> per plot: error by run, the
    residual, one per run of the recording;
  - the screenshot has the window's size, is not blank, and shows the verdict's
    colour and the two models' colours of the plots (so the SVG was painted).

Needs Chromium (Debian's `chromium`), numpy and Pillow (a dependency of matplotlib). Each
Chromium run is bounded by CHROMIUM_TIMEOUT_S."""

import argparse
import csv
import re
import shutil
import subprocess
import sys
import tempfile
import time
from html.parser import HTMLParser
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
ROBOT = REPO / "data" / "robots" / "liu2023.toml"
RECORDING = REPO / "data" / "examples" / "liu2023-recording.csv"

# seconds a Chromium run may take before the check fails
CHROMIUM_TIMEOUT_S = 60
# the screenshot's window, pixels: wide as a laptop, tall enough for every plot
WINDOW = (1100, 7000)
# colours the page paints (ctr_diagnosis: html.rs STYLE, plots.rs BEFORE / AFTER)
EXPLAINED_RGB = (0xE3, 0xF4, 0xE1)
UNEXPLAINED_RGB = (0xFD, 0xF0, 0xDC)
USER_MODEL_RGB = (214, 39, 40)
FITTED_MODEL_RGB = (31, 119, 180)
# how far (per channel, 0-255) a pixel may be from a colour and still count as it
COLOUR_TOLERANCE = 6
# at least this many pixels of each plot colour (a bar or a few dozen points)
MIN_COLOUR_PIXELS = 500
# at least this share of the screenshot is not white (text, tables, plots)
MIN_INK_SHARE = 0.03
# markup that would fetch something or run code
FORBIDDEN = ("<script", "src=", "href=", "<link", "@import", "url(", "<iframe", "<object")
SECTIONS = ("findings", "error-by-run", "residual", "paths", "unexplained", "next-run",
            "fitted")


def fail(message: str) -> None:
    print(f"check_html_report: FAILED: {message}", file=sys.stderr)
    sys.exit(1)


def chromium_binary() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    fail("no chromium on PATH (apt-get install chromium)")
    return ""


def chromium(binary: str, profile: Path, *args: str) -> subprocess.CompletedProcess:
    """Runs headless Chromium with every host name unresolvable (nothing can be
    fetched) and a throw-away profile."""
    cmd = [
        binary, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
        "--no-first-run", "--disable-background-networking", "--hide-scrollbars",
        "--host-resolver-rules=MAP * ~NOTFOUND", f"--user-data-dir={profile}", *args,
    ]
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=CHROMIUM_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        fail(f"chromium took more than {CHROMIUM_TIMEOUT_S} s: {' '.join(args)}")
    if p.returncode != 0:
        fail(f"chromium exited {p.returncode}: {p.stderr.strip()[-500:]}")
    return p


class Dom(HTMLParser):
    """What the check needs of the DOM: elements by id, the verdict's text, the svgs
    and how many shapes each holds."""

    def __init__(self):
        super().__init__()
        self.ids = {}
        self.verdict_text = ""
        self.in_verdict = 0
        self.svgs = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if "id" in a:
            self.ids[a["id"]] = a
        if self.in_verdict or a.get("id") == "verdict":
            self.in_verdict += 1
        if tag == "svg":
            self.svgs.append(0)
        elif tag in ("circle", "rect", "polyline", "path", "line") and self.svgs:
            self.svgs[-1] += 1

    def handle_endtag(self, tag):
        if self.in_verdict:
            self.in_verdict -= 1

    def handle_data(self, data):
        if self.in_verdict:
            self.verdict_text += data


def runs_of(recording: Path) -> int:
    with open(recording, newline="") as f:
        labels = [row["run"] for row in csv.DictReader(f)]
    return sum(1 for i, label in enumerate(labels) if i == 0 or labels[i - 1] != label)


def check_file(html: str) -> None:
    lower = html.lower()
    for bad in FORBIDDEN:
        if bad in lower:
            fail(f"the page holds {bad!r}: it must fetch and run nothing")
    urls = len(re.findall(r"https?:", lower))
    namespaces = lower.count('xmlns="http://www.w3.org/2000/svg"')
    if urls != namespaces:
        fail(f"{urls - namespaces} URLs beside the SVG namespaces")


def check_dom(dom_text: str, n_runs: int) -> str:
    dom = Dom()
    dom.feed(dom_text)
    verdict = dom.ids.get("verdict")
    if verdict is None:
        fail("no #verdict in the DOM")
    explained = verdict.get("data-explained")
    words = "Verdict: explained" if explained == "true" else "Verdict: not explained"
    if explained not in ("true", "false") or words not in dom.verdict_text:
        fail(f"the verdict reads {dom.verdict_text.strip()!r} (data-explained={explained})")
    missing = [s for s in SECTIONS if s not in dom.ids]
    if missing:
        fail(f"sections missing from the DOM: {missing}")
    want = 2 + n_runs
    drawn = [n for n in dom.svgs if n > 0]
    if len(dom.svgs) != want or len(drawn) != want:
        fail(f"{len(dom.svgs)} svg elements ({len(drawn)} with shapes), want {want}")
    print(f"  DOM: verdict {dom.verdict_text.strip()[:70]!r}..., {len(dom.svgs)} plots "
          f"({min(dom.svgs)} to {max(dom.svgs)} shapes each), sections {', '.join(SECTIONS)}")
    return explained


def check_screenshot(png: Path, explained: str) -> None:
    try:
        import numpy as np
        from PIL import Image
    except ImportError:
        fail("numpy and Pillow are needed to read the screenshot (pip install matplotlib)")
    image = Image.open(png).convert("RGB")
    if image.size != WINDOW:
        fail(f"the screenshot is {image.size}, the window {WINDOW}")
    pixels = np.asarray(image, dtype=np.int16).reshape(-1, 3)
    ink = float(np.mean(np.any(pixels != 255, axis=1)))

    def count(rgb):
        return int(np.sum(np.all(np.abs(pixels - np.array(rgb)) <= COLOUR_TOLERANCE, axis=1)))

    verdict_rgb = EXPLAINED_RGB if explained == "true" else UNEXPLAINED_RGB
    counts = {name: count(rgb) for name, rgb in (("verdict box", verdict_rgb),
                                                ("user model", USER_MODEL_RGB),
                                                ("fitted model", FITTED_MODEL_RGB))}
    print(f"  screenshot: {image.size[0]}x{image.size[1]}, {png.stat().st_size} bytes, "
          f"{100 * ink:.1f} % not white, pixels of " +
          ", ".join(f"{k} {v}" for k, v in counts.items()))
    if ink < MIN_INK_SHARE:
        fail(f"the screenshot is nearly blank ({100 * ink:.2f} % not white)")
    for name, n in counts.items():
        if n < MIN_COLOUR_PIXELS:
            fail(f"only {n} pixels of the {name}'s colour: not painted")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cli", required=True, type=Path, help="the ctr-cli binary")
    ap.add_argument("--keep", type=Path, help="write the page and the screenshot here")
    args = ap.parse_args()
    start = time.monotonic()
    binary = chromium_binary()
    with tempfile.TemporaryDirectory() as tmp:
        out = args.keep or Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        page, png = out / "report.html", out / "report.png"
        p = subprocess.run([str(args.cli), "diagnose", "--robot", str(ROBOT), "--recording",
                            str(RECORDING), "--html", str(page)],
                           capture_output=True, text=True)
        if p.returncode != 0:
            fail(f"ctr-cli diagnose --html: {p.stderr.strip()}")
        print(f"  page: {page.stat().st_size} bytes from {RECORDING.relative_to(REPO)}")
        check_file(page.read_text(encoding="utf-8"))
        dom = chromium(binary, Path(tmp) / "profile-dom", "--dump-dom", page.as_uri())
        explained = check_dom(dom.stdout, runs_of(RECORDING))
        chromium(binary, Path(tmp) / "profile-shot", f"--screenshot={png}",
                 f"--window-size={WINDOW[0]},{WINDOW[1]}", page.as_uri())
        check_screenshot(png, explained)
    print(f"check_html_report: ok ({time.monotonic() - start:.1f} s)")


if __name__ == "__main__":
    main()
