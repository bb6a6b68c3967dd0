"""The registry of real data sets: where the shared logs live and what they are.

The data are public research logs recorded and published by others; they are not shipped
with scanclique. They are looked for in, in order:

1. the directory named by the environment variable ``SCANCLIQUE_DATA`` (when set, only
   there);
2. ``../shared/data`` beside the repository checkout (found from this file's location:
   ``src/scanclique/`` -> repository root -> ``../shared/data``);
3. ``../shared/data`` relative to the current directory.

Expected layout under the data directory::

    carmen/intel-odometry.log.gz         carmen/csail-odometry.log.gz
    carmen/freiburg-079-corrected.log.gz relations/intel.relations
    carmen/intel.clf.bz2                 relations/fr079.relations
    carmen/fr079.clf.bz2                 dimacs/*.clq

Examples
--------
>>> sorted(DATASETS)
['csail', 'fr079-raw', 'freiburg', 'intel', 'intel-raw']
>>> DATASETS["intel"].beams, DATASETS["intel"].scans, DATASETS["intel"].has_odometry
(180, 910, True)
"""

from __future__ import annotations

import functools
import logging
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

from .errors import ArgumentError, DataNotFoundError
from .io import read_scans
from .scan import Scan

__all__ = [
    "ENV_VAR",
    "Dataset",
    "DATASETS",
    "ALIASES",
    "data_dir",
    "data_dir_candidates",
    "dataset_path",
    "resolve_log",
    "registered_name",
    "load_log",
    "clear_cache",
    "relations_path",
    "log_relations",
    "dimacs_dir",
]

logger = logging.getLogger(__name__)

ENV_VAR = "SCANCLIQUE_DATA"

_RADISH = "the Radish robotics data set repository (radish.sourceforge.net)"
_FREIBURG = (
    "the Freiburg SLAM benchmark, 'SLAM evaluation' pages of the University of Freiburg "
    "(ais.informatik.uni-freiburg.de/slamevaluation), Kümmerle et al. 2009"
)


@dataclass(frozen=True, slots=True)
class Dataset:
    """One registered log.

    Attributes
    ----------
    name : str
        Registry key, e.g. ``"intel"``.
    relpath : str
        Path under the data directory, e.g. ``"carmen/intel-odometry.log.gz"``.
    scans : int
        Number of laser scans in the log.
    beams : int
        Beams per scan.
    has_odometry : bool
        Whether the odometry fields hold raw (drifting) odometry distinct from the reference
        poses. False when they merely repeat the corrected pose.
    description : str
        What the log is and what its poses and timestamps mean.
    source : str
        Where it is published, in words, so that a user can fetch it.
    has_reference : bool
        Whether the log's poses include a corrected reference pose. False for the raw logs
        of the SLAM benchmark, whose poses are all odometry (``Scan.reference`` then repeats
        an odometry pose and is no ground truth); their reference is the relations file.
    relations : str or None
        Path under the data directory of the Kuemmerle et al. relations for this log.
    """

    name: str
    relpath: str
    scans: int
    beams: int
    has_odometry: bool
    description: str
    source: str
    has_reference: bool = True
    relations: str | None = None


DATASETS: Mapping[str, Dataset] = MappingProxyType(
    {
        "intel": Dataset(
            name="intel",
            relpath="carmen/intel-odometry.log.gz",
            scans=910,
            beams=180,
            has_odometry=True,
            description=(
                "Intel Research Lab, Seattle: CARMEN FLASER log, 180 beams 1 degree apart. "
                "x y theta are corrected reference poses, odom_x odom_y odom_theta raw wheel "
                "odometry (drifts by tens of metres); absolute timestamps, matching "
                "relations/intel.relations."
            ),
            source=f"{_RADISH}; corrected poses and relations from {_FREIBURG}",
            relations="relations/intel.relations",
        ),
        "csail": Dataset(
            name="csail",
            relpath="carmen/csail-odometry.log.gz",
            scans=406,
            beams=361,
            has_odometry=True,
            description=(
                "MIT CSAIL building: CARMEN FLASER log, 361 beams 0.5 degree apart. "
                "x y theta are corrected reference poses, odometry is raw and in an offset "
                "frame; timestamps follow scan order."
            ),
            source=f"{_RADISH}; corrected poses from {_FREIBURG}",
        ),
        "freiburg": Dataset(
            name="freiburg",
            relpath="carmen/freiburg-079-corrected.log.gz",
            scans=4791,
            beams=360,
            has_odometry=False,
            description=(
                "Freiburg building 079: CARMEN log (FLASER, ODOM, PARAM, NEFF), 360 beams "
                "0.5 degree apart. Corrected poses only: the odometry fields equal the "
                "corrected pose. Relative timestamps. Large: good for scale tests."
            ),
            source=f"{_FREIBURG}; also in {_RADISH}",
        ),
        "intel-raw": Dataset(
            name="intel-raw",
            relpath="carmen/intel.clf.bz2",
            scans=13631,
            beams=180,
            has_odometry=True,
            description=(
                "The raw Intel Research Lab log of the SLAM benchmark of Kuemmerle et al. "
                "2009 (bzip2 as published): FLASER poses are wheel odometry only, there is no "
                "reference pose in the log; the reference is relations/intel.relations (2984 "
                "relations, joining FLASER timestamps exactly)."
            ),
            source=f"{_FREIBURG} (SLAM benchmark raw logs)",
            has_reference=False,
            relations="relations/intel.relations",
        ),
        "fr079-raw": Dataset(
            name="fr079-raw",
            relpath="carmen/fr079.clf.bz2",
            scans=4934,
            beams=360,
            has_odometry=True,
            description=(
                "The raw Freiburg building 079 log of the SLAM benchmark (bzip2): FLASER x y "
                "theta is the laser's odometry pose, odom_* the robot's; no reference pose in "
                "the log; the reference is relations/fr079.relations (1685 relations)."
            ),
            source=f"{_FREIBURG} (SLAM benchmark raw logs)",
            has_reference=False,
            relations="relations/fr079.relations",
        ),
    }
)
"""Registered logs by name."""

ALIASES: Mapping[str, str] = MappingProxyType(
    {
        "freiburg-079": "freiburg",
        "intel-lab": "intel",
        "intel.clf": "intel-raw",
        "fr079": "fr079-raw",
        "fr079.clf": "fr079-raw",
    }
)
"""Other accepted names."""

_RELATIONS = "relations/intel.relations"
_DIMACS = "dimacs"


def _repo_root() -> Path:
    # src/scanclique/datasets.py -> parents[0] = scanclique, [1] = src, [2] = repository root
    return Path(__file__).resolve().parents[2]


def data_dir_candidates() -> list[Path]:
    """Directories :func:`data_dir` considers, in order (``SCANCLIQUE_DATA`` alone when set)."""
    env = os.environ.get(ENV_VAR)
    if env:
        return [Path(env).expanduser()]
    found = [_repo_root().parent / "shared" / "data", Path.cwd().parent / "shared" / "data"]
    # once each (run from the checkout, both are the same directory)
    return [c for k, c in enumerate(found) if c.resolve() not in {d.resolve() for d in found[:k]}]


def data_dir() -> Path:
    """The data directory: ``$SCANCLIQUE_DATA``, else ``../shared/data`` by the checkout or cwd.

    Returns the first candidate that is a directory, or the first candidate when none
    exists (so that messages can say where the data were looked for). Never raises.
    """
    candidates = data_dir_candidates()
    for c in candidates:
        if c.is_dir():
            return c
    return candidates[0]


def _looked_in() -> str:
    return ", ".join(str(c) for c in data_dir_candidates())


def _not_found(what: str, relpath: str, source: str | None) -> DataNotFoundError:
    msg = (
        f"{what} not found: looked for {relpath} in {_looked_in()}. "
        f"Set {ENV_VAR} to the directory that holds it"
    )
    if source:
        msg += f"; the data are public: {source}"
    return DataNotFoundError(msg + ".")


def _canonical(name: str) -> str | None:
    key = name.strip().lower()
    key = ALIASES.get(key, key)
    return key if key in DATASETS else None


def _first_file(relpath: str) -> Path | None:
    """``relpath`` under the first data directory candidate that holds it as a file."""
    for base in data_dir_candidates():
        p = base / relpath
        if p.is_file():
            return p
    return None


def dataset_path(name: str) -> Path:
    """The file of a registered log.

    Parameters
    ----------
    name : str
        A key of :data:`DATASETS` (or of :data:`ALIASES`).

    Raises
    ------
    DataNotFoundError
        If the name is not registered, or the file is not there; the message says what was
        looked for, where, how to set ``SCANCLIQUE_DATA`` and where the data are published.
    """
    key = _canonical(name)
    if key is None:
        raise DataNotFoundError(
            f"unknown data set {name!r}: registered are {', '.join(sorted(DATASETS))}"
        )
    ds = DATASETS[key]
    p = _first_file(ds.relpath)
    if p is None:
        raise _not_found(f"data set {key!r}", ds.relpath, ds.source)
    return p


def resolve_log(path_or_name: str | os.PathLike) -> Path:
    """A registered name (``"intel"``) or a path, as the path of an existing file.

    Raises
    ------
    DataNotFoundError
        If it is neither an existing file nor a registered name (or the registered file is
        missing).
    """
    if not isinstance(path_or_name, (str, os.PathLike)):
        raise ArgumentError(f"expected a path or a registered data set name, got {path_or_name!r}")
    if isinstance(path_or_name, str) and _canonical(path_or_name) is not None:
        if not Path(path_or_name).is_file():
            return dataset_path(path_or_name)
    p = Path(path_or_name).expanduser()
    if p.exists():  # a directory, FIFO or device: the reader refuses it by name
        return p
    raise DataNotFoundError(
        f"{os.fspath(path_or_name)!r} is neither an existing file nor a registered data set "
        f"({', '.join(sorted(DATASETS))})"
    )


def registered_name(path_or_name: str | os.PathLike) -> str | None:
    """The registered name of a log given by name (an alias gives its canonical name) or by
    the path of a registered data set's file, else None.

    So that a log added to a place database once by name and once by path is one log:

    >>> registered_name("intel-lab"), registered_name("no-such-log.txt")
    ('intel', None)
    """
    if isinstance(path_or_name, str):
        key = _canonical(path_or_name)
        if key is not None and not Path(path_or_name).is_file():
            return key
    p = Path(path_or_name).expanduser()
    if not p.is_file():
        return None
    for key, ds in DATASETS.items():
        for base in data_dir_candidates():
            f = base / ds.relpath
            if f.is_file() and os.path.samefile(f, p):
                return key
    return None


@functools.lru_cache(maxsize=8)
def _load_cached(path: str, mtime_ns: int, size: int, options: tuple) -> tuple[Scan, ...]:
    logger.debug("reading %s", path)
    return tuple(read_scans(path, **dict(options)))


def load_log(path_or_name: str | os.PathLike, **kwargs) -> list[Scan]:
    """All scans of a registered log (or of a file), cached in-process.

    Parameters
    ----------
    path_or_name : str or path-like
        A registered name (``"intel"``, ``"csail"``, ``"freiburg"``) or a path.
    **kwargs
        Passed to :func:`scanclique.io.read_scans` (``strict``, ``max_beams``,
        ``max_range``); part of the cache key, so must be hashable.

    Returns
    -------
    list of Scan
        A new list each call; the (immutable) scans are shared between calls. The cache
        is keyed by the resolved path, its modification time and size, and the options.

    Raises
    ------
    DataNotFoundError
        See :func:`resolve_log`.
    ParseError
        If the file is malformed.
    """
    p = resolve_log(path_or_name).resolve()
    st = p.stat()
    return list(_load_cached(str(p), st.st_mtime_ns, st.st_size, tuple(sorted(kwargs.items()))))


def clear_cache() -> None:
    """Forget the scans cached by :func:`load_log`."""
    _load_cached.cache_clear()


def relations_path() -> Path:
    """``relations/intel.relations`` (Kümmerle et al. 2009 relations for the Intel log).

    Raises
    ------
    DataNotFoundError
        If the file is not found.
    """
    p = _first_file(_RELATIONS)
    if p is None:
        raise _not_found("Intel relations file", _RELATIONS, _FREIBURG)
    return p


def log_relations(path_or_name: str | os.PathLike) -> Path | None:
    """The relations file (Kümmerle et al. 2009) of a registered log, given by name or by
    the path of its file; None for a log without relations, one not registered, or when
    the relations file is not in the data directory.

    >>> log_relations("no-such-log.clf") is None
    True
    """
    key = registered_name(path_or_name)
    rel = None if key is None else DATASETS[key].relations
    return None if rel is None else _first_file(rel)


def dimacs_dir() -> Path:
    """The directory of DIMACS maximum clique benchmark graphs (``dimacs/*.clq``).

    Raises
    ------
    DataNotFoundError
        If the directory is not found.
    """
    for base in data_dir_candidates():
        p = base / _DIMACS
        if p.is_dir():
            return p
    raise _not_found(
        "DIMACS graph directory",
        _DIMACS,
        "the second DIMACS implementation challenge benchmark graphs (.clq files)",
    )
