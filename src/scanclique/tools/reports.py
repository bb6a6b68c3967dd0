"""Rows of the tables ``scanclique`` prints, and JSON-ready dicts, as plain functions.

Each builder returns a list of string tuples (``(metric, value, units)`` for the
Metric / Value / Units tables) that a script can print any way it likes; the commands
render them with rich.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigError
from ..features import POINT_LABEL_NAMES, Features
from ..kinds import kind as _kind
from ..kinds import kind_name, kind_names
from ..match import STAGES
from ..validation import ACCEPTED, VERDICTS, Validation
from .runs import MatchRun, ValidateRun, _std

__all__ = [
    "KINDS",
    "match_rows",
    "validation_rows",
    "feature_rows",
    "features_to_dict",
    "confusion_rows",
]

#: The built-in kinds of mapped pairs, in table order (kinds registered later, see
#: :mod:`scanclique.kinds`, are listed by the reports too, in label order).
KINDS = (*POINT_LABEL_NAMES.values(), "line")


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
    if run.poses:
        add(("poses in the log", run.poses, ""))
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
    per_kind = {k: 0 for k in kind_names().values()}
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
    from ..match import warm_up_seconds

    load = warm_up_seconds()
    if load is not None:  # loading (or compiling) the kernels, before any stage's clock
        add(("kernel loading", _num(load, ".2f"), "s"))
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
        kind = kind_name(int(lab))
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


def _kind_attributes(label: int) -> tuple[str, ...]:
    """Attribute names of the kind with this label (none for an unregistered label)."""
    try:
        return _kind(label).attributes
    except ConfigError:
        return ()


def _attributes(label: int, values: np.ndarray) -> dict:
    """``{attribute name: value}`` of a feature of a registered kind with attributes."""
    names = _kind_attributes(label)
    return {n: float(v) for n, v in zip(names, values, strict=False) if np.isfinite(v)}


def features_to_dict(features: Features) -> dict:
    """A JSON-ready dict of a :class:`Features` (counts, point features, lines); a point of
    a kind with node attributes (:mod:`scanclique.kinds`) lists them under
    ``"attributes"``."""
    points = []
    for i, (xy, lab, beam, attrs) in enumerate(
        zip(
            features.points_xy,
            features.points_label,
            features.points_beam,
            features.points_attributes,
            strict=True,
        )
    ):
        rec = {
            "index": i,
            "kind": kind_name(int(lab)),
            "x": float(xy[0]),
            "y": float(xy[1]),
            "beam": int(beam),
        }
        extra = _attributes(int(lab), attrs) if attrs.size else {}
        if extra:
            rec["attributes"] = extra
        points.append(rec)
    return {
        "counts": features.counts(),
        "points": points,
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
