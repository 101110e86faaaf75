"""Type stubs and documentation of the compiled module ``ctr_py._ctr``.

Conventions of every call:

- Joints ``q`` are in file units and file order: ``s1_mm, theta1_deg, s2_mm,
  theta2_deg, ...`` (tube 1 is the outermost), shape ``(2n,)`` for one joint vector or
  ``(m, 2n)`` for ``m`` of them. Any array-like is accepted: numpy arrays of any memory
  order or strides (Fortran order, slices with steps, negative strides), lists, tuples.
  ``float64`` is used as is; integer and other float dtypes are converted; bool,
  complex, string and object arrays raise :class:`~ctr_py.InputTypeError`.
- Joints are checked as ``ctr-cli fk`` checks a joint file: every value finite, then
  the core's ranges (``0 <= s1 <= s2 <= ... <= sn``, ``s_i <= length_i``); the first
  bad row raises :class:`~ctr_py.InputError` with the CLI's message located at the
  argument and row, e.g. ``q[41]: s2_mm = 20 must be >= s1_mm = 30 (...)``.
- A 1-D input gives results without the row axis (``(3,)`` rather than ``(1, 3)``, a
  float or str rather than an array of one).
- ``model`` is ``"rigid"`` or ``"torsion"``; ``None`` means the robot file's
  ``[model] kind``.
- ``threads`` is the number of worker threads, 0 (the default) for all cores, at most
  1024. Results never depend on it. The GIL is released while solving.
- The robot file's ``[model.effects]`` are part of the model, as in ``ctr-cli``: joint
  offsets (``q`` are the commanded joints), scaled stiffness and precurvature,
  clearance kinks or gravity, and the tip as measured (sensor offset, then
  registration: positions and orientations are in the measuring frame). Time effects
  (``latency``, ``friction`` with a non-zero play) need the rows' times: see
  :meth:`Robot.fk`.
"""

from os import PathLike
from typing import Literal, Optional, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

__version__: str

ArrayLike = npt.ArrayLike
F64 = npt.NDArray[np.float64]
Model = Literal["rigid", "torsion"]

class Robot:
    """A robot read from a robot TOML file: its tubes, ``[model]`` (with
    ``[model.effects]``), ``[limits]`` and ``[actuation]``, validated exactly as
    ``ctr-cli`` validates them.

    Immutable, comparable with ``==`` (same robot description) and picklable: it
    pickles as its TOML text, so it can be sent to worker processes
    (``multiprocessing``, Dask, Ray) and gives the same results there bit for bit.
    """

    @classmethod
    def from_toml(cls, path: Union[str, "PathLike[str]"]) -> "Robot":
        """Reads a robot TOML file.

        Raises :class:`~ctr_py.FileError` when the file cannot be read (or is not
        UTF-8) and :class:`~ctr_py.InputError` when it does not parse or validate; the
        message names ``path`` as given, with line and column, exactly as
        ``ctr-cli fk --robot path`` prints it.
        """

    @classmethod
    def from_toml_str(cls, text: str, name: str = "<string>") -> "Robot":
        """Parses robot TOML text; errors name the file ``name``."""

    def to_toml(self) -> str:
        """The robot file's TOML text, with an explicit ``[model]`` and its
        ``[model.effects]`` tables. ``Robot.from_toml_str(r.to_toml()) == r``."""

    @property
    def n_tubes(self) -> int:
        """Number of tubes (1 to 4)."""

    @property
    def name(self) -> Optional[str]:
        """The file's ``name``, if it has one."""

    @property
    def model(self) -> Model:
        """The file's ``[model] kind`` (``"torsion"`` when the file has no ``[model]``)."""

    @property
    def joint_columns(self) -> list[str]:
        """Joint names in file order: ``["s1_mm", "theta1_deg", ...]``."""

    @property
    def source(self) -> str:
        """The file name errors give: the path as given to :meth:`from_toml`, or the
        ``name`` given to :meth:`from_toml_str`."""

    def __eq__(self, other: object) -> bool: ...
    def __reduce__(self) -> tuple[object, tuple[str, str]]: ...

    @overload
    def fk(
        self,
        q: ArrayLike,
        model: Optional[Model] = None,
        *,
        on_error: Literal["fail"] = "fail",
        threads: int = 0,
        t_s: Optional[ArrayLike] = None,
    ) -> Tuple[F64, F64]: ...
    @overload
    def fk(
        self,
        q: ArrayLike,
        model: Optional[Model] = None,
        *,
        on_error: Literal["mark"],
        threads: int = 0,
        t_s: Optional[ArrayLike] = None,
    ) -> Tuple[F64, F64, Union[npt.NDArray[np.str_], str], Union[F64, float]]: ...
    def fk(
        self,
        q: ArrayLike,
        model: Optional[Model] = None,
        *,
        on_error: Literal["fail", "mark"] = "fail",
        threads: int = 0,
        t_s: Optional[ArrayLike] = None,
    ) -> tuple:
        """Tip forward kinematics: ``positions, quaternions = robot.fk(q)``.

        ``q`` of shape ``(2n,)`` or ``(m, 2n)`` gives positions ``(3,)`` / ``(m, 3)``
        (mm, in the world frame W) and quaternions ``(4,)`` / ``(m, 4)``, ``w, x, y, z``
        with ``w >= 0``: the tip frame of the innermost tube.

        The numbers are those ``ctr-cli fk`` writes for the same rows, to the last bit:
        the rows are solved by the same batch function, in chunks of 32 consecutive rows
        each warm-started from the previous rows of its chunk (so results depend on a
        row's position modulo 32, below the solver tolerance, exactly as in the CLI,
        and never on ``threads``).

        ``on_error`` is what to do when a solve does not converge, as the CLI's
        ``--on-error``: ``"fail"`` (default) raises :class:`~ctr_py.SolverError` with
        the CLI's message (the first failed row, and how many failed); ``"mark"``
        returns two more results, the status of every row (``"converged"``,
        ``"iteration_limit"`` or ``"diverged"``) and its free-tip torque residual in
        rad/mm. (The CLI's ``skip`` has no counterpart: mask with the status.)

        Effects: the robot file's ``[model.effects]`` are applied as ``ctr-cli fk``
        applies them (see the module notes), with the same numbers to the last bit.
        Time effects (``latency``, ``friction`` with a non-zero play) make a row's tip
        depend on the rows before it: then ``t_s`` is required, the rows' times in
        seconds, shape ``(m,)`` (or a float for one row), finite and non-decreasing;
        the rows are one run in order (friction's memory starts at the first row;
        latency interpolates the commands between rows), exactly as ``ctr-cli fk`` on
        a joint file with that ``t_s`` column and no ``run`` column. Without ``t_s``
        such a robot raises :class:`~ctr_py.InputError` naming the effect (the CLI,
        for a file without ``t_s``, takes the row order as time; here rows are often
        unrelated configurations, so the times must be given). For several runs call
        ``fk`` once per run. Without time effects ``t_s`` is checked and not used.
        """

    def backbone(self, q: ArrayLike, model: Optional[Model] = None) -> F64:
        """Backbone points of one joint vector ``q`` (shape ``(2n,)``): an array
        ``(k, 3)`` of positions in W, mm, from the guide exit (the first point) to the
        tip (the last), one per integration step. Solved cold; raises
        :class:`~ctr_py.SolverError` when the solve does not converge.

        Effects: the backbone of the static mechanics: joint offsets added, tubes
        scaled (stiffness, precurvature), points in the measuring frame when the file
        has a registration (the sensor offset is not a backbone point: the last point
        is the tube's tip, not the tracked point). Robots with clearance kinks, gravity
        or time effects raise :class:`~ctr_py.InputError` (the backbone solver does not
        model them; use :meth:`fk` for the tip)."""

    def jacobian(
        self, q: ArrayLike, model: Optional[Model] = None, *, threads: int = 0
    ) -> F64:
        """Tip Jacobian: shape ``(6, 2n)`` for ``q`` of shape ``(2n,)``, ``(m, 6, 2n)``
        for ``(m, 2n)``.

        Column ``j`` is the derivative with respect to joint ``j`` in file units (per mm
        for a feed, per degree for a rotation); rows 0-2 the tip position (mm), rows
        3-5 the tip's angular velocity in W (rad). Computed as the inverse kinematics
        computes it: central finite differences of the forward kinematics solved to
        tight tolerances (1e-13 rad/mm), one-sided at the core's joint bounds (the
        robot file's ``[limits]`` do not apply here). Raises
        :class:`~ctr_py.SolverError` where the forward kinematics does not converge.
        The forward kinematics is the file's static model with its effects (as in
        :meth:`ik`): the Jacobian of the measured tip with respect to the commanded
        joints. Time effects raise :class:`~ctr_py.InputError`.
        """

    def ik(
        self,
        targets: ArrayLike,
        q0: Optional[ArrayLike] = None,
        *,
        model: Optional[Model] = None,
        cold: bool = False,
        chunk_rows: int = 32,
        tolerance_mm: float = 1e-4,
        orientation_tolerance_deg: float = 0.0057,
        position_weight: float = 1.0,
        orientation_weight: float = 100.0,
        damping_feed: float = 1e-6,
        damping_rotation: float = 1e-4,
        restarts: int = 8,
        max_iterations: int = 100,
        threads: int = 0,
    ) -> Tuple[F64, Union[F64, float], Union[npt.NDArray[np.str_], str]]:
        """Inverse kinematics: ``q, residual_mm, status = robot.ik(targets)``.

        ``targets`` are tip positions ``(3,)`` / ``(m, 3)`` (``x_mm, y_mm, z_mm``) or
        poses ``(7,)`` / ``(m, 7)`` (position then the orientation quaternion
        ``qw, qx, qy, qz``: a unit quaternion within 1e-3, then normalised, as
        ``ctr-cli ik`` reads a targets file). The solver is the library's damped
        Levenberg-Marquardt with joint limits (the core's ranges and the robot file's
        ``[limits]``) held exactly at every step. The keyword settings are
        ``ctr-cli ik``'s options of the same names, with the same defaults.

        Without ``q0`` the results are those ``ctr-cli ik`` writes for the same targets
        and settings, to the last bit:

        - by default the targets are a trajectory: each row starts from the previous
          row's result, in chunks of ``chunk_rows`` rows whose first rows are solved in
          order first (so chunks run in parallel and the results never depend on
          ``threads``); ``chunk_rows=0`` makes one chain on one thread;
        - ``cold=True``: every target is solved on its own from a seeded table of start
          points (scattered targets), in parallel.

        With ``q0`` (this has no CLI counterpart): of shape ``(2n,)``, the trajectory
        starts there and is solved as one chain, in order (``chunk_rows`` is not used);
        with ``cold=True`` every target starts from ``q0``, or of shape ``(m, 2n)``
        each from its own row, independently and in parallel.

        Returns joints ``(2n,)`` / ``(m, 2n)`` in file units, inside the limits; the
        distance from the tip to the target position in mm; and the status:
        ``"reached"`` (within ``tolerance_mm``, and ``orientation_tolerance_deg`` for a
        pose), ``"unreachable"`` (the closest point found, for a target outside the
        workspace), ``"iteration_limit"`` or ``"fk_failed"``. An unreachable target is
        not an error.

        Effects: the forward model inside the IK is the file's static model, as
        ``ctr-cli ik`` uses it: the joints found are the commanded ones (joint offsets
        included) and the targets are in the measuring frame (sensor offset and
        registration are inverted with the rest). Time effects (``latency``,
        ``friction`` with a non-zero play) cannot be inverted target by target:
        raises :class:`~ctr_py.InputError` naming ``model.effects.latency`` /
        ``friction``, with the CLI's message.
        """
