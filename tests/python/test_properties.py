"""Property tests of the ctr_py boundary (hypothesis): arrays of any shape, dtype,
memory layout and content, and any robot text, either give results of the documented
shapes or raise a typed ``ctr_py`` exception (a ``CtrError``), never crash the
interpreter or raise anything else.

Case counts: 150 examples per test (``HYPOTHESIS_MAX_EXAMPLES`` overrides them, for
longer local runs). The examples are the same on every run (the ``ci`` profile of
``conftest.py``); ``HYPOTHESIS_PROFILE=explore`` draws fresh ones.
"""

import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import ctr_py
from conftest import REPO

EXAMPLES = int(os.environ.get("HYPOTHESIS_MAX_EXAMPLES", "150"))
SETTINGS = settings(
    max_examples=EXAMPLES,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)

ROBOT = ctr_py.Robot.from_toml(REPO / "data" / "robots" / "nitinol3.toml")

# every numpy dtype kind the boundary may meet
DTYPES = st.one_of(
    hnp.floating_dtypes(),
    hnp.integer_dtypes(),
    hnp.unsigned_integer_dtypes(),
    hnp.boolean_dtypes(),
    hnp.complex_number_dtypes(),
    hnp.datetime64_dtypes(),
    hnp.unicode_string_dtypes(),
    hnp.byte_string_dtypes(),
)
SHAPES = hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=8)
ELEMENTS = st.floats(allow_nan=True, allow_infinity=True, width=64) | st.sampled_from(
    [0.0, -0.0, 1e308, -1e308, 5e-324, 20.0, 50.0, 80.0, 180.0, -720.0]
)


def arrays():
    """Arrays of any dtype and shape; float arrays of plausible and extreme values, in
    C order, Fortran order, or viewed with steps and negative strides."""
    plain = hnp.arrays(DTYPES, SHAPES)
    floats = hnp.arrays(np.float64, SHAPES, elements=ELEMENTS)
    fortran = floats.map(np.asfortranarray)
    strided = hnp.arrays(np.float64, hnp.array_shapes(min_dims=2, max_dims=2, min_side=2, max_side=12), elements=ELEMENTS).map(
        lambda a: a[::-2, ::2]
    )
    rows = st.lists(
        st.lists(ELEMENTS, min_size=6, max_size=6), min_size=0, max_size=5
    ).map(lambda r: np.array(r, dtype=np.float64).reshape(-1, 6))
    return st.one_of(plain, floats, fortran, strided, rows)


def others():
    """What else may be passed where an array is wanted."""
    return st.one_of(
        st.none(),
        st.text(max_size=5),
        st.integers(),
        st.lists(st.one_of(st.floats(), st.text(max_size=2), st.none()), max_size=7),
        st.dictionaries(st.text(max_size=2), st.integers(), max_size=2),
    )


def outcome(call):
    """The result of `call()`, or its exception if a ctr_py one; anything else fails."""
    try:
        return call()
    except ctr_py.CtrError as e:
        # one line, located at the argument
        assert "\n" not in str(e), str(e)
        return e


@SETTINGS
@given(q=st.one_of(arrays(), others()))
def test_fk_takes_any_input_or_raises_typed(q):
    got = outcome(lambda: ROBOT.fk(q, on_error="mark"))
    if isinstance(got, Exception):
        return
    pos, quat, status, residual = got
    a = np.asarray(q)
    batched = a.ndim == 2
    m = a.shape[0] if batched else None
    assert pos.shape == ((m, 3) if batched else (3,))
    assert quat.shape == ((m, 4) if batched else (4,))
    # results are finite numbers whatever the status (no NaN passed on)
    assert np.all(np.isfinite(pos)) and np.all(np.isfinite(quat))


@SETTINGS
@given(q=st.one_of(arrays(), others()))
def test_jacobian_and_backbone_take_any_input_or_raise_typed(q):
    got = outcome(lambda: ROBOT.jacobian(q))
    if not isinstance(got, Exception):
        assert got.shape[-2:] == (6, 6)
    got = outcome(lambda: ROBOT.backbone(q))
    if not isinstance(got, Exception):
        assert got.ndim == 2 and got.shape[1] == 3 and np.all(np.isfinite(got))


@settings(max_examples=max(EXAMPLES // 3, 10), deadline=None)
@given(
    targets=st.one_of(
        hnp.arrays(np.float64, st.sampled_from([(3,), (7,), (2, 3), (0, 3), (1, 7), (4,), (2, 2)]), elements=ELEMENTS),
        others(),
    ),
    tolerance=st.one_of(st.just(1e-4), st.floats(allow_nan=True, allow_infinity=True)),
    restarts=st.one_of(st.just(2), st.integers(min_value=-5, max_value=3)),
)
def test_ik_takes_any_input_or_raises_typed(targets, tolerance, restarts):
    got = outcome(
        lambda: ROBOT.ik(targets, tolerance_mm=tolerance, restarts=restarts, max_iterations=20)
    )
    if isinstance(got, Exception):
        return
    q, residual, status = got
    assert np.all(np.isfinite(q))


@SETTINGS
@given(text=st.one_of(st.text(max_size=400), st.binary(max_size=200).map(lambda b: b.decode("latin-1"))))
def test_robot_text_parses_or_raises_typed(text):
    got = outcome(lambda: ctr_py.Robot.from_toml_str(text, "fuzz.toml"))
    if isinstance(got, Exception):
        assert str(got).startswith("fuzz.toml"), str(got)


@SETTINGS
@given(
    seed=st.sampled_from(sorted((REPO / "data" / "robots").glob("*.toml"))),
    cut=st.integers(min_value=0, max_value=2000),
    insert=st.sampled_from(["=", "[", "\"", "\n", "nan", "-1", "[[tube]]", "\x00", "é", "1e999"]),
)
def test_mutated_robot_files_parse_or_raise_typed(seed, cut, insert):
    text = seed.read_text()
    cut = cut % (len(text) + 1)
    got = outcome(lambda: ctr_py.Robot.from_toml_str(text[:cut] + insert + text[cut:], "m.toml"))
    if isinstance(got, ctr_py.Robot):
        # a robot that validates round trips through its TOML
        assert ctr_py.Robot.from_toml_str(got.to_toml(), "m.toml") == got


def test_a_large_broadcast_batch_solves():
    """200,000 rows of a zero-stride (broadcast) array solve, to the same tip within the
    solver's tolerance (rows are warm-started in chunks)."""
    q = np.broadcast_to(np.array([20.0, 0, 50, 0, 80, 90]), (200_000, 6))
    pos, quat = ROBOT.fk(q, threads=2)
    assert pos.shape == (200_000, 3) and np.allclose(pos, pos[0], atol=1e-6)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"restarts": -1}, r"^restarts: -1 is not in 0\.\.=4294967295$"),
        ({"threads": -1}, r"^threads: -1 is not in 0\.\.=1024 \(0 = all cores\)$"),
        ({"chunk_rows": 2**70}, r"^chunk_rows: 1180591620717411303424 is not in 0\.\.="),
        ({"max_iterations": 1.5}, r"^max_iterations: 1\.5 is not an integer$"),
        ({"max_iterations": 0}, r"^max_iterations: 0 must be >= 1$"),
        ({"threads": "2"}, r"^threads: '2' is not an integer$"),
    ],
)
def test_counts_out_of_range_raise_input_error(kwargs, message):
    """Found by test_ik_takes_any_input_or_raises_typed: ``restarts=-1`` (and a negative
    ``threads``, a huge ``chunk_rows``) raised Python's ``OverflowError`` from the
    argument conversion, a float or a string its ``TypeError``: now ``InputError``s
    naming the argument."""
    with pytest.raises(ctr_py.InputError, match=message):
        ROBOT.ik([0.0, 0.0, 90.0], **kwargs)
    if "threads" in kwargs:
        with pytest.raises(ctr_py.InputError, match=message):
            ROBOT.fk([20.0, 0, 50, 0, 80, 90], **kwargs)
        with pytest.raises(ctr_py.InputError, match=message):
            ROBOT.jacobian([20.0, 0, 50, 0, 80, 90], **kwargs)
