"""Draws docs/margin-sweep.svg: the tip and the stability margin along a turn of the
seed's robot with 100 mm longer transmissions, solved by `ctr-cli fk --margin` as a
joint file (row after row). Usage: python3 scripts/plot_margin_sweep.py [CTR_CLI] [OUT.svg]
(needs numpy and matplotlib)."""

import csv
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
EXTRA_MM = 100.0  # longer transmissions
S1_MM, AHEAD_MM, STEP_DEG = 55.0, 40.0, 2.0


def main():
    cli = sys.argv[1] if len(sys.argv) > 1 else str(REPO / "target/release/ctr-cli")
    out = Path(sys.argv[2] if len(sys.argv) > 2 else REPO / "docs/margin-sweep.svg")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        text = (REPO / "data/robots/liu2023.toml").read_text()
        text = re.sub(
            r"length_mm = ([0-9.]+)",
            lambda m: f"length_mm = {float(m.group(1)) + EXTRA_MM}",
            text,
        )
        (tmp / "robot.toml").write_text(text)
        n = round(360 / STEP_DEG)
        along = list(range(n + 1)) + list(range(n - 1, -1, -1))
        rel = [180.0 + k * STEP_DEG for k in along]
        with (tmp / "joints.csv").open("w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["s1_mm", "theta1_deg", "s2_mm", "theta2_deg"])
            w.writerows([[S1_MM, 0.0, S1_MM + AHEAD_MM, r] for r in rel])
        done = subprocess.run(
            [cli, "fk", "--robot", str(tmp / "robot.toml"), "--joints",
             str(tmp / "joints.csv"), "--margin", "--threads", "1"],
            capture_output=True, text=True, check=True,
        )
    rows = list(csv.DictReader(done.stdout.splitlines()))
    margin = np.array([float(r["stability_margin"]) for r in rows])
    tip = np.array([[float(r[k]) for k in ("x_mm", "y_mm", "z_mm")] for r in rows])
    rel = np.array(rel) - 180.0
    fwd, back = slice(0, n + 1), slice(n, None)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for k, name in ((0, "x"), (1, "y")):
        ax1.plot(rel[fwd], tip[fwd, k], color=f"C{k}", label=f"{name}, turning forward")
        ax1.plot(rel[back], tip[back, k], "--", color=f"C{k}", label=f"{name}, turning back")
    ax1.set_ylabel("tip, mm")
    ax1.legend(loc="best", fontsize=7, ncol=2)
    ax1.set_title(
        f"seed robot, transmissions +{EXTRA_MM:.0f} mm, s = {S1_MM:.0f}, "
        f"{S1_MM + AHEAD_MM:.0f} mm: a turn and back", fontsize=10
    )
    ax2.plot(rel[fwd], margin[fwd], label="turning forward")
    ax2.plot(rel[back], margin[back], "--", label="turning back")
    ax2.axhline(0.05, color="grey", lw=0.8, ls=":")
    ax2.text(2, 0.07, "--warn-margin 0.05", fontsize=8, color="grey")
    ax2.set_ylim(0, max(1.2, margin.max() * 1.05))
    ax2.set_ylabel("stability margin")
    ax2.set_xlabel("relative angle of tube 2 from the relaxed configuration, deg")
    ax2.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(out, format="svg", metadata={"Date": None})
    print(out)


if __name__ == "__main__":
    main()
