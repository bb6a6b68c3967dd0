"""The runs behind ``scanclique match``, ``demo`` and ``validate``, as plain functions.

No typer, no rich: a script calls :func:`run_match`, :func:`run_demo` or
:func:`run_validate` and gets an immutable record (:class:`MatchRun`,
:class:`ValidateRun`) that the commands print with the row builders of
:mod:`scanclique.tools.reports`.

Examples
--------
>>> run = run_demo(data=False)
>>> run.names
('sim:a', 'sim:b')
>>> t_err, r_err = run.errors()
>>> bool(t_err < 0.1)
True
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import datasets
from ..config import MatchConfig, config_to_dict
from ..errors import DataNotFoundError, ScanError, ScanIndexError
from ..eval.success import RIGHT_ROTATION, RIGHT_TRANSLATION, is_right, is_success
from ..geometry import Pose2
from ..io import odometry_is_reference, poses_carried
from ..match import ScanMatch, match_prepared, match_scans, prepare_scan
from ..pairsets import pair_sets, relative_reference
from ..scan import Scan
from ..validation import (
    ACCEPTED,
    VERDICTS,
    OdometryNoise,
    Validation,
    validate_match,
)
from .loading import _label, load_scan_pair, odometry_path, read_options

__all__ = [
    "MatchRun",
    "ValidateRun",
    "run_match",
    "run_demo",
    "run_validate",
    "SUCCESS_TRANSLATION",
    "SUCCESS_ROTATION_DEG",
    "DEMO_INDICES",
    "DEMO_SEED",
]

log = logging.getLogger(__name__)

#: A pair is a success when the estimated pose is this close to the reference (DESIGN.md).
SUCCESS_TRANSLATION = RIGHT_TRANSLATION  # metres (the one rule: scanclique.eval.success)
SUCCESS_ROTATION_DEG = math.degrees(RIGHT_ROTATION)
DEMO_INDICES = (120, 121)
DEMO_SEED = 7


def _pose_dict(p: Pose2 | None) -> dict | None:
    return None if p is None else {"x": p.x, "y": p.y, "theta": p.theta}


@dataclass(frozen=True, slots=True, eq=False)
class MatchRun:
    """One ``scanclique match`` (or ``demo``): the two scans, the result and its context.

    Attributes
    ----------
    scan_a, scan_b : Scan
    match : ScanMatch
        ``match.pose`` maps points of B into A's frame.
    names : (str, str)
        ``"<log>:<index>"`` of each scan.
    config : MatchConfig
        The configuration used.
    notes : tuple of str
        Messages for the user (e.g. "a.txt holds 3 scans; using the first").
    reference : Pose2 or None
        The reference pose of B in A, ``ref_a.inverse() @ ref_b``, when both scans have a
        reference pose (a simulated pair: the true pose).
    validation : Validation or None
        The verdict on the match (paper §7; with the odometry when asked for). None when
        the run was built without one; :meth:`checked` computes it then.
    poses : str
        Which poses the scans carry (:func:`scanclique.io.poses_carried`): ``"reference
        and odometry"``, ``"odometry only"``, ``"reference only (the odometry fields
        repeat it)"``, ...
    """

    scan_a: Scan
    scan_b: Scan
    match: ScanMatch
    names: tuple[str, str]
    config: MatchConfig
    notes: tuple[str, ...] = ()
    reference: Pose2 | None = field(default=None)
    validation: Validation | None = field(default=None)
    poses: str = ""

    def checked(self) -> Validation:
        """:attr:`validation`, or the verdict without odometry when there is none."""
        return self.validation if self.validation is not None else validate_match(self.match)

    def errors(self) -> tuple[float, float] | None:
        """``(translation error m, rotation error rad)`` of ``match.pose`` against the
        reference, or None when either is missing."""
        if self.match.pose is None or self.reference is None:
            return None
        return self.match.pose.distance_to(self.reference)

    def verdict(self, against: str = "reference") -> str:
        """One line: the error against the reference and whether it is a success
        (within 0.20 m and 2 deg, the criterion of the benchmarks)."""
        if self.match.pose is None:
            return f"no pose: {self.match.reason}"
        e = self.errors()
        if e is None:
            return "pose found; no reference pose to compare with"
        t, r = e
        ok = is_success(t, r)
        return (
            f"error {t:.3f} m, {math.degrees(r):.2f} deg vs {against}: "
            f"{'success' if ok else 'FAILURE'} "
            f"(threshold {SUCCESS_TRANSLATION:.2f} m, {SUCCESS_ROTATION_DEG:g} deg)"
        )

    def to_dict(self) -> dict:
        """``match.to_dict()`` plus the scans, the reference pose, the errors, the notes and
        the configuration: JSON-ready."""
        out = self.match.to_dict()
        out["scan_a"] = {"name": self.names[0], "source": self.scan_a.source}
        out["scan_b"] = {"name": self.names[1], "source": self.scan_b.source}
        out["std"] = _std(self.match)
        out["reference"] = _pose_dict(self.reference)
        e = self.errors()
        out["error"] = (
            None
            if e is None
            else {"translation_m": e[0], "rotation_rad": e[1], "rotation_deg": math.degrees(e[1])}
        )
        out["notes"] = list(self.notes)
        out["poses"] = self.poses
        out["validation"] = self.checked().to_dict()
        out["config"] = config_to_dict(self.config)
        return out


def _registered(source) -> datasets.Dataset | None:
    """The registered data set ``source`` names or whose file it is, else None."""
    try:
        if isinstance(source, str) and not os.path.exists(source):
            key = datasets._canonical(source)
            return datasets.DATASETS[key] if key else None
        name = os.path.basename(os.fspath(source))
    except TypeError:
        return None
    for ds in datasets.DATASETS.values():
        if os.path.basename(ds.relpath) == name:
            return ds
    return None


def _pose_notes(source, scans, odometry: bool) -> tuple[bool, str, list[str]]:
    """(has_reference, poses carried, notes) of the scans of a run."""
    ds = _registered(source)
    has_ref = ds is None or ds.has_reference
    notes: list[str] = []
    if not has_ref:
        notes.append(
            f"{ds.name} carries odometry only: its x y theta are odometry, not a reference "
            f"pose (its reference is {ds.relations or 'not in the log'}); no error is computed"
        )
    elif odometry and odometry_is_reference(scans):
        msg = (
            "the odometry of these scans equals their reference pose (the log's odometry "
            "fields repeat the corrected pose): validating against the odometry uses ground "
            "truth, not raw odometry"
        )
        log.warning(msg, extra={"user_note": True})  # the CLI prints it as a note
        notes.append(msg)
    return has_ref, poses_carried(scans, has_ref), notes


def run_match(
    source: str | os.PathLike,
    a: str | int | None = None,
    b: str | int | None = None,
    config: MatchConfig | None = None,
    *,
    odometry: bool = False,
    noise: OdometryNoise | None = None,
    max_range: float | None = None,
    max_beams: int | None = None,
) -> MatchRun:
    """Load two scans (see :func:`load_scan_pair`), match B against A and validate the
    match (:func:`scanclique.validation.validate_match`): with the scans' odometry poses
    when ``odometry`` (and, for two scans of one log, the odometry of every scan between
    them for the distance travelled), else on the features alone.

    Raises
    ------
    ScanError
        ``odometry`` and a scan without an odometry pose.
    """
    cfg = config or MatchConfig()
    opts = read_options(max_range, max_beams)
    scan_a, scan_b, names, notes = load_scan_pair(source, a, b, **opts)
    m = match_scans(scan_a, scan_b, cfg)
    has_ref, poses, pose_notes = _pose_notes(source, (scan_a, scan_b), odometry)
    notes = [*notes, *pose_notes]
    if odometry:
        for scan, name in ((scan_a, names[0]), (scan_b, names[1])):
            if scan.odometry is None:
                raise ScanError(f"{name}: the scan has no odometry pose (--odometry)")
        path = odometry_path(source, a, b, **opts)
        v = validate_match(m, scan_a.odometry, scan_b.odometry, noise, path=path)
    else:
        v = validate_match(m)
    ref = relative_reference(scan_a, scan_b) if has_ref else None
    return MatchRun(scan_a, scan_b, m, names, cfg, tuple(notes), ref, v, poses)


def run_demo(config: MatchConfig | None = None, data: bool = True) -> MatchRun:
    """What ``make demo`` shows: Intel scans 120 and 121 when the Intel log is found
    (and ``data``), else a simulated pair (``simulate_pair(default_rng(7))``) whose true
    relative pose is the reference."""
    cfg = config or MatchConfig()
    if data:
        try:
            path = datasets.dataset_path("intel")
        except DataNotFoundError as exc:
            log.info("no real data: %s", exc)
        else:
            run = run_match(path, *DEMO_INDICES, config=cfg)
            names = tuple(f"intel:{i}" for i in DEMO_INDICES)
            return MatchRun(
                run.scan_a,
                run.scan_b,
                run.match,
                names,
                cfg,
                run.notes,
                run.reference,
                poses=run.poses,
            )
    from ..sim import simulate_pair

    pair = simulate_pair(np.random.default_rng(DEMO_SEED))
    m = match_scans(pair.scan_a, pair.scan_b, cfg)
    poses = poses_carried((pair.scan_a, pair.scan_b))
    return MatchRun(
        pair.scan_a, pair.scan_b, m, ("sim:a", "sim:b"), cfg, (), pair.pose_a_b, poses=poses
    )


def _std(m: ScanMatch) -> dict | None:
    if m.covariance is None:
        return None
    d = np.diag(np.asarray(m.covariance, dtype=float))
    s = [math.sqrt(v) if math.isfinite(v) and v >= 0 else None for v in d]
    return {"x": s[0], "y": s[1], "theta": s[2]}


@dataclass(frozen=True, slots=True, eq=False)
class ValidateRun:
    """One ``scanclique validate``: every pair of the pair sets of a log, matched and
    validated, against the reference poses.

    Attributes
    ----------
    name : str
        The log.
    records : tuple of dict
        One per pair: ``set``, ``i``, ``j``, ``verdict``, ``right`` (the verdict's pose
        within 0.2 m and 2 deg of the reference), ``match_right`` (the match's own pose),
        ``ambiguous`` (the match's flag), ``hypothesis`` and ``mahalanobis_sq``.
    odometry : bool
        Whether the log's odometry was used.
    noise : OdometryNoise
    notes : tuple of str
        Messages for the user (the log's odometry repeats its reference poses, ...).
    """

    name: str
    records: tuple[dict, ...]
    odometry: bool
    noise: OdometryNoise
    notes: tuple[str, ...] = ()

    def counts(self, set_name: str | None = None) -> dict:
        """``{(right, verdict): count}`` plus ``precision`` and ``recall`` of
        ``accepted`` (over one pair set, or all)."""
        recs = [r for r in self.records if set_name is None or r["set"] == set_name]
        c = {(right, v): 0 for right in (True, False) for v in VERDICTS}
        for r in recs:
            c[(r["right"], r["verdict"])] += 1
        acc_r, acc_w = c[(True, ACCEPTED)], c[(False, ACCEPTED)]
        n_right = sum(c[(True, v)] for v in VERDICTS)
        amb = [r for r in recs if r["ambiguous"]]
        return {
            "n": len(recs),
            "table": c,
            "precision": acc_r / (acc_r + acc_w) if acc_r + acc_w else math.nan,
            "recall": acc_r / n_right if n_right else math.nan,
            "ambiguous": len(amb),
            "ambiguous_to_right": sum(1 for r in amb if r["verdict"] == ACCEPTED and r["right"]),
        }

    def to_dict(self) -> dict:
        sets = sorted({r["set"] for r in self.records})

        def summary(s):
            c = self.counts(s)
            table = {
                ("right" if right else "wrong"): {v: c["table"][(right, v)] for v in VERDICTS}
                for right in (True, False)
            }
            return {**{k: v for k, v in c.items() if k != "table"}, "table": table}

        return {
            "log": self.name,
            "notes": list(self.notes),
            "odometry": self.odometry,
            "noise": {f: getattr(self.noise, f) for f in self.noise.__dataclass_fields__},
            "all": summary(None),
            "sets": {s: summary(s) for s in sets},
            "pairs": list(self.records),
        }


def run_validate(
    source: str | os.PathLike,
    *,
    cap: int | None = 50,
    sets: Sequence[str] | None = None,
    odometry: bool = True,
    noise: OdometryNoise | None = None,
    config: MatchConfig | None = None,
    seed: int = 0,
    progress: Callable[[int, int], None] | None = None,
    max_range: float | None = None,
    max_beams: int | None = None,
) -> ValidateRun:
    """Match and validate the pair sets of a log with reference poses (what
    ``scanclique validate`` prints; :func:`scanclique.pairsets.pair_sets`).

    Parameters
    ----------
    source : str or path-like
        A log with reference poses (and odometry poses, with ``odometry``).
    cap : int or None
        At most this many pairs per set (None: all).
    sets : sequence of str, optional
        Some of ``"consecutive"``, ``"skip3"``, ``"revisit"`` (default all).
    odometry : bool
        Validate with the log's odometry along the path between the two scans.
    noise : OdometryNoise, optional
    config : MatchConfig, optional
    seed : int
        For the random draw of revisit pairs.
    progress : callable(done, total), optional
        Called after each pair.

    Raises
    ------
    ScanError
        A scan without a reference pose (or, with ``odometry``, without an odometry pose).
    """
    cfg = config or MatchConfig()
    noise = noise or OdometryNoise()
    scans = datasets.load_log(source, **read_options(max_range, max_beams))
    has_ref, _, notes = _pose_notes(source, scans, odometry)
    if not has_ref:
        raise ScanError(
            f"{os.fspath(source)}: carries no reference pose (its x y theta are odometry): "
            "validate needs reference poses"
        )
    if odometry:
        for k, scan in enumerate(scans):
            if scan.odometry is None:
                raise ScanError(
                    f"{os.fspath(source)}: scan {k} has no odometry pose (use --no-odometry)"
                )
    all_sets = pair_sets(scans, cap, seed)
    wanted = list(all_sets) if sets is None else list(sets)
    for name in wanted:
        if name not in all_sets:
            raise ScanIndexError(f"unknown pair set {name!r}: choose from {', '.join(all_sets)}")
    jobs = [(name, i, j) for name in wanted for i, j in all_sets[name]]
    prepared: dict[int, Any] = {}
    records = []
    for n_done, (set_name, i, j) in enumerate(jobs, start=1):
        for k in (i, j):
            if k not in prepared:
                prepared[k] = prepare_scan(scans[k], cfg)
        m = match_prepared(prepared[i], prepared[j], cfg)
        ref = scans[i].reference.inverse() @ scans[j].reference
        if odometry:
            lo, hi = min(i, j), max(i, j)
            path = [s.odometry for s in scans[lo : hi + 1]]
            v = validate_match(m, scans[i].odometry, scans[j].odometry, noise, path=path)
        else:
            v = validate_match(m)
        records.append(
            {
                "set": set_name,
                "i": i,
                "j": j,
                "verdict": v.verdict,
                "right": is_right(v.pose, ref),
                "match_right": is_right(m.pose, ref),
                "ambiguous": m.ambiguous,
                "hypothesis": v.hypothesis,
                "mahalanobis_sq": v.mahalanobis_sq,
            }
        )
        if progress is not None:
            progress(n_done, len(jobs))
    return ValidateRun(_label(source), tuple(records), odometry, noise, tuple(notes))
