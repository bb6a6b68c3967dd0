"""The relation metric of Kuemmerle et al. 2009 (scanclique.eval.relations)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from scanclique import datasets
from scanclique.errors import ParseError
from scanclique.eval import join_relations, read_relations, relation_errors, relation_metrics
from scanclique.eval.relations import Relation
from scanclique.geometry import Pose2


def test_hand_computed_case():
    # x1 = (1, 2, 90 deg), x2 = (1, 3, 90 deg): x2 in x1's frame is (1, 0, 0).
    x1 = Pose2(1.0, 2.0, math.pi / 2)
    x2 = Pose2(1.0, 3.0, math.pi / 2)
    # relation 1: delta* = (0.9, 0, 0) -> E = (0.1, 0, 0): 0.1 m, 0 deg
    # relation 2: delta* = (1, 0, 0.05) -> E = (1 - cos .05, sin .05, -.05): |t| = 2 sin(.025)
    # relation 3 (long, 20 s): delta* = (1, 0, 0) exactly -> 0
    rels = [
        Relation(0.0, 1.0, Pose2(0.9, 0.0, 0.0)),
        Relation(0.0, 1.0, Pose2(1.0, 0.0, 0.05)),
        Relation(1.0, 21.0, Pose2(-1.0, 0.0, 0.0)),
    ]
    x3 = Pose2(1.0, 2.0, math.pi / 2)  # at t = 21: back at x1
    poses = {0.0: x1, 1.0: x2, 21.0: x3}
    t, r, span = relation_errors(rels, poses)
    assert t[0] == pytest.approx(0.1, abs=1e-12)
    assert r[0] == pytest.approx(0.0, abs=1e-12)
    assert t[1] == pytest.approx(2 * math.sin(0.025), abs=1e-12)
    assert r[1] == pytest.approx(0.05, abs=1e-12)
    assert t[2] == pytest.approx(0.0, abs=1e-12)
    assert span.tolist() == [1.0, 1.0, 20.0]
    m = relation_metrics(rels, poses)
    tt = np.array([0.1, 2 * math.sin(0.025)])
    assert m.short.n == 2 and m.long.n == 1 and m.all.n == 3
    assert m.short.translation_mean == pytest.approx(tt.mean())
    assert m.short.translation_std == pytest.approx(tt.std())
    assert m.short.translation_sq_mean == pytest.approx((tt**2).mean())
    assert m.short.rotation_mean == pytest.approx(math.degrees(0.05) / 2)
    assert m.all.translation_mean == pytest.approx(tt.sum() / 3)


def test_sequence_of_poses_and_missing():
    rels = [Relation(0.0, 1.0, Pose2(1.0, 0.0, 0.0)), Relation(1.0, 5.0, Pose2(1.0, 0.0, 0.0))]
    poses = [Pose2(0, 0, 0), Pose2(1.0, 0.0, 0.0), None]
    ts = [0.0, 1.0, 2.0]
    ij, ok = join_relations(rels, ts)
    assert ij.tolist() == [[0, 1], [1, -1]] and ok.tolist() == [True, False]
    m = relation_metrics(rels, poses, ts)
    assert m.all.n == 1 and m.all.missing == 1 and m.all.translation_mean == pytest.approx(0.0)


def test_mounting_changes_frame():
    # the sensor sits 0.5 m ahead of the robot; the robot turns on the spot by 90 deg:
    # the sensor moves, the robot does not.
    mount = Pose2(0.5, 0.0, 0.0)  # robot in sensor frame is (-0.5, 0, 0)
    s1 = Pose2(0.5, 0.0, 0.0)
    s2 = Pose2(0.0, 0.5, math.pi / 2)
    rel = [Relation(0.0, 1.0, Pose2(0.0, 0.0, math.pi / 2))]
    t_no, _, _ = relation_errors(rel, {0.0: s1, 1.0: s2})
    t_yes, r_yes, _ = relation_errors(rel, {0.0: s1, 1.0: s2}, mounting=mount.inverse())
    assert t_no[0] > 0.5
    assert t_yes[0] == pytest.approx(0.0, abs=1e-12) and r_yes[0] == pytest.approx(0.0, abs=1e-12)


@settings(max_examples=50, deadline=None)
@given(
    st.floats(-5, 5), st.floats(-5, 5), st.floats(-3, 3),
    st.floats(-5, 5), st.floats(-5, 5), st.floats(-3, 3),
    st.floats(-5, 5), st.floats(-5, 5), st.floats(-3, 3),
)  # fmt: skip
def test_invariant_to_world_frame(x1, y1, a1, x2, y2, a2, gx, gy, ga):
    p1, p2, g = Pose2(x1, y1, a1), Pose2(x2, y2, a2), Pose2(gx, gy, ga)
    rel = [Relation(0.0, 1.0, Pose2(0.3, -0.2, 0.1))]
    t, r, _ = relation_errors(rel, {0.0: p1, 1.0: p2})
    tg, rg, _ = relation_errors(rel, {0.0: g @ p1, 1.0: g @ p2})
    assert tg[0] == pytest.approx(t[0], abs=1e-9) and rg[0] == pytest.approx(r[0], abs=1e-9)
    # the exact relation gives zero error
    t0, r0, _ = relation_errors([Relation(0.0, 1.0, p1.inverse() @ p2)], {0.0: p1, 1.0: p2})
    assert t0[0] == pytest.approx(0.0, abs=1e-9) and r0[0] == pytest.approx(0.0, abs=1e-9)


def test_bad_files(tmp_path):
    p = tmp_path / "bad.relations"
    p.write_text("1 2 0.1 0.2 0 0 0 0.3\n1 2 0.1\n")
    with pytest.raises(ParseError, match=r"bad.relations:2: expected 8 numbers"):
        read_relations(p)
    p.write_text("1 2 0.1 abc 0 0 0 0.3\n")
    with pytest.raises(ParseError, match=r"bad.relations:1: y: expected a number, found 'abc'"):
        read_relations(p)
    p.write_text("1 2 0.1 0.1 0.5 0 0 0.3\n")
    with pytest.raises(ParseError, match=r":1: z: expected 0"):
        read_relations(p)
    with pytest.raises(ParseError, match="cannot read"):
        read_relations(tmp_path / "missing.relations")


@pytest.mark.realdata
@pytest.mark.parametrize("name,n", [("fr079-raw", 1685), ("intel-raw", 2984)])
def test_shared_relations_join_raw_logs(name, n):
    path = datasets.data_dir() / datasets.DATASETS[name].relations
    if not path.is_file():
        pytest.skip(f"real data not found: set {datasets.ENV_VAR} (looked for {path})")
    rels = read_relations(path)
    assert len(rels) == n
    if name == "fr079-raw":  # the smaller log: every relation joins a scan exactly
        scans = datasets.load_log(name)
        _, ok = join_relations(rels, [s.timestamp for s in scans])
        assert ok.all()


def test_frame_mounting_is_the_constant_offset_of_the_two_poses_or_none():
    from scanclique.eval import frame_mounting
    from scanclique.geometry import Pose2
    from scanclique.scan import Scan

    def scan(ref, off):
        return Scan([1.0, 1.0], [0.0, 0.1], reference=ref, odometry=ref @ off)

    refs = [Pose2(0.1 * k, 0.05 * k, 0.2 * k) for k in range(60)]
    behind = Pose2(0.04, 0.0, 0.0)  # fr079: the robot frame 0.04 m ahead of the laser
    m = frame_mounting([scan(r, behind) for r in refs])
    assert m is not None and np.allclose(m.as_array(), [0.04, 0.0, 0.0])
    assert frame_mounting([scan(r, Pose2(0.0, 0.0, 0.0)) for r in refs]) is None  # same frame
    varying = [scan(r, Pose2(0.01 * (k % 3), 0.0, 0.0)) for k, r in enumerate(refs)]
    assert frame_mounting(varying) is None  # not a mounting
    assert frame_mounting([Scan([1.0, 1.0], [0.0, 0.1])]) is None  # no poses
