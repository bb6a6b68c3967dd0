"""Hostile arguments to the writers of map and SLAM runs and to the place tracker (found
by fuzzing): a named error before anything is written, not a raw NumPy or zip error, a
silently dropped row or a NaN in the file."""

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from scanclique.errors import ArgumentError, ConfigError
from scanclique.geometry import Pose2
from scanclique.io.tum import write_tum
from scanclique.mapping import outputs as map_out
from scanclique.mapping.config import OccupancyConfig
from scanclique.mapping.occupancy import OccupancyGrid, occupancy_grid
from scanclique.places import PlaceDB, track
from scanclique.places.locate import Localiser
from scanclique.scan import Scan
from scanclique.slam import outputs as slam_out


def scan():
    return Scan(np.full(5, 2.0), np.linspace(-1.0, 1.0, 5), range_max=30.0)


def grid(log_odds=None, resolution=0.1):
    lo = np.zeros((3, 4), np.float32) if log_odds is None else log_odds
    return OccupancyGrid(lo, resolution, (0.0, 0.0))


# -- occupancy_grid --------------------------------------------------------------------


def test_occupancy_grid_refuses_poses_too_far_apart():
    scans = [scan()] * 4
    poses = [Pose2(1e308, 0, 0), Pose2(-1e308, 0, 0), None, None]
    with pytest.raises(ConfigError, match="cells"):
        occupancy_grid(scans, poses, timing=None)


@pytest.mark.parametrize("poses", [[(0.0, 0.0, 0.0)] * 4, np.zeros((4, 3))])
def test_occupancy_grid_refuses_poses_that_are_not_pose2(poses):
    with pytest.raises(ArgumentError, match=r"poses\[0\]"):
        occupancy_grid([scan()] * 4, poses, timing=None)


def test_occupancy_grid_refuses_items_that_are_not_scans():
    with pytest.raises(ArgumentError, match=r"scans\[1\]"):
        occupancy_grid([scan(), "scan"], [Pose2(0, 0, 0)] * 2, timing=None)


@pytest.mark.parametrize(
    "kw", [{"log_odds_hit": 1e300}, {"clamp": 1e300}, {"log_odds_miss": -1e300}]
)
def test_occupancy_config_refuses_log_odds_past_float32(kw):
    with pytest.raises(ConfigError, match=next(iter(kw))):
        OccupancyConfig(**kw)


# -- map writers -----------------------------------------------------------------------


def test_write_png_refuses_bad_closures_covariances_and_grids(tmp_path):
    poses = [Pose2(0, 0, 0), Pose2(1, 0, 0)]
    out = tmp_path / "map.png"
    with pytest.raises(ArgumentError, match="closure"):
        map_out.write_png(out, grid(), poses, closures=[SimpleNamespace(i=0, j=5)])
    with pytest.raises(ArgumentError, match="covariances"):
        map_out.write_png(out, grid(), poses, covariances=[np.eye(3)])
    with pytest.raises(ArgumentError, match="resolution"):
        map_out.write_png(out, grid(resolution=math.nan), poses)
    assert not out.exists()


def test_write_map_refuses_a_grid_that_is_not_2d(tmp_path):
    with pytest.raises(ArgumentError, match="2-D"):
        map_out.write_map(tmp_path / "m.pgm", tmp_path / "m.yaml", grid(np.zeros(4, np.float32)))
    assert not (tmp_path / "m.pgm").exists()


def test_write_covariances_refuses_lengths_that_differ(tmp_path):
    poses = [Pose2(0, 0, 0), Pose2(1, 0, 0)]
    with pytest.raises(ArgumentError, match="covariances"):
        map_out.write_covariances(tmp_path / "c.csv", poses, [np.eye(3)], [0.0, 1.0])
    with pytest.raises(ArgumentError, match="timestamps"):
        map_out.write_covariances(tmp_path / "c.csv", poses, [np.eye(3)] * 2, [0.0])


def test_map_write_report_takes_arrays(tmp_path):
    map_out.write_report(tmp_path / "r.json", {"c": np.arange(3), "x": np.float64("nan")})
    assert json.loads((tmp_path / "r.json").read_text()) == {"c": [0, 1, 2], "x": None}


# -- TUM and landmarks -----------------------------------------------------------------


@pytest.mark.parametrize(
    ("poses", "times", "match"),
    [
        ([Pose2(0, 0, 0)], [math.nan], "finite"),
        (np.array([[math.nan, 0.0, 0.0]]), [0.0], "finite"),
        ([Pose2(0, 0, 0), Pose2(1, 0, 0)], [0.0], "timestamps"),
        ([(1.0, 2.0)], [0.0], r"poses\[0\]"),
    ],
)
def test_write_tum_refuses_nan_and_missing_timestamps(tmp_path, poses, times, match):
    with pytest.raises(ArgumentError, match=match):
        write_tum(tmp_path / "t.tum", poses, times)
    assert not (tmp_path / "t.tum").exists()


def test_slam_write_tum_refuses_nan(tmp_path):
    with pytest.raises(ArgumentError, match="finite"):
        slam_out.write_tum(tmp_path / "t.tum", [0.0], [[math.nan, 0.0, 0.0]])


def test_write_landmarks_refuses_rows_that_do_not_match(tmp_path):
    out = tmp_path / "l.csv"
    with pytest.raises(ArgumentError, match="landmarks"):
        slam_out.write_landmarks(out, [1, 2, 3], [[0, 0]], [np.eye(2)] * 3, [1, 1, 1])
    with pytest.raises(ArgumentError, match="ids"):
        slam_out.write_landmarks(out, [math.nan], [[0, 0]], [np.eye(2)], [1])
    assert not out.exists()
    slam_out.write_landmarks(out, [7], [[1.0, 2.0]], [np.eye(2)], [3])
    assert out.read_text().splitlines()[1] == "7,1.0000,2.0000,1,0,1,3"


# -- places.track ----------------------------------------------------------------------


def test_map_poses_refuses_poses_that_are_not_pose2():
    with pytest.raises(ArgumentError, match="Pose2"):
        track.MapPoses.of({1: (0, 0, 0)})


def test_near_places_refuses_a_count_that_is_not_an_integer():
    places = track.MapPoses.of({1: Pose2(0, 0, 0)})
    with pytest.raises(ConfigError, match="n must be an integer"):
        track.near_places(places, Pose2(0, 0, 0), 2.0, 2.5)


@pytest.mark.parametrize("kw", [{"k": -1}, {"candidates": -1}, {"k": 2.5}])
def test_localiser_checks_its_counts_when_made(tmp_path, kw):
    with PlaceDB(tmp_path / "p.db") as db, pytest.raises(ConfigError, match=next(iter(kw))):
        Localiser(db, **kw)


def test_localiser_add_refuses_a_query_that_is_not_a_flag():
    loc = object.__new__(Localiser)  # the flag is checked before the localiser's state
    with pytest.raises(ArgumentError, match="query"):
        loc.add(scan(), query="no")


def test_track_std_and_predict_refuse_a_path_that_is_not_finite():
    with pytest.raises(ArgumentError, match="path"):
        track.track_std(math.nan)
    fix = track.Fix(0, Pose2(0, 0, 0), 0.0)
    with pytest.raises(ArgumentError, match="path_now"):
        track.predict(fix, Pose2(0, 0, 0), Pose2(1, 0, 0), math.nan)
