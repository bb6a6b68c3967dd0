"""Configuration values: the paper's defaults, paper_config(), checks, dict round trips."""

from __future__ import annotations

import dataclasses
import json
import math

import pytest

from scanclique.config import (
    CliqueConfig,
    ClusterConfig,
    CorrespondenceConfig,
    FeatureConfig,
    MatchConfig,
    PoseConfig,
    RefineConfig,
    config_from_dict,
    config_to_dict,
    paper_config,
)
from scanclique.errors import ConfigError


# -- the paper's numbers (Bailey et al. 2000, §4 and §6) ------------------------------------
def test_defaults_are_the_papers():
    c = MatchConfig()
    assert c.clustering.c1 == 0.07
    assert c.clustering.c2 == 0.04
    assert c.clustering.max_gap_beams == 0  # any invalid return breaks a cluster
    assert c.correspondence.point_point == 0.30
    assert c.correspondence.point_line == 0.40
    assert c.correspondence.line_line == 0.1


def test_paper_config_differences():
    """paper_config() changes exactly the documented switches and none of the paper's numbers.

    The clique section may hold further "maximum clique only" switches; outside it the set
    of changed fields is exact."""
    d = config_to_dict(MatchConfig())
    p = config_to_dict(paper_config())
    changed = {
        (section, key)
        for section in d
        for key in d[section]
        if d[section][key] != p[section][key] and section != "clique"
    }
    assert changed == {
        ("features", "corners"),
        ("features", "typed_edges"),
        ("correspondence", "signed"),
        ("correspondence", "parallel_offset"),
        ("pose", "method"),
        ("refine", "enabled"),
        ("refine", "min_score"),
        ("refine", "search"),
    }
    assert p["clique"]["time_limit"] == d["clique"]["time_limit"]
    assert p["clique"]["max_hypotheses"] == d["clique"]["max_hypotheses"]
    assert d["clique"]["peel"] > 0  # the default goes beyond the paper...
    pc = paper_config()
    assert pc.features.corners is False
    assert pc.features.typed_edges is False
    assert pc.correspondence.signed is False
    assert pc.correspondence.parallel_offset is False
    assert pc.clique.peel == 0
    assert pc.pose.method == "median"
    assert pc.refine.enabled is False
    # the paper's numbers stay
    assert pc.clustering.c1 == 0.07 and pc.clustering.c2 == 0.04
    assert (
        pc.correspondence.point_point,
        pc.correspondence.point_line,
        pc.correspondence.line_line,
    ) == (
        0.30,
        0.40,
        0.1,
    )


def test_configs_are_frozen():
    c = MatchConfig()
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.clustering.c1 = 0.1  # type: ignore[misc]


# -- checks -------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("cls", "kwargs"),
    [
        (ClusterConfig, {"c1": -0.01}),
        (ClusterConfig, {"c2": math.nan}),
        (ClusterConfig, {"c1": math.inf}),
        (ClusterConfig, {"c1": "0.07"}),
        (ClusterConfig, {"max_gap_beams": -1}),
        (FeatureConfig, {"point_max_extent": 0.0}),
        (FeatureConfig, {"split_distance": -0.1}),
        (FeatureConfig, {"line_min_points": 1}),
        (FeatureConfig, {"line_min_points": 6.0}),
        (FeatureConfig, {"line_min_length": 0}),
        (FeatureConfig, {"line_max_rms": math.nan}),
        (FeatureConfig, {"merge_angle": -1.0}),
        (FeatureConfig, {"range_sigma": 0.0}),
        (FeatureConfig, {"min_cluster_beams": 0}),
        (FeatureConfig, {"crowd_radius": -0.3}),
        (FeatureConfig, {"min_edge_jump": -1}),
        (CorrespondenceConfig, {"point_point": 0.0}),
        (CorrespondenceConfig, {"point_line": -0.4}),
        (CorrespondenceConfig, {"line_line": math.inf}),
        (CorrespondenceConfig, {"max_nodes": 0}),
        (CliqueConfig, {"time_limit": 0.0}),
        (CliqueConfig, {"max_hypotheses": 0}),
        (CliqueConfig, {"peel": -1}),
        (PoseConfig, {"method": "mean"}),
        (PoseConfig, {"min_pairs": 1}),
        (PoseConfig, {"min_pairs": 2.0}),
        (RefineConfig, {"max_correspondence": 0.0}),
        (RefineConfig, {"inlier_distance": -0.15}),
        (RefineConfig, {"conflict_weight": -1.0}),
        (RefineConfig, {"iterations": -1}),
        (RefineConfig, {"search_below": math.nan}),
        (RefineConfig, {"search_below": math.inf}),
        (RefineConfig, {"search_margin": -0.1}),
    ],
)
def test_invalid_values_raise(cls, kwargs):
    with pytest.raises(ConfigError, match=next(iter(kwargs))):
        cls(**kwargs)


@pytest.mark.parametrize(
    ("cls", "kwargs"),
    [
        (RefineConfig, {"iterations": 2.5}),
        (CliqueConfig, {"peel": 1.5}),
        (FeatureConfig, {"lines": "no"}),
        (CorrespondenceConfig, {"signed": "false"}),
    ],
)
def test_non_integer_counts_and_non_bool_switches_raise(cls, kwargs):
    with pytest.raises(ConfigError):
        cls(**kwargs)


@pytest.mark.parametrize(
    ("cls", "kwargs"),
    [
        (ClusterConfig, {"c1": 0.0, "c2": 0.0}),
        (RefineConfig, {"iterations": 0, "conflict_weight": 0.0}),
        (CliqueConfig, {"peel": 0}),
        (PoseConfig, {"method": "median", "min_pairs": 3}),
    ],
)
def test_boundary_values_accepted(cls, kwargs):
    c = cls(**kwargs)
    for k, v in kwargs.items():
        assert getattr(c, k) == v


# -- dicts --------------------------------------------------------------------------------
@pytest.mark.parametrize("cfg", [MatchConfig(), paper_config()], ids=["default", "paper"])
def test_round_trip_dict(cfg):
    d = config_to_dict(cfg)
    assert isinstance(d, dict) and set(d) == {
        "clustering",
        "features",
        "correspondence",
        "clique",
        "pose",
        "refine",
        "validation",
    }
    back = config_from_dict(d)
    assert back == cfg
    # plain values only: JSON survives the trip too
    assert config_from_dict(json.loads(json.dumps(d))) == cfg


def test_from_dict_partial_overrides():
    c = config_from_dict({"clustering": {"c1": 0.1}, "pose": {"method": "median"}})
    assert c.clustering.c1 == 0.1
    assert c.clustering.c2 == 0.04
    assert c.pose.method == "median"
    assert c.features == FeatureConfig()
    assert config_from_dict({}) == MatchConfig()


@pytest.mark.parametrize(
    ("data", "name"),
    [
        ({"clusterin": {}}, "clusterin"),
        ({"clustering": {"c3": 1.0}}, "c3"),
        ({"refine": {"enabled": True, "iters": 3}}, "iters"),
    ],
)
def test_from_dict_unknown_key(data, name):
    with pytest.raises(ConfigError, match=name):
        config_from_dict(data)


@pytest.mark.parametrize("data", [None, [1, 2], {"clustering": 5}, {"pose": "median"}])
def test_from_dict_not_a_table(data):
    with pytest.raises(ConfigError):
        config_from_dict(data)


def test_from_dict_checks_values():
    with pytest.raises(ConfigError, match="c1"):
        config_from_dict({"clustering": {"c1": -1.0}})


def test_from_dict_single_section():
    c = config_from_dict({"c1": 0.2}, ClusterConfig)
    assert c == ClusterConfig(c1=0.2)


@pytest.mark.parametrize(
    "cls, kwargs, match",
    [
        (RefineConfig, {"min_score": math.nan}, "min_score must be a number, got nan"),
        (RefineConfig, {"min_score": math.inf}, "min_score must be below inf"),
        (CliqueConfig, {"max_hypotheses": 2**63}, "must fit in 64 bits"),
        (CorrespondenceConfig, {"max_nodes": -(2**70)}, "must fit in 64 bits"),
        (PoseConfig, {"outlier_mahalanobis": 0.0}, "outlier_mahalanobis must be a positive"),
        (RefineConfig, {"search_cell": math.nan}, "search_cell must be a number, got nan"),
    ],
)
def test_nan_and_overflowing_values_are_refused(cls, kwargs, match):
    with pytest.raises(ConfigError, match=match):
        cls(**kwargs)


def test_match_config_sections_must_be_their_classes():
    with pytest.raises(ConfigError, match="MatchConfig.clique must be a CliqueConfig, got dict"):
        MatchConfig(clique={"time_limit": 1.0})


def test_the_former_module_constants_are_config_fields_with_their_old_values():
    r, p = RefineConfig(), PoseConfig()
    assert (r.conflict_margin, r.conflict_ratio, r.quick_exact) == (0.2, 0.02, 1)
    assert (r.distinct_metres, r.distinct_radians, r.ambiguous_score) == (
        0.3,
        math.radians(5),
        0.9,
    )
    assert (r.search_bins, r.search_peaks, r.search_top, r.search_cell) == (180, 6, 3, 0.25)
    assert (r.search_icp, r.search_stride, p.outlier_mahalanobis) == (4, 2, 3.5)
