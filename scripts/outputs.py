"""The Python half of scripts/outputs.sh: ctr_py's results on the bundled robots and
examples, written as text files (floats in repr, the shortest round-trip form) so that
scripts/compare_outputs.py can compare two versions of the wheel.

    python3 scripts/outputs.py OUT_DIR [SHARED_DATA]
"""

import sys
from pathlib import Path

import numpy as np

import ctr_py

REPO = Path(__file__).resolve().parents[1]


def dump(path: Path, *arrays) -> None:
    with path.open("w") as f:
        for a in arrays:
            a = np.asarray(a)
            f.write(f"# shape {a.shape}\n")
            for v in a.reshape(-1):
                f.write(f"{v!r}\n" if isinstance(v, (float, np.floating)) else f"{v}\n")


def main() -> None:
    out = Path(sys.argv[1])
    shared = Path(sys.argv[2]) if len(sys.argv) > 2 else REPO / "tests" / "data" / "shared"
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(7)
    for path in sorted((REPO / "data" / "robots").glob("*.toml")):
        robot = ctr_py.Robot.from_toml(path)
        n = robot.n_tubes
        # joints inside the ranges: increasing feeds, any angle
        feeds = np.cumsum(rng.uniform(15.0, 40.0, size=(200, n)), axis=1)
        angles = rng.uniform(-180.0, 180.0, size=(200, n))
        q = np.empty((200, 2 * n))
        q[:, 0::2] = feeds
        q[:, 1::2] = angles
        name = path.stem
        for model in ("rigid", "torsion"):
            p, quat, status, res = robot.fk(q, model, on_error="mark")
            dump(out / f"fk-{name}-{model}.txt", p, quat, status, res)
            dump(out / f"jacobian-{name}-{model}.txt", robot.jacobian(q[:20], model))
            dump(out / f"backbone-{name}-{model}.txt", robot.backbone(q[3], model))
        targets = robot.fk(q[:30])[0]
        qk, resid, status = robot.ik(targets)
        dump(out / f"ik-{name}.txt", qk, resid, status)
    example = REPO / "data" / "examples" / "liu2023-recording.csv"
    robot = ctr_py.Robot.from_toml(REPO / "data" / "robots" / "liu2023.toml")
    rec = ctr_py.read_recording(example, robot)
    report = ctr_py.diagnose(robot, rec, threads=2)
    (out / "diagnose-example.json").write_text(report.to_json())
    (out / "diagnose-example.summary").write_text(report.summary())
    (out / "diagnose-example.toml").write_text(report.fitted.to_toml())
    tips, _ = report.fitted.fk(rec.joints[:40], t_s=rec.t_s[:40])
    dump(out / "fitted-fk-example.txt", tips)
    clearance = shared / "recordings" / "dev-clearance.csv"
    if clearance.exists():
        robot = ctr_py.Robot.from_toml(shared / "robots" / "liu2023.toml")
        rec = ctr_py.read_recording(clearance, robot)
        cal = ctr_py.calibrate(robot, rec, ["clearance"], table=12, threads=2)
        (out / "calibrate-clearance.json").write_text(cal.to_json())
        rows = ctr_py.evaluate([robot, cal.fitted], rec)
        (out / "evaluate-clearance.txt").write_text(repr(rows))


if __name__ == "__main__":
    main()
