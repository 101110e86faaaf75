"""Feed and rotation sweeps of a robot, with the tip paths plotted, and a diagnosis of
a recording before/after.

    python examples/python/sweep.py sweep.png [--robot data/robots/liu2023.toml]
        [--recording REC.csv]

Loads a robot file, feeds all tubes out together (rotations fixed), then turns the
innermost tube a full turn (feeds fixed), and draws both tip paths in 3D with the
backbone at a few points of each sweep. Then diagnoses a recording of the robot
(``data/examples/liu2023-recording.csv``, else the shared ``dev-clearance.csv``; the
panels are skipped with a note when there is none) and plots the measured tip against
the user's model and the fitted one, and the tip error of every row before and after.
Needs numpy and matplotlib; runs without a display (Agg backend).
"""

import argparse
import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import ctr_py  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
SHARED = Path(os.environ.get("CTR_SHARED_DATA") or REPO / "tests" / "data" / "shared")
RECORDINGS = [
    REPO / "data" / "examples" / "liu2023-recording.csv",
    SHARED / "recordings" / "dev-clearance.csv",
]


def sweeps(robot: ctr_py.Robot, steps: int):
    """Joint rows of a feed sweep and of a rotation sweep (mm, degrees)."""
    n = robot.n_tubes
    # tube i sits 40% to 60% out of its own length: nested, inside every range
    lengths = [
        float(line.split("=")[1])
        for line in robot.to_toml().splitlines()
        if line.startswith("length_mm")
    ]
    u = np.linspace(0.0, 1.0, steps)
    feed = np.zeros((steps, 2 * n))
    for i in range(n):
        feed[:, 2 * i] = lengths[i] * (0.35 + 0.3 * u) * (i + 1) / n + 10.0 * i
    rotation = np.repeat(feed[steps // 2][None, :], steps, axis=0)
    rotation[:, 2 * n - 1] = np.linspace(-180.0, 180.0, steps)
    return feed, rotation


def model_tips(robot: ctr_py.Robot, rec: ctr_py.Recording) -> np.ndarray:
    """The robot's tips along a recording: one fk call per run, with the run's times
    (time effects such as friction and latency start afresh at each run)."""
    tips = np.empty((len(rec), 3))
    q, t_s = rec.joints, rec.t_s
    for _, rows in rec.runs:
        tips[rows] = robot.fk(q[rows], t_s=t_s[rows], on_error="mark")[0]
    return tips


def plot_sweeps(ax, robot: ctr_py.Robot, steps: int) -> None:
    feed, rotation = sweeps(robot, steps)
    for name, q, color in (("feed sweep", feed, "tab:blue"), ("rotation sweep", rotation, "tab:orange")):
        tips, _ = robot.fk(q)  # one call per sweep: all cores, GIL released
        ax.plot(*tips.T, color=color, lw=2, label=f"tip, {name}")
        for k in (0, len(q) // 2, len(q) - 1):
            b = robot.backbone(q[k])
            ax.plot(*b.T, color=color, lw=0.8, alpha=0.6)
        print(f"{name}: {len(q)} rows, tip travels {np.linalg.norm(np.diff(tips, axis=0), axis=1).sum():.1f} mm")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")
    ax.set_title(f"tip paths ({robot.model} model)")
    ax.legend(loc="upper left", fontsize="small")


def plot_diagnosis(fig, grid, robot: ctr_py.Robot, rec: ctr_py.Recording) -> None:
    """Measured tip vs the user model vs the fitted model along the run with the
    largest total error, and the tip error of every row before and after the fit."""
    report = ctr_py.diagnose(robot, rec)  # the GIL is released while it runs
    print(report.summary(), end="")
    fitted = report.fitted  # a Robot with the effects found in [model.effects]
    before = model_tips(robot, rec)
    after = model_tips(fitted, rec)
    err_before = np.linalg.norm(before - rec.tip, axis=1)
    label, rows = max(rec.runs, key=lambda r: err_before[r[1]].sum())
    ax = fig.add_subplot(grid[0, 1])
    ax.plot(*rec.tip[rows, :2].T, ".", color="0.5", ms=3, label="measured")
    ax.plot(*before[rows, :2].T, color="tab:red", lw=1.2, label=f"user model ({robot.model})")
    found = ", ".join(report.effects) or "no effect added"
    ax.plot(*after[rows, :2].T, color="tab:green", lw=1.2, label=f"fitted (+ {found})")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"run {label!r} of {Path(rec.file).name}")
    ax.legend(loc="best", fontsize="small")
    ax = fig.add_subplot(grid[1, :])
    row = np.arange(len(rec))
    for tips, color, name, figures in (
        (before, "tab:red", "user model", report.baseline),
        (after, "tab:green", "fitted", report.final),
    ):
        err = np.linalg.norm(tips - rec.tip, axis=1)
        ax.plot(row, err, color=color, lw=0.8,
                label=f"{name}: {figures['heldout_rms_mm']:.3f} mm RMS held out")
    for _, rows in rec.runs[1:]:
        ax.axvline(rows.start, color="0.8", lw=0.8)
    ax.axhline(report.noise["rms_mm"], color="0.4", ls="--", lw=0.8, label="noise (estimated)")
    ax.set_xlabel("row (runs separated by grey lines)")
    ax.set_ylabel("tip error (mm)")
    ax.set_title("diagnosis: tip error before and after")
    ax.legend(loc="upper right", fontsize="small")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("png", help="where to save the plot")
    parser.add_argument("--robot", default=str(REPO / "data" / "robots" / "liu2023.toml"))
    parser.add_argument("--recording", help="a recording of the robot to diagnose")
    parser.add_argument("--steps", type=int, default=181)
    args = parser.parse_args()

    robot = ctr_py.Robot.from_toml(args.robot)
    rec = None
    paths = [Path(args.recording)] if args.recording else [p for p in RECORDINGS if p.exists()]
    if paths:
        try:
            rec = ctr_py.read_recording(paths[0], robot)
        except ctr_py.CtrError as e:
            print(f"note: no diagnosis panels: {e}")
    else:
        print("note: no diagnosis panels: no recording found (tried "
              + ", ".join(str(p) for p in RECORDINGS) + ")")

    fig = plt.figure(figsize=(13, 10) if rec is not None else (9, 7))
    grid = fig.add_gridspec(2, 2, height_ratios=[3, 2]) if rec is not None else None
    ax = fig.add_subplot(grid[0, 0] if grid is not None else 111, projection="3d")
    plot_sweeps(ax, robot, args.steps)
    if rec is not None:
        plot_diagnosis(fig, grid, robot, rec)
    fig.suptitle(robot.name or Path(args.robot).stem)
    fig.tight_layout()
    fig.savefig(args.png, dpi=120)
    print(f"wrote {args.png}")


if __name__ == "__main__":
    main()
