"""One exception hierarchy for everything scanclique raises on purpose.

Every error a user can cause derives from :class:`ScanCliqueError`, so a caller can
catch that one class. Messages name the file, line and field where there is one,
and say what was expected and what was found, e.g.
``"intel.log:1042: FLASER expects 180 ranges, found 179"``.
"""

from __future__ import annotations

from contextlib import contextmanager

__all__ = [
    "ScanCliqueError",
    "ParseError",
    "ScanError",
    "ConfigError",
    "DataNotFoundError",
    "GraphError",
    "ScanIndexError",
    "PlaceDatabaseError",
    "ArgumentError",
    "StepError",
    "PoseGraphError",
    "solving",
]


class ScanCliqueError(Exception):
    """Root of every exception scanclique raises deliberately."""


class ParseError(ScanCliqueError, ValueError):
    """A file could not be read: names the file, the 1-based line and the field.

    Parameters
    ----------
    path : str
        The file (as given by the user).
    line : int or None
        1-based line number, None when the error concerns the file as a whole.
    message : str
        What was expected and what was found.
    field : str or None
        The field of the record that was wrong, when there is one.
    """

    def __init__(self, path: str, line: int | None, message: str, field: str | None = None):
        self.path = str(path)
        self.line = line
        self.field = field
        self.reason = message
        where = self.path if line is None else f"{self.path}:{line}"
        what = f"{field}: {message}" if field else message
        super().__init__(f"{where}: {what}")


class ScanError(ScanCliqueError, ValueError):
    """A scan (or a pair of arrays meant as one) is inconsistent: shapes, limits, poses."""


class ConfigError(ScanCliqueError, ValueError):
    """A configuration value is out of range, of the wrong type, or unknown."""


class DataNotFoundError(ScanCliqueError, FileNotFoundError):
    """A data set or file that was asked for is not where it was looked for."""


class GraphError(ScanCliqueError, ValueError):
    """A graph given to the clique solver is malformed (not square, not symmetric, self loops)."""


class ScanIndexError(ScanCliqueError, IndexError):
    """A scan index outside the log, or a scan file holding no scan."""


class PlaceDatabaseError(ScanCliqueError):
    """A place database (``scanclique.places``) cannot be used: not a place database, a
    newer schema, a corrupted file or record, or a configuration incompatible with the
    one its places were prepared with. The message names the file and what was wrong."""


class ArgumentError(ScanCliqueError, TypeError):
    """A function of the public API was given an argument of the wrong type or kind (e.g.
    ``read_scans(None)``); the message names the argument and what it got."""


class StepError(ScanCliqueError, ValueError):
    """An EKF-SLAM input (``scanclique.slam``) is inconsistent: a step's time, control,
    observation or attribute that is not finite, a range not above 0, a shape that does not
    fit, steps out of time order, or an association's arrays that are not finite. The
    message names the step (its time, or its index in the sequence) and the field."""


class PoseGraphError(ScanCliqueError, RuntimeError):
    """The pose graph of a map (or the EKF-SLAM smoother's factor graph) could not be
    solved (GTSAM found its linear system indeterminate): an edge's uncertainty so far
    from the others' that the solver loses the scale, as odometry in millimetres gives.
    The message names what was being solved, GTSAM's words and what to check."""


@contextmanager
def solving(what: str, hint: str):
    """Run GTSAM's solver calls in the block; its ``RuntimeError`` (an indeterminate
    linear system) becomes a :class:`PoseGraphError` naming ``what``, GTSAM's first line
    and ``hint`` (what the user should check)."""
    try:
        yield
    except RuntimeError as e:
        says = next((line.strip() for line in str(e).splitlines() if line.strip()), "")
        raise PoseGraphError(
            f"{what}: GTSAM could not solve the pose graph ({says}): one edge's uncertainty "
            f"is too far from the others' for the solver. {hint}"
        ) from e
