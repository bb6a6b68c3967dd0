"""TOML files of MatchConfig (scanclique.io.config): round trips, strict reading, errors."""

from __future__ import annotations

import dataclasses
import math
import sys

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from scanclique.config import MatchConfig, PoseConfig, paper_config
from scanclique.errors import ConfigError, DataNotFoundError
from scanclique.io.config import dumps_config, loads_config, read_config, toml_dumps, write_config

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


@pytest.mark.parametrize("cfg", [MatchConfig(), paper_config()], ids=["default", "paper"])
def test_round_trip_text(cfg):
    assert loads_config(dumps_config(cfg)) == cfg


def test_round_trip_file_with_changed_values(tmp_path):
    cfg = MatchConfig()
    cfg = dataclasses.replace(
        cfg,
        clustering=dataclasses.replace(cfg.clustering, c1=0.1 + 0.2, max_gap_beams=3),
        features=dataclasses.replace(cfg.features, corner_min_angle=math.radians(33.3)),
        pose=PoseConfig(method="median", min_pairs=4),
    )
    path = write_config(tmp_path / "run.toml", cfg, comment="a comment\nover two lines")
    text = path.read_text()
    assert text.startswith("# scanclique configuration")
    assert "# over two lines" in text
    back = read_config(path)
    assert back == cfg
    assert back.clustering.c1 == 0.1 + 0.2  # repr round trip: bit for bit


def test_every_section_is_a_table():
    data = tomllib.loads(dumps_config())
    assert set(data) == {f.name for f in dataclasses.fields(MatchConfig)}
    assert data["pose"]["method"] == "lsq"


def test_missing_keys_keep_defaults_or_base():
    cfg = loads_config("[pose]\nmin_pairs = 3\n")
    assert cfg.pose.min_pairs == 3
    assert cfg.refine == MatchConfig().refine
    cfg = loads_config("[pose]\nmin_pairs = 3\n", base=paper_config())
    assert cfg.pose == PoseConfig(method="median", min_pairs=3)
    assert cfg.refine == paper_config().refine


def test_integer_for_a_float_field_becomes_float():
    cfg = loads_config("[clique]\ntime_limit = 5\n")
    assert cfg.clique.time_limit == 5.0
    assert isinstance(cfg.clique.time_limit, float)


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("foo = 1\n", ["run.toml", "unknown key 'foo'", "known tables", "clustering"]),
        ("[features]\nfoo = 1\n", ["run.toml", "'features.foo'", "[features]", "corners"]),
        ("[nope]\nx = 1\n", ["run.toml", "unknown key 'nope'"]),
    ],
)
def test_unknown_key_names_key_and_file(tmp_path, text, words):
    p = tmp_path / "run.toml"
    p.write_text(text)
    with pytest.raises(ConfigError) as exc:
        read_config(p)
    msg = str(exc.value)
    for w in words:
        assert w in msg


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("[pose]\nmin_pairs = 3.5\n", ["'pose.min_pairs'", "integer", "3.5"]),
        ("[refine]\nenabled = 1\n", ["'refine.enabled'", "boolean"]),
        ('[clique]\ntime_limit = "2"\n', ["'clique.time_limit'", "number"]),
        ("pose = 1\n", ["'pose'", "table"]),
        ('[pose]\nmethod = "mean"\n', ["run.toml", "method", "'mean'"]),
        ("[clustering]\nc1 = -1.0\n", ["run.toml", "c1"]),
        ("[pose\nx = 1\n", ["run.toml", "not valid TOML", "line 1"]),
    ],
)
def test_bad_values_and_bad_toml(text, words):
    with pytest.raises(ConfigError) as exc:
        loads_config(text, "run.toml")
    for w in words:
        assert w in str(exc.value)


def test_missing_file_and_undecodable_file(tmp_path):
    with pytest.raises(DataNotFoundError, match="nope.toml"):
        read_config(tmp_path / "nope.toml")
    p = tmp_path / "bin.toml"
    p.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ConfigError, match="bin.toml: not UTF-8"):
        read_config(p)


def test_write_to_a_directory_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="cannot write"):
        write_config(tmp_path, MatchConfig())


def test_toml_dumps_rejects_none():
    with pytest.raises(ConfigError, match="a.b"):
        toml_dumps({"a": {"b": None}})


def test_toml_dumps_special_floats_and_keys():
    data = {"x": math.inf, "y": -math.inf, "odd key": 1, "t": {"arr": [1, 2.5, "s"]}}
    back = tomllib.loads(toml_dumps(data))
    assert back["x"] == math.inf and back["y"] == -math.inf
    assert back["odd key"] == 1
    assert back["t"]["arr"] == [1, 2.5, "s"]
    assert math.isnan(tomllib.loads(toml_dumps({"n": math.nan}))["n"])


@settings(max_examples=60, deadline=None)
@given(
    key=st.text(min_size=1, max_size=12),
    value=st.one_of(
        st.text(max_size=30),
        st.floats(allow_nan=False),
        st.integers(min_value=-(2**63), max_value=2**63 - 1),
        st.booleans(),
    ),
)
def test_toml_dumps_round_trips_scalars(key, value):
    data = {"section": {key: value}}
    assert tomllib.loads(toml_dumps(data)) == data


def test_map_and_slam_configs_round_trip_with_tuples_and_none(tmp_path):
    from scanclique.mapping import MapConfig
    from scanclique.slam import SlamConfig

    room = SlamConfig.for_sensor(0.15, math.radians(3.0), 5.0, math.radians(60.0))
    assert room.association.attribute_sigma is None  # no diameter gate for this sensor
    for cfg in (
        MapConfig(),
        SlamConfig(),
        room,
        dataclasses.replace(room, control_bias_sigma=0.01),
    ):
        text = dumps_config(cfg)
        assert loads_config(text, cls=type(cfg)) == cfg
        write_config(tmp_path / "c.toml", cfg)
        assert read_config(tmp_path / "c.toml", base=type(cfg)()) == cfg
    # MapConfig's odometry noise comes from a factory (scaled): a file changing one of its
    # keys keeps the others of the factory's default, not of OdometryNoise()
    cfg = loads_config("[front_end.odometry_noise]\nper_metre = 0.5", base=MapConfig())
    want = MapConfig().front_end.odometry_noise
    assert cfg.front_end.odometry_noise == dataclasses.replace(want, per_metre=0.5)


def test_tuple_and_optional_fields_are_checked():
    from scanclique.slam import SlamConfig

    with pytest.raises(ConfigError, match="'initial_sigma' expects an array of 3 numbers"):
        loads_config("initial_sigma = [0.1, 0.1]", cls=SlamConfig)
    with pytest.raises(ConfigError, match="'init_range' expects an array of 2 numbers"):
        loads_config('init_range = [0.0, "far"]', cls=SlamConfig)
    with pytest.raises(ConfigError, match="'sigma_range' expects a number"):
        loads_config('sigma_range = "none"', cls=SlamConfig)  # not an optional field
    assert loads_config("control_bias_sigma = 0.02", cls=SlamConfig).control_bias_sigma == 0.02
    with pytest.raises(ConfigError, match="base is a SlamConfig, not a MatchConfig"):
        loads_config("", base=SlamConfig(), cls=MatchConfig)
