"""How a log's rotating lidar timed its beams, checked on the log itself (beyond the paper).

A 360 degree lidar measures its beams over a whole revolution, and the mapper takes that
skew out (:func:`scanclique.scan.deskew`) by each beam's time
(:attr:`scanclique.scan.Scan.beam_times`, from a bag's ``time_increment``). REP 117 says
the stamp is the first beam's and the increment runs in the order of the ranges, but
drivers differ: some store the beams against the order they were measured in (to turn
a clockwise lidar's scan counter-clockwise) and stamp the scan when it is complete. Taken
the wrong way round, the times double the skew instead of removing it.

:func:`sweep_timing` tries each reading of :data:`scanclique.scan.TIMINGS` on the log's
turning scans: each de-skewed with it and aligned (point-to-line ICP from the motion's
relative pose) with a scan some 0.4 s before it, de-skewed alike. The shape tells the
direction of the times: under the wrong one the two scans agree less on the raw scans
(:func:`scanclique.match.pose_score`): the direction (``given`` or ``shifted``, forward;
``negated`` or ``reversed``, backward) whose better reading scores best, or ``none``
when not de-skewing at all does. Where the stamp lies in the sweep (its start or its
end) changes no shape, only the instant the de-skewed scan stands for: of the direction's
two readings, the one whose alignments turn least from the motion's relative poses (the
odometry's, stamped at the scans' stamps) is the driver's. Turning scans are the ones
that tell: a sweep that does not turn is skewed by its translation only.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from ..config import MatchConfig
from ..geometry import Pose2
from ..match import pose_score, prepare_scan
from ..refine import icp_point_to_line
from ..scan import TIMINGS, Scan, deskew_along, sweep_velocity_of

__all__ = [
    "TIMING_PAIRS", "TIMING_MIN_PAIRS", "TIMING_MIN_TURN", "TIMING_GAP", "DIRECTIONS",
    "TIMING_MARGIN",
    "sweep_timing",
]  # fmt: skip

#: the most turning scans :func:`sweep_timing` compares (those that turn most)
TIMING_PAIRS = 24
#: fewer turning scans than this: the log does not tell (the batch reads the times as
#: given, REP 117; the online mapper waits)
TIMING_MIN_PAIRS = 5
#: a sweep turning less than this (rad) over its span is not a turning scan
TIMING_MIN_TURN = math.radians(3.0)
#: seconds between a turning scan and the earlier scan it is aligned with
TIMING_GAP = 0.4
#: the readings of one direction of the times, which differ by where the stamp lies only
#: (the simulated LDS-01 drives: the right reading and the other of its direction score
#: within 0.005, and turn 0.46 against 1.89 degrees, 0.99 against 3.82, 1.73 against 3.07
#: from the odometry; the other direction scores 0.04 to 0.1 less)
DIRECTIONS = (("given", "shifted"), ("negated", "reversed"))
#: the least lead in mean raw-scan score that decides between the two directions, or for
#: not de-skewing at all over both (the simulated drives' whole logs: 0.04 to 0.1 between
#: the directions; an online mapper's first 25 scans, hardly turning: all readings within
#: 0.003, and the best of them the wrong way)
TIMING_MARGIN = 0.01


def sweep_timing(
    scans: Sequence[Scan],
    pose_of: Callable[[int], Pose2 | None],
    config: MatchConfig | None = None,
) -> tuple[str | None, dict[str, tuple[float, float]], int]:
    """Which reading of the scans' beam times (:data:`scanclique.scan.TIMINGS`) the log
    agrees with best (module docstring).

    Parameters
    ----------
    scans : sequence of Scan
        The log; only scans with beam times are tried.
    pose_of : callable
        ``pose_of(i)``: scan ``i``'s sensor pose along the log's motion (its odometry,
        or a first pass of the front end), or None; the velocity of a sweep is the step
        to the next scan (:func:`scanclique.scan.sweep_velocity_of`), and the relative
        pose of two scans the start of their alignment.
    config : MatchConfig, optional
        For preparing the scans and scoring their agreement.

    Returns
    -------
    (timing, scores, pairs)
        The reading; for each reading its mean raw-scan score over the pairs compared
        and the mean angle (degrees) its alignments turn from ``pose_of``'s relative
        poses; and how many pairs. ``"none"`` when not de-skewing agrees best; None when
        the log does not tell: fewer than :data:`TIMING_MIN_PAIRS` pairs (it hardly
        turns: its times hardly matter), or neither direction leads the other by
        :data:`TIMING_MARGIN`.
    """
    cfg = config or MatchConfig()
    n = len(scans)
    vel = [  # (the motion, to choose the turning scans: either step will do)
        sweep_velocity_of(scans, j, pose_of) if scans[j].beam_times is not None else None
        for j in range(n)
    ]
    turn = np.array(
        [
            abs(v[2]) * float(np.ptp(scans[j].beam_times)) if v is not None else 0.0
            for j, v in enumerate(vel)
        ]
    )
    pairs = []
    for j in np.argsort(-turn, kind="stable").tolist():
        if turn[j] < TIMING_MIN_TURN or len(pairs) == TIMING_PAIRS:
            break
        k = _earlier(scans, j)
        if k is not None and vel[k] is not None and pose_of(k) is not None:
            pairs.append((k, j))
    if len(pairs) < TIMING_MIN_PAIRS:
        return None, {}, len(pairs)
    score, turned = dict.fromkeys(TIMINGS, 0.0), dict.fromkeys(TIMINGS, 0.0)
    for k, j in pairs:
        prior = pose_of(k).inverse() @ pose_of(j)
        for timing in TIMINGS:
            pa = prepare_scan(deskew_along(scans, k, pose_of, timing), cfg)
            pb = prepare_scan(deskew_along(scans, j, pose_of, timing), cfg)
            icp = icp_point_to_line(
                pa.cloud, pb.sample, prior, max_correspondence=0.3, min_correspondence=0.05
            )
            score[timing] += pose_score(pa, pb, icp.pose, cfg) / len(pairs)
            turned[timing] += math.degrees(icp.pose.distance_to(prior)[1]) / len(pairs)
    out = {t: (score[t], turned[t]) for t in TIMINGS}
    forward, backward = (max(score[t] for t in d) for d in DIRECTIONS)
    top = max(forward, backward)
    if abs(forward - backward) < TIMING_MARGIN and score["none"] < top + TIMING_MARGIN:
        return None, out, len(pairs)
    if score["none"] > top:  # de-skewing either way helps nothing
        return "none", out, len(pairs)
    way = DIRECTIONS[0] if forward > backward else DIRECTIONS[1]
    best = min(way, key=lambda t: turned[t])  # (given or negated first on a tie)
    return best, out, len(pairs)


def _earlier(scans: Sequence[Scan], j: int) -> int | None:
    """The latest scan at least :data:`TIMING_GAP` s before scan ``j`` (None: none, or a
    scan without a timestamp on the way)."""
    t = scans[j].timestamp
    k = j - 1
    while k >= 0:
        tk = scans[k].timestamp
        if t is None or tk is None:
            return None
        if t - tk >= TIMING_GAP:
            return k
        k -= 1
    return None
