"""Consistency of several matches (paper §7): a cycle of matches A→B→C must close against
A→C within its covariance; :func:`flag_inconsistent` flags the match that breaks the most
cycles.

Poses are ``T_a_b`` (maps points of B into A); covariances of ``(x, y, theta)``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import ScanError
from ..geometry import Pose2
from ..uncertainty import (
    GATE_99,
    check_covariance,
    check_pose,
    compose_covariance,
    inverse_covariance,
    mahalanobis_sq,
)

__all__ = ["Consistency", "flag_inconsistent", "triple_consistency"]


def triple_consistency(
    T_ab: Pose2,
    T_bc: Pose2,
    T_ac: Pose2,
    cov_ab=None,
    cov_bc=None,
    cov_ac=None,
    gate: float = GATE_99,
    default_cov=None,
) -> tuple[bool, float]:
    """Does the cycle A→B→C close against A→C?

    ``T_ab @ T_bc`` and ``T_ac`` estimate the same pose (C in A's frame); their difference
    is tested with a chi-square gate on its squared Mahalanobis distance, the
    covariances propagated to first order (:func:`compose_covariance`) and added.

    Parameters
    ----------
    T_ab, T_bc, T_ac : Pose2
        Matches: B in A's frame, C in B's, C in A's.
    cov_ab, cov_bc, cov_ac : array (3, 3), optional
        Their covariances; ``default_cov`` for those not given.
    gate : float
        On the squared distance (default chi-square 99 %, 3 dof).
    default_cov : array (3, 3), optional
        Default ``diag(0.05², 0.05², (1 deg)²)``: scan matches on real data are rarely
        better than that, whatever the features' covariance says.

    Returns
    -------
    (bool, float)
        Whether the cycle is consistent, and the squared Mahalanobis distance.

    Examples
    --------
    >>> ab, bc = Pose2(1.0, 0.0, 0.3), Pose2(1.0, 0.5, -0.1)
    >>> triple_consistency(ab, bc, ab @ bc)[0]
    True
    >>> triple_consistency(ab, bc, ab @ bc @ Pose2(0.8, 0.0, 0.0))[0]
    False
    """
    d = _default_cov(default_cov)
    for name, T in (("T_ab", T_ab), ("T_bc", T_bc), ("T_ac", T_ac)):
        check_pose(T, name)
    ca = d if cov_ab is None else cov_ab
    cb = d if cov_bc is None else cov_bc
    cc = d if cov_ac is None else cov_ac
    S = compose_covariance(T_ab, ca, T_bc, cb)
    d2 = mahalanobis_sq(T_ab @ T_bc, S, T_ac, cc)
    return bool(d2 <= gate), d2


def _default_cov(default_cov) -> np.ndarray:
    if default_cov is None:
        return np.diag([0.05**2, 0.05**2, math.radians(1.0) ** 2])
    return check_covariance(default_cov, "default_cov")


@dataclass(frozen=True, slots=True, eq=False)
class Consistency:
    """Cycles of a set of matches and the matches they flag (:func:`flag_inconsistent`).

    Attributes
    ----------
    flagged : tuple of (int, int)
        The matches judged wrong, in the order they were flagged.
    triples : tuple of (int, int, int, bool, float)
        Every cycle ``(i, j, k)`` tested (matches i→j, j→k and i→k), whether it closed,
        and its squared Mahalanobis distance.
    failed : Mapping (i, j) -> int
        Number of failed cycles each match takes part in.
    tested : Mapping (i, j) -> int
        Number of cycles each match takes part in.
    """

    flagged: tuple[tuple[int, int], ...]
    triples: tuple[tuple[int, int, int, bool, float], ...]
    failed: Mapping[tuple[int, int], int]
    tested: Mapping[tuple[int, int], int]


def flag_inconsistent(
    matches: Mapping,
    gate: float = GATE_99,
    default_cov=None,
) -> Consistency:
    """Flag the matches that break cycles (paper §7: "the consistency of a particular scan
    match with other scan matches").

    Every triple of scans ``i < j < k`` with matches i→j, j→k and i→k is tested with
    :func:`triple_consistency`. A failed cycle says one of its three matches is wrong but
    not which; a wrong match breaks every cycle it is in. So the match in the most failed
    cycles is flagged (ties: the larger sum of squared distances), its cycles are set
    aside, and so on while failed cycles remain.

    Parameters
    ----------
    matches : mapping (i, j) -> Pose2 or (Pose2, covariance)
        Pose of scan j in scan i's frame (maps j's points into i), optionally with its
        covariance (``default_cov`` otherwise; see :func:`triple_consistency`). A match
        given as ``(j, i)`` is used inverted.
    gate : float
        On the squared Mahalanobis distance of each cycle.

    Returns
    -------
    Consistency

    Examples
    --------
    >>> T = [Pose2(0, 0, 0), Pose2(1, 0, 0.1), Pose2(2, 0.2, 0.2), Pose2(3, 0.1, 0.1)]
    >>> m = {(i, j): T[i].inverse() @ T[j] for i in range(4) for j in range(i + 1, 4)}
    >>> m[(1, 3)] = m[(1, 3)] @ Pose2(0.0, 0.7, 0.0)   # a symmetric alias
    >>> flag_inconsistent(m).flagged
    ((1, 3),)
    """
    default = _default_cov(default_cov)
    rel: dict[tuple[int, int], tuple[Pose2, np.ndarray]] = {}
    for key, value in matches.items():
        try:
            i, j = (int(key[0]), int(key[1]))
        except (TypeError, ValueError, IndexError):
            raise ScanError(
                f"flag_inconsistent: keys must be (i, j) scan indices, got {key!r}"
            ) from None
        if isinstance(value, Pose2):
            T, cov = value, default
        else:
            try:
                T, cov = value
            except (TypeError, ValueError):
                raise ScanError(
                    f"flag_inconsistent: match {key} must be a Pose2 or (Pose2, covariance)"
                ) from None
            T = check_pose(T, f"match {key}")
            cov = default if cov is None else check_covariance(cov, f"covariance of match {key}")
        if i == j:
            raise ScanError(f"flag_inconsistent: match {key} relates a scan to itself")
        if i < j:
            rel[(i, j)] = (T, cov)
        elif (j, i) not in rel:
            rel[(j, i)] = (T.inverse(), inverse_covariance(T, cov))
    nbrs: dict[int, set[int]] = {}
    for i, j in rel:
        nbrs.setdefault(i, set()).add(j)
    triples = []
    for (i, j), (T_ij, c_ij) in sorted(rel.items()):
        for k in sorted(nbrs.get(j, ())):
            if (i, k) not in rel:
                continue
            T_jk, c_jk = rel[(j, k)]
            T_ik, c_ik = rel[(i, k)]
            ok, d2 = triple_consistency(T_ij, T_jk, T_ik, c_ij, c_jk, c_ik, gate)
            triples.append((i, j, k, ok, d2))
    tested: dict[tuple[int, int], int] = {}
    failed: dict[tuple[int, int], int] = {}
    for i, j, k, ok, _ in triples:
        for e in ((i, j), (j, k), (i, k)):
            tested[e] = tested.get(e, 0) + 1
            if not ok:
                failed[e] = failed.get(e, 0) + 1
    flagged: list[tuple[int, int]] = []
    open_ = [t for t in triples if not t[3]]
    while open_:
        votes: dict[tuple[int, int], list[float]] = {}
        for i, j, k, _, d2 in open_:
            for e in ((i, j), (j, k), (i, k)):
                v = votes.setdefault(e, [0.0, 0.0])
                v[0] += 1
                v[1] += d2
        # most failed cycles first; then the fewest consistent cycles; then the larger sum
        worst = max(
            votes, key=lambda e: (votes[e][0], -(tested[e] - failed.get(e, 0)), votes[e][1])
        )
        flagged.append(worst)
        open_ = [t for t in open_ if worst not in ((t[0], t[1]), (t[1], t[2]), (t[0], t[2]))]
    return Consistency(tuple(flagged), tuple(triples), dict(failed), dict(tested))
