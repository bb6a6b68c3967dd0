"""The ``scanclique`` command: a thin shell over library functions.

Each command's work is a plain function of this module that scripts can call the same way
(:func:`load_scan`, :func:`load_scan_pair`, :func:`run_match`, :func:`run_demo`,
:func:`match_rows`, :func:`feature_rows`); the typer commands only parse arguments and
print. Errors a user can cause (a missing file, a scan index out of range, a malformed
configuration) end the command with one line on stderr and exit code 2, never a traceback.

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

import json
import logging
import math
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from .. import __version__, datasets
from ..config import MatchConfig, config_to_dict, paper_config
from ..errors import DataNotFoundError, ScanCliqueError, ScanError, ScanIndexError
from ..features import POINT_LABEL_NAMES, Features, extract_features
from ..geometry import Pose2
from ..match import STAGES, ScanMatch, match_prepared, match_scans, prepare_scan
from ..scan import Scan
from ..validation import (
    ACCEPTED,
    VERDICTS,
    OdometryNoise,
    Validation,
    is_right,
    pair_sets,
    validate_match,
)

__all__ = [
    "ScanIndexError",
    "MatchRun",
    "ValidateRun",
    "load_scan",
    "load_scan_pair",
    "load_config",
    "run_match",
    "run_demo",
    "run_validate",
    "odometry_path",
    "validation_rows",
    "confusion_rows",
    "match_rows",
    "feature_rows",
    "features_to_dict",
    "app",
    "main",
]

log = logging.getLogger(__name__)

#: A pair is a success when the estimated pose is this close to the reference (DESIGN.md).
SUCCESS_TRANSLATION = 0.20  # metres
SUCCESS_ROTATION_DEG = 2.0
DEMO_INDICES = (120, 121)
DEMO_SEED = 7
KINDS = (*POINT_LABEL_NAMES.values(), "line")


# ---------------------------------------------------------------------------------------
# Library side: plain functions the commands call
# ---------------------------------------------------------------------------------------
def _parse_index(text: str | int, what: str) -> int:
    if isinstance(text, int):
        return text
    try:
        return int(str(text).strip())
    except ValueError:
        raise ScanIndexError(f"{what} must be an integer scan index, got {text!r}") from None


def _label(source: str | os.PathLike) -> str:
    """A short name for messages: a registered name as given, a file by its name."""
    s = os.fspath(source)
    return s if not Path(s).exists() and "/" not in s else Path(s).name


def load_scan(source: str | os.PathLike, index: int | None = None) -> tuple[Scan, str, list[str]]:
    """One scan of a log (a path or a registered name such as ``"intel"``).

    ``index`` None means the file holds one scan; if it holds several the first is used
    and a note says so.

    Returns
    -------
    (scan, name, notes)
        ``name`` is ``"<label>:<index>"``; ``notes`` are messages for the user.

    Raises
    ------
    DataNotFoundError
        No such file or registered data set.
    ParseError
        The file is malformed.
    ScanIndexError
        ``index`` out of range, or no scan in the file.
    """
    scans = datasets.load_log(source)
    label = _label(source)
    notes: list[str] = []
    if not scans:
        raise ScanIndexError(f"{os.fspath(source)}: holds no scan")
    if index is None:
        if len(scans) > 1:
            notes.append(f"{os.fspath(source)} holds {len(scans)} scans; using the first (index 0)")
        index = 0
    elif not 0 <= index < len(scans):
        raise ScanIndexError(
            f"{os.fspath(source)}: scan index {index} out of range: "
            f"the log has {len(scans)} scans (0..{len(scans) - 1})"
        )
    return scans[index], f"{label}:{index}", notes


def load_scan_pair(
    source: str | os.PathLike, a: str | int | None = None, b: str | int | None = None
) -> tuple[Scan, Scan, tuple[str, str], list[str]]:
    """The two scans of ``scanclique match``, in either form.

    * ``load_scan_pair(LOG, 120, 125)``: scans 120 and 125 of a log (a path, or a
      registered name such as ``"intel"``);
    * ``load_scan_pair("a.txt", "b.txt")``: the scan in each file (the first if a file
      holds several; a note says so).

    Returns
    -------
    (scan_a, scan_b, (name_a, name_b), notes)
    """
    if b is not None:
        ia = _parse_index(a, "A") if a is not None else 0
        ib = _parse_index(b, "B")
        scan_a, name_a, notes_a = load_scan(source, ia)
        scan_b, name_b, notes_b = load_scan(source, ib)
        return scan_a, scan_b, (name_a, name_b), notes_a + notes_b
    if a is None:
        raise ScanIndexError(
            "need two scans: SOURCE A B (a log and two scan indices) or A B (two scan files)"
        )
    second = os.fspath(a) if not isinstance(a, int) else str(a)
    if not Path(second).exists() and second.strip().lstrip("-").isdigit():
        raise ScanIndexError(
            f"{second!r} is not a file: give a log and two scan indices "
            f"(scanclique match {os.fspath(source)} {second} <B>) or two scan files"
        )
    scan_a, name_a, notes_a = load_scan(source)
    scan_b, name_b, notes_b = load_scan(second)
    return scan_a, scan_b, (name_a, name_b), notes_a + notes_b


def load_config(path: str | os.PathLike | None = None, paper: bool = False) -> MatchConfig:
    """The configuration of a run: ``paper_config()`` with ``paper`` else ``MatchConfig()``,
    then the keys of the TOML file ``path`` (if any) on top."""
    base = paper_config() if paper else MatchConfig()
    if path is None:
        return base
    from ..io.config import read_config

    return read_config(path, base=base)


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
    """

    scan_a: Scan
    scan_b: Scan
    match: ScanMatch
    names: tuple[str, str]
    config: MatchConfig
    notes: tuple[str, ...] = ()
    reference: Pose2 | None = field(default=None)
    validation: Validation | None = field(default=None)

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
        ok = t <= SUCCESS_TRANSLATION and math.degrees(r) <= SUCCESS_ROTATION_DEG
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
        out["validation"] = self.checked().to_dict()
        out["config"] = config_to_dict(self.config)
        return out


def _reference(a: Scan, b: Scan) -> Pose2 | None:
    if a.reference is None or b.reference is None:
        return None
    return a.reference.inverse() @ b.reference


def odometry_path(
    source: str | os.PathLike, a: str | int | None, b: str | int | None
) -> list[Pose2] | None:
    """The odometry poses of the scans from A to B when the scans are ``a`` and ``b`` of
    the log ``source`` (for the distance travelled, see
    :func:`scanclique.validation.odometry_prior`); None when the scans come from two files
    or a scan in between has no odometry."""
    if b is None:
        return None
    ia = _parse_index(a, "A") if a is not None else 0
    ib = _parse_index(b, "B")
    scans = datasets.load_log(source)
    lo, hi = min(ia, ib), max(ia, ib)
    if not (0 <= lo and hi < len(scans)):
        return None
    path = [s.odometry for s in scans[lo : hi + 1]]
    if any(p is None for p in path):
        return None
    return path if ia <= ib else path[::-1]


def run_match(
    source: str | os.PathLike,
    a: str | int | None = None,
    b: str | int | None = None,
    config: MatchConfig | None = None,
    *,
    odometry: bool = False,
    noise: OdometryNoise | None = None,
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
    scan_a, scan_b, names, notes = load_scan_pair(source, a, b)
    m = match_scans(scan_a, scan_b, cfg)
    if odometry:
        for scan, name in ((scan_a, names[0]), (scan_b, names[1])):
            if scan.odometry is None:
                raise ScanError(f"{name}: the scan has no odometry pose (--odometry)")
        path = odometry_path(source, a, b)
        v = validate_match(m, scan_a.odometry, scan_b.odometry, noise, path=path)
    else:
        v = validate_match(m)
    return MatchRun(scan_a, scan_b, m, names, cfg, tuple(notes), _reference(scan_a, scan_b), v)


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
            return MatchRun(run.scan_a, run.scan_b, run.match, names, cfg, run.notes, run.reference)
    from ..sim import simulate_pair

    pair = simulate_pair(np.random.default_rng(DEMO_SEED))
    m = match_scans(pair.scan_a, pair.scan_b, cfg)
    return MatchRun(pair.scan_a, pair.scan_b, m, ("sim:a", "sim:b"), cfg, (), pair.pose_a_b)


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
    """

    name: str
    records: tuple[dict, ...]
    odometry: bool
    noise: OdometryNoise

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
) -> ValidateRun:
    """Match and validate the pair sets of a log with reference poses (what
    ``scanclique validate`` prints; :func:`scanclique.validation.pair_sets`).

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
    scans = datasets.load_log(source)
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
    return ValidateRun(_label(source), tuple(records), odometry, noise)


def confusion_rows(run: ValidateRun, set_name: str | None = None) -> list[tuple[str, ...]]:
    """Rows of the confusion table (right/wrong x accepted/rejected, the rejections by
    verdict) and the precision and recall of ``accepted``."""
    c = run.counts(set_name)
    t = c["table"]
    rows = []
    for right in (True, False):
        rejected = [t[(right, v)] for v in VERDICTS if v != ACCEPTED]
        rows.append(
            (
                "right" if right else "wrong",
                str(t[(right, ACCEPTED)]),
                str(sum(rejected)),
                *map(str, rejected),
            )
        )
    return rows


def _std(m: ScanMatch) -> dict | None:
    if m.covariance is None:
        return None
    d = np.diag(np.asarray(m.covariance, dtype=float))
    s = [math.sqrt(v) if math.isfinite(v) and v >= 0 else None for v in d]
    return {"x": s[0], "y": s[1], "theta": s[2]}


def _num(v: float | None, fmt: str = ".4f") -> str:
    if v is None:
        return "n/a"
    if not math.isfinite(v):
        return str(v)
    return format(v, fmt)


def match_rows(run: MatchRun) -> list[tuple[str, str, str]]:
    """The rows ``(metric, value, units)`` of the match table."""
    m = run.match
    rows: list[tuple[str, str, str]] = []
    add = rows.append
    add(("scan A", run.names[0], ""))
    add(("scan B", run.names[1], ""))
    if m.pose is None:
        add(("pose", f"none: {m.reason}", ""))
    else:
        p = m.pose
        add(("pose x", _num(p.x), "m"))
        add(("pose y", _num(p.y), "m"))
        add(("pose theta", _num(math.degrees(p.theta), ".3f"), "deg"))
        add(("pose theta", _num(p.theta, ".5f"), "rad"))
        s = _std(m)
        if s is not None:
            add(("std x", _num(s["x"]), "m"))
            add(("std y", _num(s["y"]), "m"))
            th = s["theta"]
            add(("std theta", _num(None if th is None else math.degrees(th), ".3f"), "deg"))
    add(("clique size", str(m.clique_size), "pairs"))
    per_kind = {k: 0 for k in KINDS}
    for pair in m.pairs:
        per_kind[pair.kind] = per_kind.get(pair.kind, 0) + 1
    for k, v in per_kind.items():
        add((f"  mapped {k.replace('_', ' ')}", str(v), "pairs"))
    add(("features A / B", f"{len(m.features_a)} / {len(m.features_b)}", ""))
    add(("score", _num(m.score, ".3f"), "fraction"))
    add(("ambiguous", "yes" if m.ambiguous else "no", ""))
    add(("optimal", "yes" if m.optimal else "no (time limit)", ""))
    add(("refined (ICP)", "yes" if m.refined else "no", ""))
    if m.pose is not None and m.hypotheses:
        found = "raw-scan search" if m.hypotheses[0].origin == "search" else "clique"
        add(("pose found by", found, ""))
    add(("hypotheses", str(len(m.hypotheses)), ""))
    add(
        (
            "correspondence graph",
            f"{m.n_correspondence_nodes} / {m.n_correspondence_edges}",
            "nodes / edges",
        )
    )
    total = 0.0
    for stage in STAGES:
        sec = float(m.seconds.get(stage, 0.0))
        total += sec
        add((f"time {stage}", _num(1e3 * sec, ".1f"), "ms"))
    add(("time total", _num(1e3 * total, ".1f"), "ms"))
    if m.pose is not None and m.reason:
        add(("note", m.reason, ""))
    ref = run.reference
    if ref is not None:
        add(("reference x", _num(ref.x), "m"))
        add(("reference y", _num(ref.y), "m"))
        add(("reference theta", _num(math.degrees(ref.theta), ".3f"), "deg"))
        e = run.errors()
        if e is not None:
            add(("error translation", _num(e[0]), "m"))
            add(("error rotation", _num(math.degrees(e[1]), ".3f"), "deg"))
    v = run.checked()
    rows.extend(validation_rows(v))
    if v.hypothesis not in (None, 0) and v.pose is not None and run.reference is not None:
        t_err, r_err = v.pose.distance_to(run.reference)
        rows.append(("chosen error translation", _num(t_err), "m"))
        rows.append(("chosen error rotation", _num(math.degrees(r_err), ".3f"), "deg"))
    return rows


def validation_rows(v: Validation) -> list[tuple[str, str, str]]:
    """The rows ``(metric, value, units)`` of a verdict (paper §7)."""
    rows: list[tuple[str, str, str]] = [("verdict", v.verdict, "")]
    for why in v.reasons:
        rows.append(("  because", why, ""))
    if v.hypothesis not in (None, 0):
        rows.append(("chosen hypothesis", str(v.hypothesis), "index"))
        if v.pose is not None:
            rows.append(("chosen pose x", _num(v.pose.x), "m"))
            rows.append(("chosen pose y", _num(v.pose.y), "m"))
            rows.append(("chosen pose theta", _num(math.degrees(v.pose.theta), ".3f"), "deg"))
    if v.prior is not None:
        p = v.prior
        rows.append(("odometry x", _num(p.x), "m"))
        rows.append(("odometry y", _num(p.y), "m"))
        rows.append(("odometry theta", _num(math.degrees(p.theta), ".3f"), "deg"))
        d = np.sqrt(np.diag(np.asarray(v.prior_covariance)))
        rows.append(("odometry std xy", _num(float(d[0])), "m"))
        rows.append(("odometry std theta", _num(math.degrees(float(d[2])), ".3f"), "deg"))
    if v.mahalanobis_sq is not None:
        rows.append(("Mahalanobis distance", _num(math.sqrt(v.mahalanobis_sq), ".2f"), "sigma"))
        rows.append(("gate (chi2 99 %, 3 dof)", _num(math.sqrt(v.gate), ".2f"), "sigma"))
    return rows


def feature_rows(features: Features) -> list[tuple[str, ...]]:
    """Rows ``(index, kind, x or rho, y or alpha, length, beams)`` of a features table:
    point features (index into ``points_xy``) then lines (``L<i>``, Hesse form)."""
    rows: list[tuple[str, ...]] = []
    for i, (xy, lab, beam) in enumerate(
        zip(features.points_xy, features.points_label, features.points_beam, strict=True)
    ):
        kind = POINT_LABEL_NAMES[int(lab)]
        rows.append((str(i), kind, f"x {xy[0]:.3f}", f"y {xy[1]:.3f}", "", str(int(beam))))
    for i, ((rho, alpha), ends, beams) in enumerate(
        zip(features.lines_rho_alpha, features.lines_ends, features.lines_beams, strict=True)
    ):
        length = float(np.linalg.norm(ends[1] - ends[0]))
        rows.append(
            (
                f"L{i}",
                "line",
                f"rho {rho:.3f}",
                f"alpha {math.degrees(alpha):.2f}°",
                f"{length:.2f}",
                f"{int(beams[0])}-{int(beams[1])}",
            )
        )
    return rows


def features_to_dict(features: Features) -> dict:
    """A JSON-ready dict of a :class:`Features` (counts, point features, lines)."""
    return {
        "counts": features.counts(),
        "points": [
            {
                "index": i,
                "kind": POINT_LABEL_NAMES[int(lab)],
                "x": float(xy[0]),
                "y": float(xy[1]),
                "beam": int(beam),
            }
            for i, (xy, lab, beam) in enumerate(
                zip(features.points_xy, features.points_label, features.points_beam, strict=True)
            )
        ],
        "lines": [
            {
                "index": i,
                "rho": float(ra[0]),
                "alpha": float(ra[1]),
                "ends": ends.tolist(),
                "beams": [int(bm[0]), int(bm[1])],
                "n_points": int(n),
            }
            for i, (ra, ends, bm, n) in enumerate(
                zip(
                    features.lines_rho_alpha,
                    features.lines_ends,
                    features.lines_beams,
                    features.lines_n_points,
                    strict=True,
                )
            )
        ],
    }


# ---------------------------------------------------------------------------------------
# Printing
# ---------------------------------------------------------------------------------------
def _console() -> Console:
    """stdout, plain text: no markup, so ``[m]`` and file names print as they are."""
    return Console(highlight=False, markup=False)


def _err_console() -> Console:
    return Console(stderr=True, highlight=False)


def _clean(obj: Any) -> Any:
    """NaN/inf -> None, NumPy scalars -> Python, recursively (strict JSON)."""
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def _print_json(obj: Any) -> None:
    typer.echo(json.dumps(_clean(obj), indent=2, allow_nan=False))


def _table(rows: Sequence[Sequence[str]], title: str, columns: Sequence[str]) -> Table:
    """A rich table, for the plain-text console of :func:`_console`."""
    t = Table(title=title, title_justify="left")
    for i, c in enumerate(columns):
        t.add_column(c, justify="right" if i == 1 and len(columns) == 3 else "left")
    for r in rows:
        t.add_row(*(str(c) for c in r))
    return t


def _note(msg: str) -> None:
    _err_console().print(f"[yellow]note:[/yellow] {_escape(msg)}", soft_wrap=True)


def _fail(msg: str, code: int = 2) -> typer.Exit:
    _err_console().print(f"[bold red]error:[/bold red] {msg}", soft_wrap=True, markup=True)
    return typer.Exit(code)


def _guard(fn: Callable[[], Any]) -> Any:
    """Run ``fn``; errors a user can cause become one line on stderr and exit code 2."""
    try:
        return fn()
    except (ScanCliqueError, IndexError) as exc:
        raise _fail(_escape(str(exc))) from None
    except OSError as exc:
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        raise _fail(_escape(f"{where}{exc.strerror or exc}")) from None


def _escape(s: str) -> str:
    from rich.markup import escape

    return escape(s)


def _plot_module():
    try:
        from .. import plot
    except ImportError as exc:  # pragma: no cover - matplotlib missing
        raise _fail(f"plotting needs matplotlib ({exc}): pip install 'scanclique[plot]'") from None
    try:
        import matplotlib  # noqa: F401
    except ImportError as exc:  # pragma: no cover
        raise _fail(f"plotting needs matplotlib ({exc}): pip install 'scanclique[plot]'") from None
    return plot


def _save_config(cfg: MatchConfig, path: Path, comment: str) -> None:
    from ..io.config import write_config

    _guard(lambda: write_config(cfg, path, comment=comment))
    _note(f"configuration written to {path}")


def _invocation() -> str:
    return "scanclique " + " ".join(sys.argv[1:]) if sys.argv else "scanclique"


# ---------------------------------------------------------------------------------------
# The typer app
# ---------------------------------------------------------------------------------------
app = typer.Typer(
    name="scanclique",
    no_args_is_help=True,
    add_completion=False,
    rich_markup_mode="markdown",
    pretty_exceptions_show_locals=False,
    context_settings={"help_option_names": ["-h", "--help"]},
)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"scanclique {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    verbose: Annotated[
        int,
        typer.Option("--verbose", "-v", count=True, help="Log more: -v info, -vv debug (stderr)."),
    ] = 0,
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_version, is_eager=True, help="Print the version and exit."
        ),
    ] = False,
) -> None:
    """Graph-theoretic data association between 2D laser scans (Bailey et al., ICRA 2000):
    maximum-clique feature mapping and the relative pose, without a prior pose.

    **Examples**

    ```
    scanclique demo
    scanclique match intel 120 125
    scanclique -v match a.txt b.txt --json
    ```
    """
    level = logging.WARNING if verbose == 0 else logging.INFO if verbose == 1 else logging.DEBUG
    root = logging.getLogger("scanclique")
    root.setLevel(level)
    if not any(getattr(h, "_scanclique", False) for h in root.handlers):
        h = logging.StreamHandler(sys.stderr)
        h.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
        h._scanclique = True  # type: ignore[attr-defined]
        root.addHandler(h)


ConfigOpt = Annotated[
    Path | None,
    typer.Option(
        "--config",
        "-c",
        help="TOML configuration (keys override the defaults / --paper).",
        dir_okay=False,
    ),
]
PaperOpt = Annotated[
    bool,
    typer.Option("--paper", help="Start from the paper's exact configuration (paper_config())."),
]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print JSON only (for machines).")]
_DEFAULT_NOISE = OdometryNoise()
PerMetreOpt = Annotated[
    float,
    typer.Option(
        "--odom-per-metre",
        min=0.0,
        help="Odometry translation error per metre travelled (1 sigma, m/m).",
    ),
]
PerRadianOpt = Annotated[
    float,
    typer.Option(
        "--odom-per-radian",
        min=0.0,
        help="Odometry heading error per radian turned (1 sigma, rad/rad).",
    ),
]


def _noise(per_metre: float, per_radian: float) -> OdometryNoise:
    return _guard(lambda: OdometryNoise(per_metre=per_metre, per_radian=per_radian))


@app.command()
def match(
    source: Annotated[
        str,
        typer.Argument(
            help="A log (CARMEN, .npz, scan text) or data set name (intel); or scan file A."
        ),
    ],
    a: Annotated[
        str | None,
        typer.Argument(help="Index of scan A in the log; or scan file B.", show_default=False),
    ] = None,
    b: Annotated[
        str | None, typer.Argument(help="Index of scan B in the log.", show_default=False)
    ] = None,
    config: ConfigOpt = None,
    paper: PaperOpt = False,
    plot: Annotated[
        Path | None,
        typer.Option("--plot", help="Write the figure (paper Fig. 8-10) here (.png/.pdf/.svg)."),
    ] = None,
    save_config: Annotated[
        Path | None, typer.Option("--save-config", help="Write the configuration used (TOML).")
    ] = None,
    odometry: Annotated[
        bool,
        typer.Option(
            "--odometry",
            help="Validate the pose against the scans' odometry (paper §7): Mahalanobis gate.",
        ),
    ] = False,
    odom_per_metre: PerMetreOpt = _DEFAULT_NOISE.per_metre,
    odom_per_radian: PerRadianOpt = _DEFAULT_NOISE.per_radian,
    json_out: JsonOpt = False,
) -> None:
    """Match scan B against scan A: feature mapping (maximum clique), pose and verdict.

    The pose maps points of B into A's frame: p_a = R(theta) p_b + (x, y). When both scans
    carry reference poses the table adds the reference relative pose and the errors. The
    verdict (accepted, rejected_odometry, ambiguous, too_few_features) judges the match on
    its features alone, or with --odometry also against the odometry of the log (the
    distance travelled summed over the scans in between).

    **Examples**

    ```
    scanclique match intel 120 125          # data set name, 2 indices
    scanclique match path/to/intel-odometry.log.gz 120 121
    scanclique match a.txt b.txt            # one scan per file
    scanclique match intel 120 125 --plot match.png
    scanclique match intel 120 125 --paper --json
    scanclique match intel 0 5 -c my.toml --save-config used.toml
    scanclique match intel 120 125 --odometry
    scanclique match csail 10 11 --odometry --odom-per-radian 0.3
    ```
    """
    cfg = _guard(lambda: load_config(config, paper))
    noise = _noise(odom_per_metre, odom_per_radian)
    run = _guard(lambda: run_match(source, a, b, cfg, odometry=odometry, noise=noise))
    for n in run.notes:
        _note(n)
    if save_config is not None:
        _save_config(cfg, save_config, f"used by: {_invocation()}")
    if json_out:
        _print_json(run.to_dict())
    else:
        _console().print(
            _table(
                match_rows(run),
                f"B = {run.names[1]} matched against A = {run.names[0]}",
                ("Metric", "Value", "Units"),
            )
        )
    if plot is not None:
        p = _plot_module()
        _guard(
            lambda: p.plot_match(
                run.scan_a, run.scan_b, run.match, plot, reference=run.reference, names=run.names
            )
        )
        if not json_out:
            _console().print(f"wrote {plot}")


@app.command()
def features(
    source: Annotated[str, typer.Argument(help="A log or scan file, or a data set name (intel).")],
    index: Annotated[
        int | None, typer.Argument(help="Scan index (default: the first scan).", show_default=False)
    ] = None,
    config: ConfigOpt = None,
    paper: PaperOpt = False,
    plot: Annotated[
        Path | None, typer.Option("--plot", help="Write the features figure (paper Fig. 8) here.")
    ] = None,
    json_out: JsonOpt = False,
) -> None:
    """Extract the features of one scan (paper §4): counts per kind and a table.

    Point features (foreground points, foreground edges cw/ccw, corners) are listed by
    position (sensor frame, metres); lines in Hesse normal form
    x cos(alpha) + y sin(alpha) = rho.

    **Examples**

    ```
    scanclique features intel 120
    scanclique features intel 120 --plot features.png
    scanclique features scan.txt --json
    ```
    """
    cfg = _guard(lambda: load_config(config, paper))
    scan, name, notes = _guard(lambda: load_scan(source, index))
    for n in notes:
        _note(n)
    feats = extract_features(scan, cfg.features, cfg.clustering)
    if json_out:
        _print_json({"scan": name, "source": scan.source, **features_to_dict(feats)})
    else:
        con = _console()
        counts = [(k.replace("_", " "), str(v)) for k, v in feats.counts().items()]
        counts.append(("total", str(len(feats))))
        counts.append(("valid beams", f"{scan.n_valid}/{scan.n_beams}"))
        con.print(_table(counts, f"features of {name}", ("Kind", "Count")))
        if len(feats):
            con.print(
                _table(
                    feature_rows(feats),
                    "features (sensor frame)",
                    ("#", "Kind", "x / rho [m]", "y [m] / alpha", "Length [m]", "Beams"),
                )
            )
    if plot is not None:
        p = _plot_module()

        def draw():
            ax = p.plot_features(scan, feats, title=f"{name}: {len(feats)} features")
            p.save_figure(ax.figure, plot)
            p._pyplot().close(ax.figure)

        _guard(draw)
        if not json_out:
            _console().print(f"wrote {plot}")


@app.command()
def clique(
    file: Annotated[Path, typer.Argument(help="A DIMACS .clq graph (p edge N M; e u v).")],
    all_: Annotated[
        bool, typer.Option("--all", help="Also enumerate every maximum clique (up to 1000).")
    ] = False,
    time_limit: Annotated[
        float | None,
        typer.Option(
            "--time-limit", min=0.0, help="Seconds; past it the best clique so far (optimal: no)."
        ),
    ] = None,
    json_out: JsonOpt = False,
) -> None:
    """Maximum clique of a DIMACS graph with the library's exact solver (paper §5.3).

    **Examples**

    ```
    scanclique clique brock200_2.clq
    scanclique clique MANN_a27.clq --time-limit 5
    scanclique clique graph.clq --all --json
    ```
    """
    from ..clique import solve_file

    res = _guard(lambda: solve_file(file, all=all_, time_limit=time_limit))
    if json_out:
        _print_json(res)
        return
    rows = [
        ("graph", f"{res['n']} vertices, {res['m']} edges", ""),
        ("ω (clique number)", str(res["omega"]), "vertices"),
        ("optimal", "yes" if res["optimal"] else "no (time limit)", ""),
        ("clique", " ".join(map(str, res["clique"])), "1-based"),
        ("search nodes", str(res["nodes"]), ""),
        ("search time", f"{1e3 * res['elapsed']:.1f}", "ms"),
        ("compiled kernels loaded in", f"{1e3 * res['load']:.0f}", "ms"),
    ]
    if all_:
        rows.insert(
            3,
            (
                "maximum cliques",
                str(len(res["cliques"])) + ("" if res["complete"] else " (incomplete)"),
                "",
            ),
        )
    _console().print(_table(rows, f"maximum clique of {file}", ("Metric", "Value", "Units")))


@app.command()
def demo(
    plot: Annotated[Path, typer.Option("--plot", help="Where to write the figure.")] = Path(
        "match.png"
    ),
    config: ConfigOpt = None,
    paper: PaperOpt = False,
) -> None:
    """Match one scan pair, print the table and the error, and draw it.

    Intel scans 120 and 121 when the Intel log is found (SCANCLIQUE_DATA, default
    ../shared/data); else a simulated pair whose true pose is known.

    **Examples**

    ```
    scanclique demo
    scanclique demo --plot /tmp/match.png
    SCANCLIQUE_DATA=/nonexistent scanclique demo  # simulated
    ```
    """
    cfg = _guard(lambda: load_config(config, paper))
    con = _console()
    run = _guard(lambda: run_demo(cfg))
    real = run.names[0].startswith("intel")
    if real:
        where = datasets.dataset_path("intel")
        con.print(
            f"Intel Research Lab log, scans {DEMO_INDICES[0]} and {DEMO_INDICES[1]} ({where})",
            soft_wrap=True,
        )
    else:
        looked = ", ".join(map(str, datasets.data_dir_candidates()))
        con.print(
            f"no real data found in {looked} (set {datasets.ENV_VAR}): "
            f"simulated pair, simulate_pair(default_rng({DEMO_SEED}))",
            soft_wrap=True,
        )
    con.print(
        _table(
            match_rows(run),
            f"B = {run.names[1]} matched against A = {run.names[0]}",
            ("Metric", "Value", "Units"),
        )
    )
    p = _plot_module()
    _guard(
        lambda: p.plot_match(
            run.scan_a, run.scan_b, run.match, plot, reference=run.reference, names=run.names
        )
    )
    con.print(f"wrote {plot}")
    con.print(run.verdict("reference" if real else "known pose"), soft_wrap=True)
    if run.match.pose is None:
        raise typer.Exit(1)


@app.command()
def validate(
    source: Annotated[
        str, typer.Argument(help="A log with reference poses (CARMEN, .npz, text) or intel.")
    ],
    cap: Annotated[
        int, typer.Option("--cap", min=0, help="At most this many pairs per set (0: all).")
    ] = 50,
    sets: Annotated[
        list[str] | None,
        typer.Option("--set", help="consecutive, skip3 or revisit (repeat; default all)."),
    ] = None,
    odometry: Annotated[
        bool,
        typer.Option("--odometry/--no-odometry", help="Use the log's odometry (default yes)."),
    ] = True,
    odom_per_metre: PerMetreOpt = _DEFAULT_NOISE.per_metre,
    odom_per_radian: PerRadianOpt = _DEFAULT_NOISE.per_radian,
    config: ConfigOpt = None,
    paper: PaperOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Match and validate the pair sets of a log; print the confusion table.

    The pair sets are consecutive scans, scans three apart and revisits (scans at least
    50 apart that see the same place). A verdict's pose is right when within 0.2 m and
    2 deg of the reference; the table counts right and wrong poses by verdict, with the
    precision (right accepted / accepted) and recall (right accepted / right) of
    accepted.

    **Examples**

    ```
    scanclique validate intel                 # 50 pairs per set, with odometry
    scanclique validate csail --cap 0 --set consecutive
    scanclique validate intel --no-odometry --json
    ```
    """
    cfg = _guard(lambda: load_config(config, paper))
    noise = _noise(odom_per_metre, odom_per_radian)
    from rich.progress import Progress

    with Progress(console=_err_console(), transient=True, disable=json_out) as bar:
        task = bar.add_task("matching", total=None)

        def tick(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        run = _guard(
            lambda: run_validate(
                source,
                cap=None if cap == 0 else cap,
                sets=sets or None,
                odometry=odometry,
                noise=noise,
                config=cfg,
                progress=tick,
            )
        )
    if json_out:
        _print_json(run.to_dict())
        return
    con = _console()
    columns = ("Pose", "accepted", "rejected", "odometry", "ambiguous", "too few")
    what = "with odometry" if odometry else "without odometry"
    for set_name in sorted({r["set"] for r in run.records}):
        c = run.counts(set_name)
        con.print(_table(confusion_rows(run, set_name), f"{run.name} {set_name} ({what})", columns))
        con.print(_summary(c), soft_wrap=True)
    c = run.counts()
    con.print(_table(confusion_rows(run), f"{run.name}: all pairs ({what})", columns))
    con.print(_summary(c), soft_wrap=True)
    con.print(
        "right: the verdict's pose is within 0.2 m and 2 deg of the reference; rejected = "
        "rejected_odometry (odometry) + ambiguous + too_few_features (too few)",
        soft_wrap=True,
    )


def _summary(c: dict) -> str:
    return (
        f"{c['n']} pairs: precision of accepted {_pct(c['precision'])}, recall "
        f"{_pct(c['recall'])}; odometry turned {c['ambiguous_to_right']} of "
        f"{c['ambiguous']} ambiguous matches into a right accepted pose"
    )


def _pct(v: float) -> str:
    return "n/a" if not math.isfinite(v) else f"{100 * v:.1f} %"


@app.command("config")
def config_cmd(
    paper: Annotated[
        bool,
        typer.Option(
            "--paper/--default", help="The paper's configuration, or this library's defaults."
        ),
    ] = False,
    output: Annotated[
        Path | None, typer.Option("--output", "-o", help="Write to this file instead of stdout.")
    ] = None,
) -> None:
    """Print a configuration as TOML, to edit and pass back with --config.

    **Examples**

    ```
    scanclique config --default > my.toml
    scanclique config --paper > paper.toml
    scanclique match intel 120 125 --config my.toml
    ```
    """
    from ..io.config import dumps_config

    cfg = paper_config() if paper else MatchConfig()
    comment = "the paper's configuration (paper_config())" if paper else "defaults (MatchConfig())"
    if output is not None:
        _save_config(cfg, output, comment)
    else:
        typer.echo(dumps_config(cfg, comment), nl=False)


# ---------------------------------------------------------------------------------------
# Application commands: one module of this package each, registered here
# ---------------------------------------------------------------------------------------
#: Modules of ``scanclique.cli`` that add commands. Each defines ``register(app)``, which
#: adds its typer command(s) to ``app``. A command module imports only typer, rich and the
#: standard library at module level (heavy imports go inside the command), so that
#: ``scanclique --help`` and ``--version`` stay light.
COMMAND_MODULES: tuple[str, ...] = ()


def _register_commands() -> None:
    import importlib

    for name in COMMAND_MODULES:
        importlib.import_module(f"{__name__}.{name}").register(app)


_register_commands()


def main() -> None:
    """Console-script entry point (``scanclique``)."""
    app(prog_name="scanclique")
