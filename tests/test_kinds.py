"""The registry of feature kinds (scanclique.kinds): the built-in kinds register through
it, and a kind registered from outside (a tree trunk with its diameter) is extracted,
paired by its attribute and matched without any change of the matcher."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from scanclique import kinds, sim
from scanclique.correspondence import candidate_pairs, correspondence_graph, count_pairs
from scanclique.errors import ConfigError, ScanCliqueError
from scanclique.features import Features, extract_features
from scanclique.geometry import Pose2
from scanclique.graph import LINE, NODE_KIND_NAMES, feature_graph
from scanclique.match import match_scans

TRUNK_LABEL = 5


# --------------------------------------------------------------------------------------
# A new kind, written as a user would: circles fitted to small clusters
# --------------------------------------------------------------------------------------
def _fit_circle(p: np.ndarray):
    """Algebraic (Kasa) circle fit: centre (2,), radius, RMS radial residual."""
    A = np.column_stack((2.0 * p, np.ones(len(p))))
    b = (p * p).sum(axis=1)
    (cx, cy, c), *_ = np.linalg.lstsq(A, b, rcond=None)
    r2 = c + cx * cx + cy * cy
    if r2 <= 0:
        return None
    r = math.sqrt(r2)
    res = np.linalg.norm(p - (cx, cy), axis=1) - r
    return np.array([cx, cy]), r, float(np.sqrt(np.mean(res * res)))


def trunk_extractor(scan, features: Features) -> kinds.KindFeatures:
    """Trunks: clusters of 8..80 beams whose points lie on a circle of radius 0.05..1 m
    centred beyond them (as seen from the sensor); the diameter is the attribute."""
    xy = scan.xy()
    out_xy, out_cov, out_beam, out_d = [], [], [], []
    for start, stop in features.clusters:
        p = xy[start:stop]
        p = p[np.all(np.isfinite(p), axis=1)]
        if not 8 <= len(p) <= 80:  # a short arc fixes no radius
            continue
        fit = _fit_circle(p)
        if fit is None:
            continue
        centre, r, rms = fit
        if not (0.05 <= r <= 1.0 and rms < 0.02):
            continue
        if np.linalg.norm(centre) <= np.linalg.norm(p, axis=1).mean():
            continue  # a concave arc (the inside of a room's corner), not a trunk
        out_xy.append(centre)
        out_cov.append(np.eye(2) * (0.02**2 + (r * 0.05) ** 2))
        out_beam.append((start + stop) // 2)
        out_d.append([2.0 * r])
    n = len(out_xy)
    return kinds.KindFeatures(
        xy=np.reshape(out_xy, (n, 2)),
        cov=np.reshape(out_cov, (n, 2, 2)),
        beam=np.asarray(out_beam, dtype=np.int64),
        attributes=np.reshape(out_d, (n, 1)),
    )


TRUNK = kinds.FeatureKind(
    "trunk",
    TRUNK_LABEL,
    "point",
    attributes=("diameter",),
    attribute_tolerances=(0.06,),
    extract=trunk_extractor,
    description="tree trunk: circle fitted to a small cluster; attribute diameter [m]",
)


def _park(seed: int = 3, n: int = 28):
    rng = np.random.default_rng(seed)
    centres, radii = [], []
    while len(centres) < n:
        c = rng.uniform([-14.0, 2.0], [14.0, 22.0])
        if all(np.linalg.norm(c - q) > 2.0 for q in centres):
            centres.append(c)
            radii.append(rng.uniform(0.1, 0.45))
    return sim.World(np.zeros((0, 2, 2)), circle_centres=centres, circle_radii=radii)


# --------------------------------------------------------------------------------------
# The registry itself
# --------------------------------------------------------------------------------------
def test_builtin_kinds_are_registered_with_their_labels_and_geometries():
    names = {k.name: (k.label, k.geometry) for k in kinds.registered_kinds()}
    assert names == {
        "foreground_point": (0, "point"),
        "edge_cw": (1, "point"),
        "edge_ccw": (2, "point"),
        "corner": (3, "point"),
        "line": (LINE, "line"),
    }
    assert dict(NODE_KIND_NAMES) == {0: "foreground_point", 1: "edge_cw", 2: "edge_ccw",
                                     3: "corner", LINE: "line"}  # fmt: skip
    # every geometry declares its relations with every geometry, and a pose residual
    for g in kinds.GEOMETRIES.values():
        assert set(g.relations) == set(kinds.GEOMETRIES) and g.residual


@pytest.mark.parametrize(
    "bad, match",
    [
        (dict(name="corner", label=9, geometry="point"), "clashes"),
        (dict(name="pole", label=3, geometry="point"), "clashes"),
        (dict(name="pole", label=9, geometry="plane"), "geometry"),
        (dict(name="pole", label=99, geometry="point"), r"\[0, 63\]"),
        (dict(name="pole", label=9, geometry="point", attributes=("d",)), "one tolerance"),
        (
            dict(
                name="pole",
                label=9,
                geometry="point",
                attributes=("d",),
                attribute_tolerances=(-1.0,),
            ),
            "> 0",
        ),  # fmt: skip
        (dict(name="wall2", label=9, geometry="line"), "line geometry"),
        (dict(name="not an id", label=9, geometry="point"), "identifier"),
    ],
)
def test_bad_kinds_are_refused_with_a_clear_error(bad, match):
    with pytest.raises(ConfigError, match=match):
        kinds.register_kind(kinds.FeatureKind(**bad))
    assert len(kinds.registered_kinds()) == 5  # nothing half-registered


def test_registered_is_scoped_and_builtins_cannot_be_removed():
    with kinds.registered(TRUNK):
        assert kinds.kind("trunk") is TRUNK and kinds.kind(TRUNK_LABEL) is TRUNK
        assert NODE_KIND_NAMES[TRUNK_LABEL] == "trunk"
    with pytest.raises(ConfigError, match="no feature kind"):
        kinds.kind("trunk")
    with pytest.raises(ConfigError, match="built-in"):
        kinds.unregister_kind("line")
    assert kinds.kind_name(TRUNK_LABEL) == f"label_{TRUNK_LABEL}"


# --------------------------------------------------------------------------------------
# Attributes in the graph and the correspondence stage
# --------------------------------------------------------------------------------------
def _trunk_features(xy, diameters) -> Features:
    n = len(xy)
    return Features(
        np.asarray(xy, float), np.full(n, TRUNK_LABEL, np.int8),
        np.tile(np.eye(2) * 1e-4, (n, 1, 1)), np.arange(n),
        np.zeros((0, 2)), np.zeros((0, 2, 2)), np.zeros((0, 2, 2)),
        np.zeros((0, 2), int), np.zeros(0, int), np.zeros((0, 2), int),
        points_attributes=np.asarray(diameters, float).reshape(n, 1),
    )  # fmt: skip


def test_attribute_tolerance_decides_which_trunks_may_pair():
    # a parallelogram: its point distances are symmetric under a half-turn, so without
    # the diameters the two assignments (identity and half-turn) are equally good cliques
    xy = np.array([[0.0, 0.0], [4.0, 0.0], [5.0, 3.0], [1.0, 3.0]])
    d = [0.2, 0.5, 0.2, 0.5]  # the half-turn maps 0 -> 2 and 1 -> 3: same diameters!
    d_broken = [0.2, 0.5, 0.3, 0.8]  # now the half-turn pairs trunks of other diameters
    with kinds.registered(TRUNK):
        ga = feature_graph(_trunk_features(xy, d_broken))
        gb = feature_graph(_trunk_features(xy[::-1] * 1.0, d_broken[::-1]))
        assert ga.attributes.shape == (4, 1)
        assert np.all(ga.attribute_tolerances == 0.06)
        pairs = candidate_pairs(ga, gb)
        assert count_pairs(ga, gb) == len(pairs)
        # every pair agrees in diameter; only the true assignment survives
        da = ga.attributes[pairs[:, 0], 0]
        db = gb.attributes[pairs[:, 1], 0]
        assert np.all(np.abs(da - db) <= 0.06)
        assert sorted(map(tuple, pairs)) == [(0, 3), (1, 2), (2, 1), (3, 0)]
        # label arrays alone (no attributes) pair all 16
        assert len(candidate_pairs(ga.labels, gb.labels)) == 16
        # with symmetric diameters both assignments stay, as they must
        gs = feature_graph(_trunk_features(xy, d))
        assert len(candidate_pairs(gs, gs)) == 8
        cg = correspondence_graph(ga, gb)
        assert cg.n_nodes == 4 and cg.n_edges == 6  # one 4-clique: the true association


def test_a_node_without_an_attribute_value_is_not_vetoed():
    with kinds.registered(TRUNK):
        g = feature_graph(_trunk_features([[0.0, 0.0], [3.0, 1.0]], [np.nan, 0.3]))
        h = feature_graph(_trunk_features([[0.0, 0.0], [3.0, 1.0]], [0.9, 0.9]))
        assert sorted(map(tuple, candidate_pairs(g, h))) == [(0, 0), (0, 1)]


def test_reports_name_the_kind_and_its_attributes():
    from scanclique.tools.reports import feature_rows, features_to_dict

    f = _trunk_features([[0.0, 0.0], [3.0, 1.0]], [0.25, np.nan])
    with kinds.registered(TRUNK):
        d = features_to_dict(f)
        assert d["counts"]["trunk"] == 2
        assert d["points"][0]["kind"] == "trunk"
        assert d["points"][0]["attributes"] == {"diameter": 0.25}
        assert "attributes" not in d["points"][1]  # no value, nothing invented
        assert [r[1] for r in feature_rows(f)] == ["trunk", "trunk"]
    assert features_to_dict(f)["points"][0]["kind"] == f"label_{TRUNK_LABEL}"


def test_plot_draws_a_registered_kind_under_its_name():
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    from scanclique.plot import plot_features

    scan = sim.simulate_scan(
        _park(), Pose2.from_xytheta(0.0, 0.0, math.pi / 2), n_beams=721, range_sigma=0.0
    )
    with kinds.registered(TRUNK):
        ax = plot_features(scan, extract_features(scan))
    assert "trunk" in ax.get_legend_handles_labels()[1]
    assert "trunk" in ax.get_title()


def test_bad_extractor_output_is_refused_with_a_clear_error():
    def kf(**over):
        args = dict(xy=np.zeros((2, 2)), cov=np.zeros((2, 2, 2)), beam=[0, 1],
                    attributes=np.zeros((2, 1)))  # fmt: skip
        args.update(over)
        return kinds.KindFeatures(**args)

    with pytest.raises(ConfigError, match="xy: expected shape"):
        kf(xy=np.zeros((2, 3)))  # never silently reshaped
    with pytest.raises(ConfigError, match="cov"):
        kf(cov=np.zeros((3, 2, 2)))
    with pytest.raises(ConfigError, match="attributes"):
        kf(attributes=np.zeros(2))
    with pytest.raises(ConfigError, match="finite"):
        kf(xy=np.array([[0.0, np.nan], [1.0, 1.0]]))
    mine = np.zeros((2, 2))
    kf(xy=mine)
    assert mine.flags.writeable  # the extractor's own array is not frozen

    scan = sim.simulate_scan(
        _park(), Pose2.from_xytheta(0.0, 0.0, math.pi / 2), n_beams=721, range_sigma=0.0
    )
    wrong_type = kinds.FeatureKind("trunk", TRUNK_LABEL, "point", extract=lambda s, f: None)
    with kinds.registered(wrong_type), pytest.raises(ScanCliqueError, match="KindFeatures"):
        extract_features(scan)
    too_many = kinds.FeatureKind(
        "trunk", TRUNK_LABEL, "point", extract=lambda s, f: kf(attributes=np.zeros((2, 3)))
    )
    with kinds.registered(too_many), pytest.raises(ConfigError, match="declares 0"):
        extract_features(scan)
    f = _trunk_features([[0.0, 0.0], [3.0, 1.0]], [0.2, 0.3])
    with pytest.raises(ScanCliqueError, match="points_attributes"):
        dataclasses.replace(f, points_attributes=np.zeros((3, 1)))


def test_features_of_an_unregistered_kind_with_attributes_are_refused():
    f = _trunk_features([[0.0, 0.0], [3.0, 1.0]], [0.2, 0.3])
    with pytest.raises(ScanCliqueError, match="no feature kind"):
        feature_graph(f)


# --------------------------------------------------------------------------------------
# End to end: register, extract, match; the matcher is untouched
# --------------------------------------------------------------------------------------
def test_a_registered_trunk_kind_is_extracted_and_matched():
    world = _park()
    rng = np.random.default_rng(7)
    pose_a = Pose2.from_xytheta(0.0, 0.0, math.pi / 2)
    pose_b = Pose2.from_xytheta(0.8, 0.5, math.pi / 2 + math.radians(12.0))
    a = sim.simulate_scan(world, pose_a, rng=rng, range_sigma=0.01, n_beams=721)
    b = sim.simulate_scan(world, pose_b, rng=rng, range_sigma=0.01, n_beams=721)
    truth = pose_a.inverse() @ pose_b  # pose of B's sensor in A's frame

    assert "trunk" not in extract_features(a).counts()
    with kinds.registered(TRUNK):
        fa = extract_features(a)
        assert fa.counts()["trunk"] >= 10
        trunks = fa.points_label == TRUNK_LABEL
        # the fitted diameters are the world's, within the tolerance
        centres = pose_a.transform(fa.points_xy[trunks])
        dist = np.linalg.norm(centres[:, None] - world.circle_centres[None], axis=2)
        nearest = dist.argmin(axis=1)
        assert np.all(dist.min(axis=1) < 0.15)  # a far trunk is a short arc
        diam = fa.points_attributes[trunks, 0]
        assert np.all(np.abs(diam - 2.0 * world.circle_radii[nearest]) < 0.06)
        assert np.all(np.isnan(fa.points_attributes[~trunks]))

        m = match_scans(a, b)
    assert m.pose is not None
    err = m.pose.inverse() @ truth
    assert math.hypot(err.x, err.y) < 0.05 and abs(err.theta) < math.radians(0.5)
    trunk_pairs = [p for p in m.pairs if p.kind == "trunk"]
    assert len(trunk_pairs) >= 6
    for p in trunk_pairs:  # every mapped trunk pair agrees in diameter
        assert abs(fa.points_attributes[p.a, 0] - m.features_b.points_attributes[p.b, 0]) <= 0.06
