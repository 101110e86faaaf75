"""Concentric tube robot kinematics in numpy.

``ctr_py`` is the Python face of the ``ctr`` toolkit (the same library ``ctr-cli``
runs): robot TOML files in, forward and inverse kinematics, tip Jacobians and backbones
out as float64 numpy arrays. Joints are in file units, ``s1_mm, theta1_deg, ...``
(outermost tube first), positions in mm, orientations as unit quaternions
``(w, x, y, z)`` with ``w >= 0``.

    >>> import ctr_py
    >>> robot = ctr_py.Robot.from_toml("data/robots/nitinol3.toml")
    >>> positions, quaternions = robot.fk([[20, 0, 50, 0, 80, 90]])

Batch calls release the GIL and use all cores. Every failure is a :class:`CtrError`
whose message is the line ``ctr-cli`` prints for the same input. A :class:`Robot`
pickles (as its TOML text), so it can be sent to worker processes.
"""

from ._ctr import Robot, __version__
from ._errors import CtrError, FileError, InputError, InputTypeError, SolverError

__all__ = [
    "Robot",
    "CtrError",
    "InputError",
    "InputTypeError",
    "FileError",
    "SolverError",
    "__version__",
]
