"""The exceptions ``ctr_py`` raises.

Every message is one line, ``where: what was found and what was wanted``: exactly the
line ``ctr-cli`` prints after ``error:`` for a bad file (``robot.toml:12:21: tube 2:
...``). For arrays the location names the argument and, in a batch, the row
(``q[41]: s2_mm = 20 must be >= s1_mm = 30 (...)`` where the CLI says
``joints.csv:43: ...``); what follows it is the CLI's text.
"""


class CtrError(Exception):
    """Base class of every error ``ctr_py`` raises."""


class InputError(CtrError, ValueError):
    """Bad input: a robot file that does not parse or validate, joints outside the
    robot's range, NaN or infinite values, arrays of the wrong shape, unknown options."""


class InputTypeError(InputError, TypeError):
    """An array whose dtype is not a real number type (bool, complex, str, object).
    Integer and other float arrays are converted to float64 instead."""


class FileError(CtrError, OSError):
    """A file that cannot be read (missing, unreadable, not UTF-8)."""


class SolverError(CtrError, RuntimeError):
    """A solve that did not converge (with ``on_error="fail"``, the default)."""
