"""ROS 1 / ROS 2 bag reader (scanclique.io.rosbag), on bags this test writes itself with
rosbags from scans of a CARMEN log (never a downloaded bag)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

pytest.importorskip("rosbags")

from rosbags.typesys import Stores, get_typestore  # noqa: E402

from scanclique.errors import ParseError  # noqa: E402
from scanclique.geometry import Pose2  # noqa: E402
from scanclique.io.rosbag import read_bag  # noqa: E402
from scanclique.mapping.run import is_bag  # noqa: E402


@pytest.fixture(scope="module")
def carmen_scans(request):
    from conftest import require_log

    from scanclique import datasets

    require_log("intel")
    return datasets.load_log("intel")[:25]


def _msgs(ts, ros1: bool):
    T = ts.types
    Time = T["builtin_interfaces/msg/Time"]

    def header(t: float, frame: str, seq: int):
        sec = int(math.floor(t))
        stamp = Time(sec=sec, nanosec=int(round((t - sec) * 1e9)))
        if ros1:
            return T["std_msgs/msg/Header"](seq=seq, stamp=stamp, frame_id=frame)
        return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def quat(th: float):
        return T["geometry_msgs/msg/Quaternion"](
            x=0.0, y=0.0, z=math.sin(th / 2), w=math.cos(th / 2)
        )

    def laser(scan, seq):
        a = scan.angles
        return T["sensor_msgs/msg/LaserScan"](
            header=header(scan.timestamp, "laser", seq),
            angle_min=float(a[0]), angle_max=float(a[-1]), angle_increment=float(a[1] - a[0]),
            time_increment=0.0, scan_time=0.0, range_min=0.0, range_max=float(scan.range_max),
            ranges=np.asarray(scan.ranges, dtype=np.float32), intensities=np.zeros(0, np.float32),
        )  # fmt: skip

    def odom(t, p: Pose2, seq):
        V3 = T["geometry_msgs/msg/Vector3"]
        pose = T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=p.x, y=p.y, z=0.0), orientation=quat(p.theta)
        )
        tw = T["geometry_msgs/msg/Twist"](
            linear=V3(x=0.0, y=0.0, z=0.0), angular=V3(x=0.0, y=0.0, z=0.0)
        )
        return T["nav_msgs/msg/Odometry"](
            header=header(t, "odom", seq), child_frame_id="base_link",
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=tw, covariance=np.zeros(36)),
        )  # fmt: skip

    def tf(t, p: Pose2, seq):
        tr = T["geometry_msgs/msg/TransformStamped"](
            header=header(t, "odom", seq), child_frame_id="base_link",
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=p.x, y=p.y, z=0.0),
                rotation=quat(p.theta),
            ),
        )  # fmt: skip
        return T["tf2_msgs/msg/TFMessage"](transforms=[tr])

    return laser, odom, tf


def _drive(seed: int, n: int):
    """``n`` scans of a short simulated drive (181 beams) with odometry."""
    from scanclique.sim import office_world, simulate_trajectory

    rng = np.random.default_rng(seed)
    return simulate_trajectory(rng, office_world(rng, length=12.0), n, n_beams=181)


def _odo_samples(scans):
    """Odometry at the scans' times and half-way between them (the reader interpolates)."""
    out = []
    for a, b in zip(scans[:-1], scans[1:], strict=True):
        out.append((a.timestamp, a.odometry))
        out.append((0.5 * (a.timestamp + b.timestamp), None))
    out.append((scans[-1].timestamp, scans[-1].odometry))
    return [(t, p) for t, p in out if p is not None]


def write_ros1(path, scans, odometry=True):
    from rosbags.rosbag1 import Writer

    ts = get_typestore(Stores.ROS1_NOETIC)
    laser, odom, _ = _msgs(ts, ros1=True)
    with Writer(path) as w:
        cs = w.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=ts)
        co = w.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=ts) if odometry else None
        for k, s in enumerate(scans):
            t_ns = int(s.timestamp * 1e9)
            if co is not None:
                w.write(
                    co,
                    t_ns,
                    ts.serialize_ros1(odom(s.timestamp, s.odometry, k), "nav_msgs/msg/Odometry"),
                )
            w.write(cs, t_ns + 1, ts.serialize_ros1(laser(s, k), "sensor_msgs/msg/LaserScan"))


def _ros2_msgs():
    """:func:`_msgs` of ROS 2 (Humble): the laser, odometry and tf message makers."""
    return _msgs(get_typestore(Stores.ROS2_HUMBLE), ros1=False)


def _write_bag2(path, rows, storage="sqlite3"):
    """A ROS 2 bag of ``rows``: (topic, time ns, message) in writing order; a topic's
    connection (of its message's type) is added when it first comes."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    ts = get_typestore(Stores.ROS2_HUMBLE)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conns = {}
        for topic, t_ns, msg in rows:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msg.__msgtype__, typestore=ts)
            w.write(conns[topic], t_ns, ts.serialize_cdr(msg, msg.__msgtype__))


def write_ros2(path, scans, storage="sqlite3"):
    laser, _, tf = _ros2_msgs()

    def rows():
        for k, s in enumerate(scans):
            t_ns = int(s.timestamp * 1e9)
            yield "/tf", t_ns, tf(s.timestamp, s.odometry, k)
            yield "/front/scan", t_ns + 1, laser(s, k)

    _write_bag2(path, rows(), storage)


def _same(scans, back):
    assert len(back) == len(scans)
    for s, b in zip(scans, back, strict=True):
        np.testing.assert_allclose(b.ranges, s.ranges, rtol=1e-6, atol=1e-5)
        np.testing.assert_allclose(b.angles, s.angles, atol=1e-6)
        assert b.timestamp == pytest.approx(s.timestamp, abs=1e-6)
        t, r = b.odometry.distance_to(s.odometry)
        assert t < 1e-6 and r < 1e-6
        assert b.reference is None


@pytest.mark.realdata
def test_ros1_bag_round_trip(tmp_path, carmen_scans):
    path = tmp_path / "intel.bag"
    write_ros1(path, carmen_scans)
    assert is_bag(path)
    back = read_bag(path)
    _same(carmen_scans, back)
    assert back[0].source.endswith("/scan#0")
    # scanclique.read_scans hands bags to the bag reader
    import scanclique as sc

    _same(carmen_scans, sc.read_scans(path))
    # a bag's lasers are its topics: the map's --laser (CARMEN message types) is refused
    from scanclique.errors import ScanCliqueError
    from scanclique.mapping.run import load_map_log

    assert len(load_map_log(path)[0]) == len(carmen_scans)
    with pytest.raises(ScanCliqueError, match="--laser applies to CARMEN logs only"):
        load_map_log(path, laser="FLASER")


@pytest.mark.realdata
def test_ros2_bag_with_tf(tmp_path, carmen_scans):
    path = tmp_path / "intel_ros2"
    write_ros2(path, carmen_scans)
    assert is_bag(path)
    back = read_bag(path, topic="/front/scan")
    _same(carmen_scans, back)


@pytest.mark.realdata
def test_bag_maps(tmp_path, carmen_scans):
    from scanclique.mapping import map_scans

    path = tmp_path / "intel.bag"
    write_ros1(path, carmen_scans)
    r = map_scans(read_bag(path))
    assert r.used_odometry and all(p is not None for p in r.poses)
    direct = map_scans(carmen_scans)
    for p, q in zip(r.poses, direct.poses, strict=True):
        assert p.distance_to(q)[0] < 1e-3


@pytest.mark.realdata
def test_interpolated_odometry(tmp_path, carmen_scans):
    # odometry only at every other scan: the reader interpolates at the others' stamps
    from rosbags.rosbag1 import Writer

    ts = get_typestore(Stores.ROS1_NOETIC)
    laser, odom, _ = _msgs(ts, ros1=True)
    path = tmp_path / "sparse.bag"
    with Writer(path) as w:
        cs = w.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=ts)
        co = w.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=ts)
        for k, s in enumerate(carmen_scans):
            if k % 2 == 0:
                w.write(
                    co,
                    int(s.timestamp * 1e9),
                    ts.serialize_ros1(odom(s.timestamp, s.odometry, k), "nav_msgs/msg/Odometry"),
                )
            w.write(
                cs,
                int(s.timestamp * 1e9) + 1,
                ts.serialize_ros1(laser(s, k), "sensor_msgs/msg/LaserScan"),
            )
    back = read_bag(path)
    s0, s1, s2 = carmen_scans[0], carmen_scans[1], carmen_scans[2]
    u = (s1.timestamp - s0.timestamp) / (s2.timestamp - s0.timestamp)
    exp_x = s0.odometry.x + u * (s2.odometry.x - s0.odometry.x)
    assert back[1].odometry.x == pytest.approx(exp_x, abs=1e-6)
    assert back[-1].odometry is None or len(carmen_scans) % 2 == 1


@pytest.mark.realdata
def test_bad_bags(tmp_path, carmen_scans):
    with pytest.raises(ParseError, match="no such bag"):
        read_bag(tmp_path / "missing.bag")
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"this is not a bag at all\n" * 10)
    with pytest.raises(ParseError, match="junk.bag: not a readable ROS bag"):
        read_bag(junk)
    path = tmp_path / "intel.bag"
    write_ros1(path, carmen_scans[:3])
    with pytest.raises(ParseError, match=r"topic '/laser' is not in the bag"):
        read_bag(path, topic="/laser")
    with pytest.raises(
        ParseError,
        match=r"topic '/odom' holds nav_msgs/msg/Odometry, expected sensor_msgs/LaserScan",
    ):
        read_bag(path, topic="/odom")
    no_scan = tmp_path / "odom_only.bag"
    from rosbags.rosbag1 import Writer

    ts = get_typestore(Stores.ROS1_NOETIC)
    _, odom, _ = _msgs(ts, ros1=True)
    with Writer(no_scan) as w:
        co = w.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=ts)
        w.write(co, 1, ts.serialize_ros1(odom(1.0, Pose2(0, 0, 0), 0), "nav_msgs/msg/Odometry"))
    with pytest.raises(ParseError, match=r"holds no sensor_msgs/LaserScan \(or MultiEcho"):
        read_bag(no_scan)


def test_ros2_mcap_bag(tmp_path):
    # MCAP is ROS 2's default storage since Iron: the directory and its .mcap file read
    # alike; the .mcap file without its metadata.yaml gets a named error saying so
    import shutil

    scans = _drive(5, 4)
    path = tmp_path / "sim_mcap"
    write_ros2(path, scans, storage="mcap")
    (file,) = path.glob("*.mcap")
    assert is_bag(path) and is_bag(file)
    _same(scans, read_bag(path))
    _same(scans, read_bag(file))
    bare = tmp_path / "bare"
    bare.mkdir()
    shutil.copy(file, bare / file.name)
    with pytest.raises(ParseError, match=r"\.mcap file without the bag's metadata\.yaml"):
        read_bag(bare / file.name)


def test_odometry_on_tf_under_other_frame_names(tmp_path, caplog):
    # a robot whose tf names its frames odom_combined -> chassis: without the names the
    # scans have no odometry, and the reader says which transforms it saw; with them
    # (scanclique map --odom-frame --base-frame) the odometry is read

    from scanclique.mapping.run import load_map_log

    scans = _drive(7, 4)
    laser, _, tf = _ros2_msgs()
    path = tmp_path / "frames"
    rows = []
    for k, s in enumerate(scans):
        t_ns = int(s.timestamp * 1e9)
        m = tf(s.timestamp, s.odometry, k)
        m.transforms[0].header.frame_id = "odom_combined"
        m.transforms[0].child_frame_id = "chassis"
        rows += [("/tf", t_ns, m), ("/scan", t_ns + 1, laser(s, k))]
    _write_bag2(path, rows)
    with caplog.at_level("WARNING", logger="scanclique"):
        back = read_bag(path)
    assert [b.odometry for b in back] == [None] * 4
    assert "tf has no odom -> base_link or base_footprint transform" in caplog.text
    assert "its moving transforms: odom_combined -> chassis" in caplog.text
    _same(scans, read_bag(path, odom_frame="odom_combined", base_frame="chassis"))
    got, _ = load_map_log(path, odom_frame="odom_combined", base_frame="chassis")
    _same(scans, got)
    from scanclique.errors import ScanCliqueError

    with pytest.raises(ScanCliqueError, match="--odom-frame applies to ROS bags only"):
        load_map_log("intel", odom_frame="odom")


def test_a_bag_of_two_lasers_is_read_one_topic_at_a_time(tmp_path):
    # read_scans' laser (and the place commands' --laser) names a bag's LaserScan topic,
    # as it names a CARMEN log's message type
    from typer.testing import CliRunner

    import scanclique as sc
    from scanclique import cli

    scans = _drive(11, 6)
    laser, _, tf = _ros2_msgs()
    path = tmp_path / "two"
    rows = []
    for k, s in enumerate(scans):
        t_ns = int(s.timestamp * 1e9)
        rows.append(("/front/scan", t_ns, laser(s, k)))
        if k % 2 == 0:
            rows.append(("/rear/scan", t_ns + 1, laser(s, k)))
    _write_bag2(path, rows)
    with pytest.raises(ParseError, match=r"several laser topics .*read_scans' laser="):
        sc.read_scans(path)
    assert len(sc.read_scans(path, laser="/front/scan")) == 6
    assert len(sc.read_scans(path, laser="/rear/scan")) == 3
    with pytest.raises(ParseError, match="topic '/scan' is not in the bag"):
        sc.read_scans(path, laser="/scan")
    from scanclique.errors import ScanCliqueError
    from scanclique.mapping.run import load_map_log

    assert len(load_map_log(path, laser="/rear/scan")[0]) == 3  # the map's --laser too
    with pytest.raises(ScanCliqueError, match="name two topics"):
        load_map_log(path, "/front/scan", "/rear/scan")
    db = tmp_path / "p.db"
    r = CliRunner().invoke(cli.app, ["places", "add", str(db), str(path), "--laser", "/rear/scan"])
    assert r.exit_code == 0, r.output
    assert "added 3 places" in r.output
    # --topic, as scanclique map names a bag's laser, is the same option
    db = tmp_path / "q.db"
    r = CliRunner().invoke(cli.app, ["places", "add", str(db), str(path), "--topic", "/rear/scan"])
    assert r.exit_code == 0 and "added 3 places" in r.output, r.output


def test_bags_without_odometry_have_none(tmp_path):
    scans = _drive(2, 4)
    path = tmp_path / "sim.bag"
    write_ros1(path, scans, odometry=False)
    back = read_bag(path)
    assert [b.odometry for b in back] == [None] * 4


def _write_mounted(path, scans, chain, odom_child=None):
    """A ROS 2 bag of ``scans`` (frame ``laser``) with the odometry of ``base_link`` on
    ``/tf`` (or, with ``odom_child``, of that frame on an ``/odom`` topic) and, on
    ``/tf_static``, ``chain``: (parent, child, Pose2[, roll]) links from the robot to the
    laser (yaw, then a roll about the turned x axis)."""

    ts = get_typestore(Stores.ROS2_HUMBLE)
    laser, odom, tf = _msgs(ts, ros1=False)
    T = ts.types
    stamp = T["builtin_interfaces/msg/Time"](sec=0, nanosec=0)

    def quat(p, roll=0.0):
        cy, sy = math.cos(p.theta / 2), math.sin(p.theta / 2)
        cr, sr = math.cos(roll / 2), math.sin(roll / 2)
        return T["geometry_msgs/msg/Quaternion"](x=cy * sr, y=sy * sr, z=sy * cr, w=cy * cr)

    links = [
        T["geometry_msgs/msg/TransformStamped"](
            header=T["std_msgs/msg/Header"](stamp=stamp, frame_id=parent),
            child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=p.x, y=p.y, z=0.1),
                rotation=quat(p, *roll),
            ),
        )
        for parent, child, p, *roll in chain
    ]
    rows = [("/tf_static", int(scans[0].timestamp * 1e9) - 1,
             T["tf2_msgs/msg/TFMessage"](transforms=links))]  # fmt: skip
    for k, s in enumerate(scans):
        t_ns = int(s.timestamp * 1e9)
        if odom_child is None:
            rows.append(("/tf", t_ns, tf(s.timestamp, s.odometry, k)))
        else:
            msg = odom(s.timestamp, s.odometry, k)
            msg.child_frame_id = odom_child
            rows.append(("/odom", t_ns, msg))
        rows.append(("/scan", t_ns + 1, laser(s, k)))
    _write_bag2(path, rows)


def test_the_mounting_chain_composes_in_the_plane():
    from scanclique.io.rosbag import mounting

    class Tr:  # the fields _link reads
        def __init__(self, parent, child, x, y, yaw, roll=0.0):
            V = type("V", (), {})
            self.header = V()
            self.header.frame_id = parent
            self.child_frame_id = child
            self.transform = V()
            self.transform.translation = V()
            t = self.transform.translation
            t.x, t.y, t.z = x, y, 0.3
            q = V()  # yaw then roll
            cy, sy, cr, sr = (
                math.cos(yaw / 2),
                math.sin(yaw / 2),
                math.cos(roll / 2),
                math.sin(roll / 2),
            )
            q.w, q.x, q.y, q.z = cy * cr, cy * sr, sy * sr, sy * cr
            self.transform.rotation = q

    from scanclique.io.rosbag import _link

    links: dict = {}
    for tr in (Tr("/base_link", "mast", 1.0, 0.0, math.pi / 2), Tr("mast", "laser", 1.0, 0.0, 0.0)):
        _link(tr, links)
    m, why, upside_down = mounting(links, "/laser", ("base_link",))
    assert why == "" and not upside_down
    assert m.distance_to(Pose2(1.0, 1.0, math.pi / 2))[0] < 1e-12
    assert abs(m.theta - math.pi / 2) < 1e-12
    assert mounting(links, "laser", ("base_footprint",))[0] is None  # no chain to it
    # upside down (a roll of pi, 20 degrees off): the frame turned upright about its x axis
    _link(Tr("base_link", "flipped", 0.5, 0.0, 0.3, roll=math.pi - 0.35), links)
    m, why, upside_down = mounting(links, "flipped", ("base_link",))
    assert why == "" and upside_down and m.distance_to(Pose2(0.5, 0.0, 0.3))[0] < 1e-12
    assert abs(m.theta - 0.3) < 1e-12
    _link(Tr("base_link", "tilted", 0.0, 0.0, 0.0, roll=math.pi / 2), links)
    m, why, upside_down = mounting(links, "tilted", ("base_link",))
    assert m is None and "is tilted" in why and not upside_down


@pytest.mark.realdata
def test_a_laser_mounted_backwards_is_mapped_through_its_mounting(tmp_path, carmen_scans, caplog):
    from scanclique.mapping import map_scans

    # the Intel laser on a robot that drives it backwards: the robot's frame is the
    # laser's turned by a half turn, which the bag's static transforms say in two links
    M = Pose2(0.0, 0.0, math.pi)
    robot = [dataclasses.replace(s, odometry=s.odometry @ M.inverse()) for s in carmen_scans]
    chain = [("base_link", "mast", Pose2(0.0, 0.0, math.pi / 2)),
             ("mast", "laser", Pose2(0.0, 0.0, math.pi / 2))]  # fmt: skip
    path = tmp_path / "backwards"
    _write_mounted(path, robot, chain)
    back = read_bag(path)
    for s, b in zip(carmen_scans, back, strict=True):  # the laser's odometry again
        t, r = b.odometry.distance_to(s.odometry)
        assert t < 1e-6 and r < 1e-6
    direct = map_scans(carmen_scans)
    mapped = map_scans(back)
    for p, q in zip(mapped.poses, direct.poses, strict=True):
        assert p.distance_to(q)[0] < 1e-3
    # an Odometry topic names the robot's frame: the chain starts there
    chassis = tmp_path / "chassis"
    _write_mounted(chassis, robot, [("chassis", "laser", M)], odom_child="chassis")
    t, r = read_bag(chassis)[5].odometry.distance_to(carmen_scans[5].odometry)
    assert t < 1e-6 and r < 1e-6
    # without the static transforms the reader says so and hands over the robot's
    bare = tmp_path / "bare"
    write_ros2(bare, robot)
    with caplog.at_level("WARNING", logger="scanclique"):
        plain = read_bag(bare)
    assert "no transform from base_link/base_footprint to the scans' frame 'laser'" in caplog.text
    assert plain[3].odometry.distance_to(robot[3].odometry)[0] < 1e-6


def test_a_laser_mounted_upside_down_is_mirrored_upright(tmp_path, caplog):
    """A laser mounted upside down (a roll of pi in the static transforms) publishes the
    plane mirrored: a beam at angle a in its frame points at -a in the frame turned upright.
    The reader mirrors the beams back and mounts that upright frame: the scans and the
    laser's odometry of the same drive with the laser upright, and the same map."""
    from scanclique.mapping import map_scans

    scans = _drive(2, 12)
    M = Pose2(0.2, -0.1, math.pi / 2)  # the laser on the robot, upright equivalent
    robot = [dataclasses.replace(s, odometry=s.odometry @ M.inverse()) for s in scans]
    # what the upside-down laser publishes: the range seen at a, at angle -a
    published = [dataclasses.replace(s, ranges=s.ranges[::-1], angles=-s.angles[::-1])
                 for s in robot]  # fmt: skip
    path = tmp_path / "upside_down"
    _write_mounted(path, published, [("base_link", "laser", M, math.pi)])
    with caplog.at_level("WARNING", logger="scanclique"):
        back = read_bag(path)
    assert "is upside down on the robot: its beams are mirrored" in caplog.text
    for s, b in zip(scans, back, strict=True):
        np.testing.assert_allclose(b.angles, s.angles, atol=1e-6)
        np.testing.assert_allclose(b.ranges, s.ranges, rtol=1e-6, atol=1e-5)
        t, r = b.odometry.distance_to(s.odometry)
        assert t < 1e-6 and r < 1e-6
    upright = map_scans(scans)
    for p, q in zip(map_scans(back).poses, upright.poses, strict=True):
        assert p.distance_to(q)[0] < 1e-3


@pytest.mark.parametrize("ros1", [True, False])
def test_multi_echo_bytes_of_another_layout_go_to_rosbags(ros1):
    """The MultiEchoLaserScan byte reader answers only for the standard layout to the last
    byte: a LaserScan's bytes, a message cut short or one byte longer, and big-endian CDR
    give None (rosbags then deserialises them and names what is wrong)."""
    from scanclique.io.rosbag import _multi_echo_fast

    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    T = ts.types
    laser, _, _ = _msgs(ts, ros1=ros1)
    scan = _drive(1, 6)[0]
    m = laser(scan, 0)
    ser = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    echo = T["sensor_msgs/msg/LaserEcho"]
    fields = {f: getattr(m, f) for f in m.__dataclass_fields__ if f != "__msgtype__"}
    fields.update(ranges=[echo(echoes=np.array([r], np.float32)) for r in scan.ranges],
                  intensities=[])  # fmt: skip
    kind = "sensor_msgs/msg/MultiEchoLaserScan"
    good = bytes(ser(T[kind](**fields), kind))
    got = _multi_echo_fast(good, not ros1)
    assert got is not None and got.header.frame_id == m.header.frame_id
    np.testing.assert_array_equal(got.ranges, np.asarray(scan.ranges, np.float32))
    assert got.angle_increment == np.float32(m.angle_increment)
    assert _multi_echo_fast(bytes(ser(m, "sensor_msgs/msg/LaserScan")), not ros1) is None
    assert _multi_echo_fast(good[:-4], not ros1) is None
    assert _multi_echo_fast(good + b"\0" * 4, not ros1) is None
    assert _multi_echo_fast(b"", not ros1) is None
    if not ros1:
        assert _multi_echo_fast(b"\0\0" + good[2:], True) is None  # big-endian CDR


@pytest.mark.parametrize("ros1", [True, False])
def test_multi_echo_scans_read_their_first_echoes(tmp_path, ros1, monkeypatch):
    """sensor_msgs/MultiEchoLaserScan (Cartographer's Deutsches Museum bags, a Hokuyo
    UTM-30LX-EW): each beam's first echo, NaN for a beam with none; mapped as the
    LaserScan of the same ranges."""
    from scanclique import map_scans

    scans = _drive(4, 6)
    store = Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE
    ts = get_typestore(store)
    T = ts.types
    laser, _, tf = _msgs(ts, ros1=ros1)
    kind = "sensor_msgs/msg/MultiEchoLaserScan"

    def echoes(scan):
        out = []
        for i, r in enumerate(np.asarray(scan.ranges, np.float32)):
            e = [] if i % 17 == 5 else [r, r + 2.0] if i % 3 == 0 else [r]  # none, two, one
            out.append(T["sensor_msgs/msg/LaserEcho"](echoes=np.array(e, np.float32)))
        return out

    def multi(scan, k):
        m = laser(scan, k)
        fields = {f: getattr(m, f) for f in m.__dataclass_fields__ if f != "__msgtype__"}
        fields.update(ranges=echoes(scan), intensities=[])
        return T[kind](**fields)

    if ros1:
        from rosbags.rosbag1 import Writer

        path = tmp_path / "multi.bag"
        with Writer(path) as w:
            c = w.add_connection("/horizontal_laser_2d", kind, typestore=ts)
            for k, s in enumerate(scans):
                w.write(c, int(s.timestamp * 1e9), ts.serialize_ros1(multi(s, k), kind))
    else:
        path = tmp_path / "multi2"
        _write_bag2(path, (("/horizontal_laser_2d", int(s.timestamp * 1e9), multi(s, k))
                           for k, s in enumerate(scans)))  # fmt: skip
    import scanclique.io.rosbag as rb

    fast, read = rb._multi_echo_fast, []
    monkeypatch.setattr(rb, "_multi_echo_fast", lambda *a: read.append(fast(*a)) or read[-1])
    back = read_bag(path)
    assert len(read) == len(scans) and all(m is not None for m in read)  # from the bytes
    import rosbags.highlevel as hl

    class Vague(hl.AnyReader):  # a rosbags whose reader does not say ROS 1 or 2 by a bool
        is2 = property(lambda self: np.bool_(self._two), lambda self, v: setattr(self, "_two", v))

    monkeypatch.setattr(hl, "AnyReader", Vague)
    read.clear()
    vague = read_bag(path)
    assert read == []  # rosbags' deserialiser, not the bytes
    monkeypatch.undo()
    for a, b in zip(vague, back, strict=True):
        assert np.array_equal(a.ranges, b.ranges, equal_nan=True) and a.timestamp == b.timestamp
    monkeypatch.setattr(rb, "_multi_echo_fast", lambda *a: None)  # rosbags' deserialiser
    for a, b in zip(read_bag(path), back, strict=True):
        assert np.array_equal(a.ranges, b.ranges, equal_nan=True)
        assert np.array_equal(a.angles, b.angles) and a.timestamp == b.timestamp
        assert (a.range_min, a.range_max, a.source) == (b.range_min, b.range_max, b.source)
    assert len(back) == len(scans) and all(b.odometry is None for b in back)
    for s, b in zip(scans, back, strict=True):
        none = np.arange(s.n_beams) % 17 == 5
        assert np.isnan(b.ranges[none]).all()
        np.testing.assert_allclose(b.ranges[~none], s.ranges[~none], rtol=1e-6, atol=1e-5)
        np.testing.assert_allclose(b.angles, s.angles, atol=1e-6)
    # the same ranges as a LaserScan bag (NaN where no echo): the same scans, the same map
    holed = [dataclasses.replace(s, ranges=b.ranges) for s, b in zip(scans, back, strict=True)]
    plain = tmp_path / "plain"
    _write_bag2(plain, (("/scan", int(s.timestamp * 1e9), _ros2_msgs()[0](s, k))
                        for k, s in enumerate(holed)))  # fmt: skip
    ref = read_bag(plain)
    for a, b in zip(ref, back, strict=True):
        assert np.array_equal(a.ranges, b.ranges, equal_nan=True)
        assert np.array_equal(a.angles, b.angles) and a.range_max == b.range_max
    a, m = map_scans(ref), map_scans(back)
    assert a.poses == m.poses and sum(p == "match" for p in m.placed_by) >= 4


def test_a_damaged_bag_is_a_parse_error_naming_it(tmp_path):
    """A byte of a bag's chunks or index damaged, or a ROS 2 bag's database cut short:
    rosbags and SQLite raise their own types (KeyError, AssertionError,
    UnicodeDecodeError, CorruptError, or a message of another type; found by fuzzing,
    session 46), read as a ParseError naming the bag, or the scans when the damage is in
    the numbers."""
    scans = _drive(3, 3)
    good = tmp_path / "good.bag"
    write_ros1(good, scans)
    data = good.read_bytes()
    bad = tmp_path / "bad.bag"
    failed = 0
    step = 21  # the second half of the bag, every 21st byte (the chunks and the index)
    for at in range(step * (len(data) // (2 * step)), len(data), step):
        b = bytearray(data)
        b[at] ^= 0xFF
        bad.write_bytes(bytes(b))
        try:
            read_bag(bad)
        except ParseError as exc:
            assert "bad.bag" in str(exc)
            failed += 1
    assert failed > 0
    d = tmp_path / "cut"
    write_ros2(d, scans)
    db3 = next(d.glob("*.db3"))
    db3.write_bytes(db3.read_bytes()[:-72])
    with pytest.raises(ParseError, match="cut"):
        read_bag(d)


def test_a_non_finite_static_transform_is_a_parse_error_naming_the_bag(tmp_path):
    from types import SimpleNamespace

    scans = _drive(4, 2)
    chain = [("base_link", "laser", SimpleNamespace(x=math.nan, y=0.0, theta=0.0))]
    path = tmp_path / "nan_tf"
    _write_mounted(path, scans, chain)
    with pytest.raises(ParseError, match=r"nan_tf: the transforms from the robot to /scan"):
        read_bag(path)


def test_a_non_finite_odometry_quaternion_is_a_parse_error_naming_the_message(tmp_path):
    """An Odometry orientation with z = inf read as a heading of 3 pi / 4 (fuzzing,
    session 46); now refused, naming the topic and the message."""
    from rosbags.rosbag1 import Writer

    ts = get_typestore(Stores.ROS1_NOETIC)
    laser, odom, _ = _msgs(ts, ros1=True)
    scans = _drive(5, 2)
    path = tmp_path / "inf_quat.bag"
    with Writer(path) as w:
        cs = w.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=ts)
        co = w.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=ts)
        for k, s in enumerate(scans):
            t_ns = int(s.timestamp * 1e9)
            msg = odom(s.timestamp, s.odometry, k)
            if k == 1:
                msg.pose.pose.orientation.z = math.inf
            w.write(co, t_ns, ts.serialize_ros1(msg, "nav_msgs/msg/Odometry"))
            w.write(cs, t_ns + 1, ts.serialize_ros1(laser(s, k), "sensor_msgs/msg/LaserScan"))
    with pytest.raises(
        ParseError, match=r"inf_quat.bag: /odom message 1: .*quaternion.*not finite"
    ):
        read_bag(path)
