"""Concentric tube robot kinematics in numpy.

``ctr_py`` is the Python face of the ``ctr`` toolkit (the same library ``ctr-cli``
runs): robot TOML files in, forward and inverse kinematics, tip Jacobians and backbones
out as float64 numpy arrays. Joints are in file units, ``s1_mm, theta1_deg, ...``
(outermost tube first), positions in mm, orientations as unit quaternions
``(w, x, y, z)`` with ``w >= 0``.

    >>> import ctr_py
    >>> robot = ctr_py.Robot.from_toml("data/robots/nitinol3.toml")
    >>> positions, quaternions = robot.fk([[20, 0, 50, 0, 80, 90]])

Recordings of the real robot are diagnosed as ``ctr-cli diagnose`` does it:

    >>> rec = ctr_py.read_recording("rec.csv", robot)
    >>> report = ctr_py.diagnose(robot, rec)
    >>> print(report.summary())
    >>> fitted = report.fitted  # a Robot: the model with the effects found

Batch calls release the GIL and use all cores. Every failure is a :class:`CtrError`
whose message is the line ``ctr-cli`` prints for the same input. A :class:`Robot`
pickles (as its TOML text), so it can be sent to worker processes; so do a
:class:`Recording` and a :class:`Report`.
"""

from ._ctr import (
    Recording,
    Report,
    Robot,
    __version__,
    calibrate,
    diagnose,
    evaluate,
    read_recording,
)
from ._errors import CtrError, FileError, InputError, InputTypeError, SolverError

__all__ = [
    "Robot",
    "Recording",
    "Report",
    "read_recording",
    "diagnose",
    "calibrate",
    "evaluate",
    "CtrError",
    "InputError",
    "InputTypeError",
    "FileError",
    "SolverError",
    "__version__",
]
