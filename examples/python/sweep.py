"""Feed and rotation sweeps of a robot, with the tip paths plotted.

    python examples/python/sweep.py sweep.png [--robot data/robots/liu2023.toml]

Loads a robot file, feeds all tubes out together (rotations fixed), then turns the
innermost tube a full turn (feeds fixed), and draws both tip paths in 3D with the
backbone at a few points of each sweep. Needs numpy and matplotlib; runs without a
display (Agg backend).
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import ctr_py  # noqa: E402

REPO = Path(__file__).resolve().parents[2]


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("png", help="where to save the plot")
    parser.add_argument("--robot", default=str(REPO / "data" / "robots" / "liu2023.toml"))
    parser.add_argument("--steps", type=int, default=181)
    args = parser.parse_args()

    robot = ctr_py.Robot.from_toml(args.robot)
    feed, rotation = sweeps(robot, args.steps)
    fig = plt.figure(figsize=(9, 7))
    ax = fig.add_subplot(projection="3d")
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
    ax.set_title(f"{robot.name or Path(args.robot).stem}: tip paths ({robot.model} model)")
    ax.legend(loc="upper left")
    fig.tight_layout()
    fig.savefig(args.png, dpi=120)
    print(f"wrote {args.png}")


if __name__ == "__main__":
    main()
