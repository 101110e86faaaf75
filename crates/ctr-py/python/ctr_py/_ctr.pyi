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
- Recordings (:func:`read_recording`) are diagnosed, calibrated and evaluated by
  :func:`diagnose`, :func:`calibrate` and :func:`evaluate`, the library calls of
  ``ctr-cli diagnose``, ``calibrate`` and ``evaluate`` with the same options and
  messages; the :class:`Report` is the JSON report ``--report`` writes.
"""

from os import PathLike
from typing import Any, Iterable, List, Literal, Optional, Sequence, Tuple, TypedDict, Union, overload

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
        margin: Literal[False] = False,
    ) -> Tuple[F64, F64]: ...
    @overload
    def fk(
        self,
        q: ArrayLike,
        model: Optional[Model] = None,
        *,
        on_error: Literal["fail"] = "fail",
        threads: int = 0,
        t_s: Optional[ArrayLike] = None,
        margin: Literal[True],
    ) -> Tuple[F64, F64, Union[F64, float]]: ...
    @overload
    def fk(
        self,
        q: ArrayLike,
        model: Optional[Model] = None,
        *,
        on_error: Literal["mark"],
        threads: int = 0,
        t_s: Optional[ArrayLike] = None,
        margin: Literal[False] = False,
    ) -> Tuple[F64, F64, Union[npt.NDArray[np.str_], str], Union[F64, float]]: ...
    @overload
    def fk(
        self,
        q: ArrayLike,
        model: Optional[Model] = None,
        *,
        on_error: Literal["mark"],
        threads: int = 0,
        t_s: Optional[ArrayLike] = None,
        margin: Literal[True],
    ) -> Tuple[
        F64, F64, Union[npt.NDArray[np.str_], str], Union[F64, float], Union[F64, float]
    ]: ...
    def fk(
        self,
        q: ArrayLike,
        model: Optional[Model] = None,
        *,
        on_error: Literal["fail", "mark"] = "fail",
        threads: int = 0,
        t_s: Optional[ArrayLike] = None,
        margin: bool = False,
        band: bool = False,
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

        ``margin=True`` returns one more result, last: every row's elastic stability
        margin, shape ``(m,)`` (a float for one row), the CLI's ``--margin`` column: the
        joint distance to the nearest snap over 20 degrees of rotation or mm of feed,
        capped at 1 (1: no snap within about 20 degrees or mm; 0.05: about one away),
        0 at a snap, negative on an unstable branch (see ``docs/snap-through.md``). Rows are solved as the CLI solves a file, so a batch along a
        path follows the branch the robot follows.

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

        A robot file with a learned discrepancy (``[model.discrepancy]``, written by
        ``ctr-cli diagnose --with-empirical``) has it added to the positions, the rows
        one run in order (its play inputs remember the joints' history; ``t_s`` where
        the model has a latency), as ``ctr-cli fk`` adds it. ``band=True`` returns one
        more result, last: each row's 95 % band half-width about the corrected tip, mm
        per axis, shape ``(m,)``; a robot without a discrepancy raises
        :class:`~ctr_py.InputError`.
        """

    def backbone(self, q: ArrayLike, model: Optional[Model] = None) -> F64:
        """Backbone points of one joint vector ``q`` (shape ``(2n,)``): an array
        ``(k, 3)`` of positions in W, mm, from the guide exit (the first point) to the
        tip (the last), one per integration step. Solved cold; raises
        :class:`~ctr_py.SolverError` when the solve does not converge.

        Effects: the backbone of the file's static model, the same solve as
        :meth:`fk`'s: joint offsets added, tubes scaled (stiffness, precurvature),
        clearance kinks, gravity, points in the measuring frame when the file has a
        registration (the sensor offset is not a backbone point: the last point is the
        tube's tip, not the tracked point). Time effects (latency, friction with a
        play) raise :class:`~ctr_py.InputError`: one joint vector has no history; use
        :meth:`fk` with ``t_s`` for the tip along a run."""

    def jacobian(
        self, q: ArrayLike, model: Optional[Model] = None, *, threads: int = 0
    ) -> F64:
        """Tip Jacobian: shape ``(6, 2n)`` for ``q`` of shape ``(2n,)``, ``(m, 6, 2n)``
        for ``(m, 2n)``.

        Column ``j`` is the derivative with respect to joint ``j`` in file units (per mm
        for a feed, per degree for a rotation); rows 0-2 the tip position (mm), rows
        3-5 the tip's angular velocity in W (rad). Computed as the inverse kinematics
        computes it, at the forward kinematics solved to tight tolerances (1e-13
        rad/mm): the core's analytic Jacobian from integrated sensitivities, or, with
        gravity or clearance kinks, central finite differences, one-sided at the core's
        joint bounds (the robot file's ``[limits]`` do not apply here). Raises
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
        min_margin: Optional[float] = None,
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
        workspace), ``"iteration_limit"``, ``"fk_failed"`` or
        ``"unreachable_with_margin"`` (see ``min_margin``). An unreachable target is
        not an error.

        ``min_margin`` (``ctr-cli ik --min-margin``): no joints returned have a
        stability margin (the one ``fk(q, margin=True)`` returns; dimensionless, 1 with
        no snap within about 20 degrees or mm, 0 at one) below it; where the tubes are bistable, neither
        the equilibrium the solve followed nor the one a cold solve finds. It is a
        constraint of every step: a target reachable only less stable gets the closest
        point found within it, status ``"unreachable_with_margin"``. A value that is
        not finite, or that no joints sampled within the limits reach, raises
        :class:`~ctr_py.InputError`.

        Effects: the forward model inside the IK is the file's static model, as
        ``ctr-cli ik`` uses it: the joints found are the commanded ones (joint offsets
        included) and the targets are in the measuring frame (sensor offset and
        registration are inverted with the rest). Time effects (``latency``,
        ``friction`` with a non-zero play) cannot be inverted target by target:
        raises :class:`~ctr_py.InputError` naming ``model.effects.latency`` /
        ``friction``, with the CLI's message.
        """


# ---------------------------------------------------------------- recordings, diagnosis

PathArg = Union[str, "PathLike[str]"]
EffectId = Literal[
    "torsion",
    "friction",
    "clearance",
    "gravity",
    "registration",
    "joint_offset",
    "stiffness",
    "precurvature",
    "latency",
    "sensor_offset",
]
"""The contract's effect ids (``docs/formats.md``)."""

class Recording:
    """A recording of the real robot: commanded joints and measured tips, row by row, in
    runs (``docs/formats.md``), read by :func:`read_recording`.

    Columns come out as new float64 numpy arrays (``m`` rows, ``n`` tubes).
    ``len(recording)`` is ``m``. Immutable, comparable with ``==`` and picklable: it
    pickles as its rows, every value exact (not as a path), so it can be sent to
    worker processes without the file.
    """

    def __len__(self) -> int: ...
    def __eq__(self, other: object) -> bool: ...
    def __reduce__(self) -> tuple[object, tuple[Any]]: ...
    @property
    def file(self) -> str:
        """The file name errors give: the path as given to :func:`read_recording`."""
    @property
    def n_tubes(self) -> int:
        """The tube count the joint columns were read for."""
    @property
    def joint_columns(self) -> list[str]:
        """``["s1_mm", "theta1_deg", ...]``: the columns of :attr:`joints`."""
    @property
    def has_time(self) -> bool:
        """Whether the file has a ``t_s`` column."""
    @property
    def t_s(self) -> F64:
        """Times, s, ``(m,)``; the row's index in the file when there is no ``t_s``
        column. Non-decreasing within each run."""
    @property
    def joints(self) -> F64:
        """Commanded joints ``(m, 2n)``, file order and units (``s1_mm, theta1_deg,
        ...``): what :meth:`Robot.fk` takes."""
    @property
    def tip(self) -> F64:
        """Measured tip positions ``(m, 3)``, mm (``x_mm, y_mm, z_mm``)."""
    @property
    def quaternion(self) -> Optional[F64]:
        """Measured orientations ``(m, 4)`` (``qw, qx, qy, qz``, unit quaternions
        within 1e-3), or ``None`` when the file has no such columns."""
    @property
    def tangent(self) -> Optional[F64]:
        """Measured unit tangents of the tip ``(m, 3)`` (``tx, ty, tz``, unit within
        1e-3: a 5-DOF sensor, no roll), or ``None`` when the file has no such
        columns."""
    @property
    def force_n(self) -> Optional[F64]:
        """Known tip forces in W ``(m, 3)``, N (``fx_n, fy_n, fz_n``, e.g. hung
        weights), or ``None`` when the file has no such columns."""
    @property
    def run(self) -> npt.NDArray[np.str_]:
        """The run label of every row, ``(m,)`` (``"all"`` when the file has no
        ``run`` column)."""
    @property
    def runs(self) -> list[Tuple[str, slice]]:
        """The runs in file order: ``(label, rows)`` with ``rows`` a slice, e.g.
        ``recording.joints[rows]``. A run is a contiguous block of rows with one
        label; time effects (friction, latency) start afresh at each run, so call
        :meth:`Robot.fk` once per run with ``t_s=recording.t_s[rows]``."""
    @property
    def lines(self) -> npt.NDArray[np.int64]:
        """The line of every row in the file, ``(m,)`` (the header is line 1)."""

def read_recording(
    path: PathArg, robot: Optional[Robot] = None, *, n_tubes: Optional[int] = None
) -> Recording:
    """Reads a recording CSV as ``ctr-cli diagnose --recording`` reads it.

    The robot (or ``n_tubes``, 1 to 4) gives the joint columns: ``s1_mm, theta1_deg,
    ..., x_mm, y_mm, z_mm`` are required; ``t_s``, ``run``, ``qw, qx, qy, qz`` and
    ``fx_n, fy_n, fz_n`` are optional; other columns are ignored. Within a run time
    must not decrease.

    Raises :class:`~ctr_py.FileError` (an ``OSError``) when the file cannot be read
    and :class:`~ctr_py.InputError` (a ``ValueError``) for a bad file (a missing
    column, a cell that is not a finite number, a ragged row, time going backwards,
    no rows) with the message ``ctr-cli`` prints, e.g. ``rec.csv:1: missing column
    s3_mm (the header needs ...)``. Giving neither or contradicting ``robot`` and
    ``n_tubes`` raises :class:`~ctr_py.InputError`.
    """

class Figures(TypedDict):
    """Error figures of a model on a recording, mm (typing only: a dict at run time)."""

    rms_mm: float
    """RMS tip error over the fit rows."""
    max_mm: float
    """Largest tip error over the fit rows."""
    heldout_rms_mm: float
    """RMS tip error over the held-out rows."""

# With the recording's orientation or tangent columns in the residual, a figures dict
# also holds ``rms_deg``, ``max_deg``, ``heldout_rms_deg`` (the tip angle, degrees) and
# ``weighted_rms_mm_eq``, ``weighted_heldout_rms_mm_eq`` (the fits' weighted basis,
# mm-equivalent); the ``*_mm`` figures stay of the tip position alone.

Finding = TypedDict(
    "Finding",
    {
        "effect": EffectId,
        "grade": Literal["established", "predictive"],
        "grade_reason": str,
        "explanation": str,
        "where": str,
        "parameters": Any,
        "rms_mm_before": float,
        "rms_mm_after": float,
        "heldout_rms_mm_before": float,
        "heldout_rms_mm_after": float,
        "empirical_heldout_rms_mm": Optional[float],
        "ci95": Any,
        "equally_explained_by": List[Any],
    },
)
"""One effect found (typing only: a dict at run time): its id, its ``grade``
(``"established"``: it passes every check and a 95 % interval excludes its "not there"
value, physics the data show; ``"predictive"``: it helps prediction on held-out rows
but its form is not established, it may stand in for something outside the vocabulary)
and ``grade_reason``, what the model leaves out in words with the fitted values, where
it shows, its fitted parameters as the robot file's ``[model.effects.<id>]`` table
writes them, the fit-row and held-out RMS of the tip positions of the final model
without it (``*_before``, the others as fitted) and with it (``*_after``), mm, and
the held-out RMS of the generic empirical
correction of as many parameters in its place (the yardstick it beat; ``None`` for
torsion and for :func:`calibrate`), and ``ci95``: the 95 % intervals of ``parameters``
(the same keys and shapes, each number replaced by ``[lo, hi]`` in its unit,
``[None, None]`` where the data set no bound), with ``identified``, a list of
``{"combination": str, "value": float, "ci95": [lo, hi]}`` (and ``"not_there"``,
the combination's value where the effect is not there, when both its parameters are
the finding's own), where only a combination
of the parameters is identified (the ratio of two tubes' stiffness factors), and
``equally_explained_by``: a list of ``{"effect": EffectId, "heldout_rms_mm": float}``,
the other effects that explained the same residual as well when it was added (the data
do not tell them from it; empty when the choice was clear)."""

class ExpectedInterval(TypedDict):
    """A parameter's 95 % interval now and expected after the suggested run (typing
    only; ``[None, None]``: not identified)."""

    parameter: str
    value: float
    ci95_now: List[Optional[float]]
    ci95_expected: List[Optional[float]]

class SuggestedRun(TypedDict):
    """The run to record next (typing only)."""

    run: str
    """What to do, in words (``turn tube 2 alone from 0 to 360 deg and back``)."""
    rows: int
    sample_period_s: float
    why: str
    expected: List[ExpectedInterval]

class Correlated(TypedDict):
    """Two fitted parameters the data hardly tell apart (typing only)."""

    a: str
    b: str
    r: float
    """Their correlation in the fit, above 0.9 in size."""

class Noise(TypedDict):
    """The noise estimated from the data (typing only)."""

    sigma_mm_per_axis: float
    rms_mm: float
    method: str

class Split(TypedDict):
    """The split of the rows into fit and held-out rows (typing only)."""

    method: str
    fit_rows: int
    heldout_rows: int

class Statement(TypedDict):
    """A pattern of the user model's error (typing only)."""

    kind: str
    """``run``, ``offset``, ``grows_with``, ``periodic``, ``direction`` or
    ``workspace``."""
    feature: str
    explained: float
    """Share of the squared error the pattern explains, 0..1."""
    text: str

class Trial(TypedDict):
    """One candidate fitted in one round of the search (typing only). The figures are
    ``None`` (JSON ``null``) for a candidate that was not tried."""

    round: int
    effect: EffectId
    rms_mm: Optional[float]
    heldout_rms_mm: Optional[float]
    bic_change: Optional[float]
    added: bool
    note: str

class MarginRange(TypedDict):
    """Consecutive rows of one run whose stability margin is below a threshold
    (typing only): the run's label, the file ``lines`` of its first and last row
    (the header is line 1), its ``rows``, and the ``lowest_margin`` with its
    ``lowest_line``."""

    run: str
    lines: List[int]
    rows: int
    lowest_margin: float
    lowest_line: int

class Marks(TypedDict):
    """The rows one model marks (typing only): ``near_snap``, ranges below the
    warning margin (rows on an unstable branch included); ``unstable``, ranges below
    0 (the model on an unstable branch)."""

    near_snap: List[MarginRange]
    unstable: List[MarginRange]

class Stability(TypedDict):
    """Where the user's (``nominal``) or the ``fitted`` model, solved along the
    recording row after row as the robot moved, is within ``warn_margin`` of a snap
    or on an unstable branch; ``outlier_lines_near_snap``: the tracker outliers
    (``outlier_lines``) in a near-snap range of either model or the row right after
    one (typing only)."""

    warn_margin: float
    nominal: Marks
    fitted: Marks
    outlier_lines_near_snap: List[int]

class RunErrors(TypedDict):
    """Tip errors of one run under each model of :func:`evaluate` (typing only), and
    per model its smallest stability margin over the run's rows (``None`` when none
    converged) and its ranges of rows near a snap and on an unstable branch (for
    ``"all"``: every run's)."""

    run: str
    rows: int
    mean_mm: List[float]
    max_mm: List[float]
    lowest_margin: List[Optional[float]]
    near_snap: List[List[MarginRange]]
    unstable: List[List[MarginRange]]

class Report:
    """The mismatch report of :func:`diagnose` or :func:`calibrate`: the JSON report
    ``ctr-cli diagnose --report`` writes (``docs/formats.md``: ``baseline``,
    ``findings``, ``final``, ``unexplained``; with this project's ``noise``,
    ``split``, ``located``, ``tried``, ``failed_rows``, ``stability``, ...), the
    summary the CLI prints and the fitted model.

    The attributes are fresh plain Python values on every access (changing them does
    not change the report). Immutable, comparable with ``==`` and picklable.
    """

    def to_dict(self) -> dict[str, Any]:
        """The report as plain dicts, lists, str, int, float and bool: equal to
        ``json.load`` of the file ``ctr-cli diagnose --report`` writes for the same
        robot, recording and options, to the last bit (a figure that does not exist,
        ``NaN`` in Rust, is ``None``, as JSON writes it)."""
    def to_json(self, indent: bool = True) -> str:
        """The report's JSON text: with ``indent`` exactly the file ``--report``
        writes (two-space indents, a final newline), else compact."""
    def summary(self) -> str:
        """The plain-language summary ``ctr-cli diagnose`` prints: the error of the
        user model and where it sits, each finding with its held-out gain, and what
        is left."""
    @property
    def fitted(self) -> Robot:
        """The fitted model: the robot with its ``[model]`` and the effects found (or
        calibrated) in ``[model.effects]``, fitted. ``fitted.to_toml()`` is the file
        ``ctr-cli diagnose --out`` writes, without its comment lines (what fitted it,
        and the findings by grade);
        ``fitted.fk(recording.joints)`` (per run with ``t_s=`` for time effects)
        gives the model's tips. Its :attr:`Robot.source` is the robot's with
        ``" (fitted)"``."""
    @property
    def fitted_with_empirical(self) -> Robot:
        """The fitted model with the report's labelled empirical correction in
        ``[model.empirical]`` (after any terms the robot file had): the file
        ``ctr-cli diagnose --with-empirical --out`` writes, without its comment lines;
        its ``fk`` applies the correction as ``ctr-cli fk`` does. The same as
        :attr:`fitted` when the recording is explained (no empirical term). Where the
        report's empirical term is the learned discrepancy (``report["empirical"]``
        with a ``band``) it is written as ``[model.discrepancy]`` and ``fk`` adds it
        along the rows (``band=True`` returns its 95 % band). Physics first: use it to
        predict, not to read causes from."""
    @property
    def fitted_established(self) -> Robot:
        """The fitted model with the established findings alone, refitted on the fit
        rows without the predictive ones (whose values the others may have leaned on):
        the file ``ctr-cli diagnose --established-only --out`` writes, without its
        comment lines."""
    @property
    def recording(self) -> str:
        """The recording's file name."""
    @property
    def effects(self) -> list[str]:
        """The ids of the effects found, in the order added."""
    @property
    def baseline(self) -> Figures:
        """The user model's figures."""
    @property
    def findings(self) -> list[Finding]:
        """The effects found, in the order added (for :func:`calibrate`: one per
        effect fitted, all with the same before and after)."""
    @property
    def final(self) -> Figures:
        """The fitted model's figures."""
    @property
    def unexplained(self) -> str:
        """What is left, in words (whether it is consistent with the noise)."""
    @property
    def noise(self) -> Noise:
        """The noise estimated from the data (second differences along the runs; of a
        static configuration set, from its repeats, or unknown where nothing repeats)."""
    @property
    def split(self) -> Split:
        """The split used."""
    @property
    def located(self) -> list[Statement]:
        """Where the user model's error sits, strongest pattern first."""
    @property
    def tried(self) -> list[Trial]:
        """Every candidate fitted, round by round (empty for :func:`calibrate`)."""
    @property
    def failed_rows(self) -> int:
        """Rows whose solve did not converge under the fitted model."""
    @property
    def explained(self) -> bool:
        """The verdict: ``True`` when the held-out residual with the found physics
        (tracker outliers set aside) is consistent with the noise estimate; ``False``
        when a part is left that no effect of the vocabulary accounts for
        (:attr:`unexplained` says where, :attr:`empirical` fits it)."""
    @property
    def uncertainty_method(self) -> str:
        """How the findings' ``ci95`` were computed (the covariance, the clusters, the
        quantile)."""
    @property
    def identifiability(self) -> list[str]:
        """What the data do not identify, in words, with the combinations they do
        identify; empty when every parameter is identified."""
    @property
    def correlated(self) -> list[Correlated]:
        """Pairs of fitted parameters correlated above 0.9."""
    @property
    def suggested_run(self) -> Optional[SuggestedRun]:
        """The run to record next when parameters are poorly identified (not
        identified alone, correlated above 0.9 with another effect's, or an interval
        wider than a quarter of their size): the candidate run on the recorded ranges
        whose simulated information shrinks their intervals most, with the intervals
        expected after it; ``None`` otherwise. ``ctr-cli diagnose --suggest-run``
        writes its joints."""
    @property
    def stability(self) -> Stability:
        """The rows where the user's or the fitted model is within the warning
        margin (``warn_margin=``, default 0.05 as ``ctr-cli fk --warn-margin``) of a
        snap or on an unstable branch, from the margins of the simulations the
        diagnosis made anyway: a jump in the data there is physics, not a tracker
        glitch. The summary says it in one line when a row is marked."""
    @property
    def empirical(self) -> Optional[dict[str, Any]]:
        """The labelled empirical correction fitted on top of the physics for what is
        left (``method``, ``terms``, ``rms_mm``, ``heldout_rms_mm``, ``dominant``; the
        learned discrepancy also ``inputs``, each with its ``length_scale``, and
        ``band``: ``median_sd_mm``, ``signal_mm``, ``noise_mm`` and
        ``heldout_coverage_95``), or ``None`` when the recording is explained. Not
        physics."""
    def __eq__(self, other: object) -> bool: ...
    def to_html(self) -> str:
        """The report as one self-contained HTML page: the verdict, the findings with
        their parameters and 95 % intervals, the error by run, the residual against
        the feature that located it, each run's measured and modelled tip paths, what
        is left and where, the suggested next run and the fitted robot file; inline
        SVG and CSS, nothing fetched, so it opens offline. The same bytes as
        ``ctr-cli diagnose --html`` for the same robot, recording and options (the
        report keeps the robot and the recording it was made from, and pickles with
        them). Strings from files are HTML-escaped.

        >>> open("report.html", "w", encoding="utf-8").write(report.to_html())  # doctest: +SKIP
        """
    def __eq__(self, other: object) -> bool: ...
    def __reduce__(
        self,
    ) -> tuple[object, tuple[str, str, Robot, str, Robot, Recording]]: ...

RecordingArg = Union[Recording, PathArg]

def diagnose(
    robot: Robot,
    recording: RecordingArg,
    *,
    holdout: Optional[str] = None,
    effects: Optional[Union[str, Iterable[str]]] = None,
    threads: Optional[int] = None,
    warn_margin: Optional[float] = None,
) -> Report:
    """Diagnoses the robot's model against a recording: ``ctr-cli diagnose``.

    Splits the rows (``holdout``), estimates the noise, locates the error, then adds
    the left-out effects that explain it, one at a time, each fitted and kept only
    when it lowers the error on the held-out rows; see ``docs/diagnosis.md`` and
    ``ctr_diagnosis``. The report equals the CLI's for the same inputs.

    ``recording``: a :class:`Recording` read for the robot's tube count, or a path
    (read with the robot's joint columns). ``holdout``: ``"blocks:K"`` (each run in
    contiguous blocks, one in K held out; ``None`` means ``"blocks:4"``) or
    ``"runs:LABEL,LABEL"`` (those runs held out whole), the CLI's ``--holdout``.
    ``effects``: the effect ids to try (a list, or a comma-separated str as the
    CLI's ``--effects``); ``None`` tries all ten. ``threads``: worker threads,
    ``None`` or 0 for all cores (results do not depend on it). ``warn_margin``: the
    rows where the user's or the fitted model has a stability margin below it are
    marked near a snap in :attr:`Report.stability` (``None``: 0.05, the CLI's
    ``--warn-margin`` default; 0 marks only rows on an unstable branch). The GIL is
    released while it runs (about a second for a thousand rows on two cores).

    Raises :class:`~ctr_py.InputError` with the CLI's message for an unknown effect
    id, a bad holdout string, a negative or non-finite ``warn_margin``, a holdout run label the recording lacks, a split
    leaving no fit or no held-out rows, a recording read for another tube count, or
    a model that cannot be simulated on the recording;
    :class:`~ctr_py.InputTypeError` for arguments of the wrong type; reading a path
    raises as :func:`read_recording`.
    """

def calibrate(
    robot: Robot,
    recording: RecordingArg,
    fit: Union[str, Iterable[str]],
    *,
    table: Optional[int] = None,
    holdout: Optional[str] = None,
    threads: Optional[int] = None,
    warn_margin: Optional[float] = None,
) -> Report:
    """Fits the parameters of the named effects together, without the search:
    ``ctr-cli calibrate --fit``. For a lab that knows what to identify: a clearance
    profile, the stiffness from tip deflections under known hung weights (a recording
    with ``fx_n, fy_n, fz_n``), ... Effects the model already has are refitted from
    their values. The report has one finding per effect (before: the user model;
    after: all fitted) and no ``tried``.

    ``table`` (3 to 72, with ``fit=["clearance"]``): the clearance as a smooth table
    of that many values per pair over one turn instead of a cosine profile.
    ``holdout``, ``threads`` and ``warn_margin`` as for :func:`diagnose`. Raises as
    :func:`diagnose`, and :class:`~ctr_py.InputError` for an empty ``fit``, a
    ``table`` out of range or an effect the recording cannot show (latency without
    ``t_s``, ...).
    """

def evaluate(
    robots: Union[Robot, Sequence[Robot]],
    recording: RecordingArg,
    *,
    warn_margin: Optional[float] = None,
) -> list[RunErrors]:
    """Mean and largest tip error per run for each model: ``ctr-cli evaluate``.

    One dict per run in file order, then one for the whole recording (``run ==
    "all"``), with ``mean_mm`` and ``max_mm`` lists in the order of ``robots``, and
    per model its ``lowest_margin`` and its ranges of rows within ``warn_margin`` of
    a snap (``near_snap``) or on an unstable branch (``unstable``), as
    :attr:`Report.stability` gives them (``None``: 0.05, the CLI's default). All
    robots must have the same tube count (the CLI's message otherwise), that of the
    recording.
    """
