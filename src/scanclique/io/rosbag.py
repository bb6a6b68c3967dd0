"""Reader for ROS 1 (``.bag``) and ROS 2 (directory with ``metadata.yaml``, ``.db3``,
``.mcap``) bags through ``rosbags`` (pure Python, no ROS install): ``sensor_msgs/LaserScan``
and ``sensor_msgs/MultiEchoLaserScan`` messages become :class:`~scanclique.scan.Scan`
records.

Conventions
-----------
* **Topic.** ``topic`` names the laser's topic; when None, the bag must hold exactly
  one LaserScan or MultiEchoLaserScan topic.
* **Echoes.** Of a ``MultiEchoLaserScan`` (a Hokuyo UTM-30LX-EW's, the 2D lasers of
  Cartographer's Deutsches Museum bags) each beam's first echo is its range (the one
  Cartographer takes too), and a beam with no echo is NaN (no reading: no point, and no
  free space painted along it).
* **Beams.** ``angle_min + i * angle_increment``; ``range_min`` / ``range_max`` from the
  message (ranges outside are kept and masked by :class:`Scan`). A message with a negative
  ``angle_increment`` (scanning clockwise) is reversed into increasing angles, each beam
  keeping its angle.
  Beam angles are brought into [-pi, pi), where the matcher measures bearings (``atan2``):
  shifted by whole turns, and a full circle published from 0 to 2 pi (the TurtleBot3's
  LDS-01 driver) rolled to start at -pi, its two halves meeting where they meet on the
  sensor (:func:`_wrap_beams`). Left outside [-pi, pi), the raw-scan score saw no free
  space behind the robot: a pose 0.5 m off scored 0.03 instead of -0.42.
* **Timestamp.** The message header's stamp (seconds), else the bag's receive time.
* **Odometry.** From ``nav_msgs/Odometry`` (the topic ``odom_topic``, default: the only
  Odometry topic) or, when the bag has none, from ``tf`` / ``tf2_msgs/TFMessage``
  transforms ``odom_frame -> base_frame`` (default ``odom`` -> ``base_link``, or
  ``base_footprint``); interpolated at each scan's stamp (linear in x and y, along the
  shorter arc in the heading); None outside their time span. It is the *laser's* pose, as
  a Scan's poses are: the robot's composed with the laser's mounting, the chain of
  transforms from the robot's frame (``base_frame``, an Odometry message's
  ``child_frame_id``, ``base_link`` or ``base_footprint``) to the scans' ``frame_id`` in
  the bag's static transforms (``/tf_static``, or fixed ones on ``/tf``), projected to
  the plane. A laser mounted upside down (a roll of pi, within about 25 degrees) sees
  the plane mirrored: its beams are mirrored (angle ``a`` becomes ``-a``) into the frame
  turned upright about its x axis, whose pose on the robot is the mounting, and a warning
  says so (with or without odometry). When the bag holds no such chain, or the laser is
  tilted (its z axis more than about 25 degrees off the robot's, up or down), the robot's
  pose is used and a warning says so: a laser mounted turned on the robot (sideways,
  backwards) then disagrees with the odometry, which the mapper reads as the laser's
  motion (300 Intel scans with the odometry of a robot that carries the laser backwards:
  66 scans placed by odometry, the mean error of consecutive poses 0.45 m, against 0.028
  m with the laser's odometry).
* ``Scan.reference`` is None; ``Scan.source`` is ``"<bag>:<topic>#<index>"``.

Errors
------
A missing or unreadable bag (a ROS 2 ``.db3`` or ``.mcap`` file whose ``metadata.yaml``
is not beside it among them), a topic that is not in the bag or not a LaserScan, a bag
with several LaserScan topics and no ``topic``, and a message that cannot be
deserialised or is inconsistent (ranges of another length than the angles imply, non-
finite angles) raise :class:`~scanclique.errors.ParseError` naming the bag, the topic and
the message index.
"""

from __future__ import annotations

import logging
import math
import os
import struct
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from ..errors import ParseError, ScanCliqueError, ScanError
from ..geometry import Pose2, pose_at
from ..scan import MAX_SWEEP, Scan

log = logging.getLogger(__name__)

__all__ = ["read_bag", "mounting", "LASERSCAN", "MULTIECHO", "LASERS", "ODOMETRY", "TF"]

LASERSCAN = ("sensor_msgs/msg/LaserScan", "sensor_msgs/LaserScan")
MULTIECHO = ("sensor_msgs/msg/MultiEchoLaserScan", "sensor_msgs/MultiEchoLaserScan")
#: the message types of a laser's topic
LASERS = LASERSCAN + MULTIECHO
ODOMETRY = ("nav_msgs/msg/Odometry", "nav_msgs/Odometry")
TF = ("tf2_msgs/msg/TFMessage", "tf2_msgs/TFMessage", "tf/tfMessage", "tf/msg/tfMessage")


def _yaw(q) -> float:
    """The heading (rad) of quaternion ``q``; :class:`ScanError` when it is not finite
    (an infinite component otherwise reads as a heading: z = inf as 3 pi / 4)."""
    x, y, z, w = float(q.x), float(q.y), float(q.z), float(q.w)
    if not all(map(math.isfinite, (x, y, z, w))):
        raise ScanError(f"the quaternion ({x}, {y}, {z}, {w}) is not finite")
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _stamp(msg, t_ns: int) -> float:
    h = getattr(msg, "header", None)
    st = getattr(h, "stamp", None)
    if st is not None:
        sec = getattr(st, "sec", None)
        nsec = getattr(st, "nanosec", getattr(st, "nsec", 0))
        if sec is not None and (sec or nsec):
            return float(sec) + 1e-9 * float(nsec)
    return 1e-9 * t_ns


def _wrap_beams(r: np.ndarray, ang: np.ndarray, along: np.ndarray):
    """Ranges and increasing beam angles ``ang`` with the angles in [-pi, pi): shifted by
    whole turns when that brings them all in; a full circle (``n`` beams spanning ``n``
    increments of about 2 pi) rolled so that it starts at -pi. A field of view that
    crosses pi but is no full circle is returned as given (rolling it would make its two
    ends neighbours). ``(r, ang, along)``: another per-beam array (each beam's place in
    its message) follows them."""
    if ang.size == 0 or (ang[0] >= -math.pi and ang[-1] < math.pi):
        return r, ang, along
    two_pi = 2.0 * math.pi
    shifted = ang - two_pi * math.floor((ang[0] + math.pi) / two_pi)
    if shifted[-1] < math.pi:
        return r, shifted, along
    inc = (ang[-1] - ang[0]) / (ang.size - 1) if ang.size > 1 else 0.0
    if abs(ang[-1] - ang[0] + inc - two_pi) > 0.5 * inc:
        return r, ang, along
    wrapped = np.mod(shifted + math.pi, two_pi) - math.pi
    order = np.argsort(wrapped, kind="stable")
    if not np.all(np.diff(wrapped[order]) > 0):
        return r, ang, along
    return r[order], wrapped[order], along[order]


def _time_increment(msg, n: int, name: str, topic: str, warned: set) -> float | None:
    """The message's ``time_increment`` (s between beams in its order; REP 117: the stamp
    is the first beam's). None when it is 0 or not finite, or the sweep would last more
    than :data:`scanclique.scan.MAX_SWEEP` (warned once per topic: a driver's
    placeholder, not the scanner's timing)."""
    t_inc = float(getattr(msg, "time_increment", 0.0) or 0.0)
    if not math.isfinite(t_inc) or t_inc == 0.0 or n == 0:
        return None
    if abs(t_inc) * (n - 1) > MAX_SWEEP:
        if topic not in warned:
            warned.add(topic)
            log.warning(
                "%s: %s: time_increment %g s over %d beams would be a sweep of %g s, more "
                "than %g s: not the beams' times",
                name, topic, t_inc, n, abs(t_inc) * (n - 1), MAX_SWEEP,
            )  # fmt: skip
        return None
    return t_inc


#: a scan whose beams span at least this (rad) is a rotating lidar's full circle
FULL_CIRCLE = math.radians(350.0)


def _inferred_sweeps(scans: list[Scan], places: list, name: str, topic: str) -> list[Scan]:
    """A topic of full circles (every scan's beams span :data:`FULL_CIRCLE`: a rotating
    lidar, one revolution a scan) whose published sweep is shorter than half the period
    between its scans, or absent (``time_increment`` 0), is given the times a revolution
    takes: beam ``i`` of a message of ``n`` at ``i * period / n`` (the median period
    between stamps), in the message's order (``places``: each beam's place in it), warned.
    Drivers that do not know their timing publish 0, and some a wrong one (the LDS-01's
    gives a sweep of about 11 ms for its 200 ms revolution). Which way round and where the
    stamp lies is then for the mapper to check (:mod:`scanclique.mapping.sweep`)."""
    if len(scans) < 3 or not all(_span(s) >= FULL_CIRCLE for s in scans):
        return scans
    stamps = np.array([s.timestamp for s in scans], dtype=float)
    steps = np.diff(stamps)
    steps = steps[steps > 0]
    period = float(np.median(steps)) if steps.size else 0.0
    if not 0.0 < period <= MAX_SWEEP:
        return scans
    published = float(np.median([np.ptp(s.beam_times) if s.beam_times is not None else 0.0
                                 for s in scans]))  # fmt: skip
    if published >= 0.5 * period:
        return scans
    log.warning(
        "%s: %s: full circles every %.3g s whose beams are published %.3g s apart (a sweep "
        "of %.3g s): a rotating lidar sweeps in its period; each beam's time taken as its "
        "place in the revolution (which way round, and where the stamp lies, is checked "
        "when mapping)",
        name, topic, period, published / max(scans[0].n_beams - 1, 1), published,
    )  # fmt: skip
    return [
        replace(s, beam_times=idx * (period / len(idx)))
        for s, idx in zip(scans, places, strict=True)
    ]


def _span(scan: Scan) -> float:
    """The angle a scan's beams cover (rad), one beam's width included."""
    a = scan.angles
    return float(a[-1] - a[0] + np.median(np.diff(a))) if a.size > 1 else 0.0


def _first_echoes(echoes) -> list[float]:
    """The ranges of a ``MultiEchoLaserScan``'s beams (``sensor_msgs/LaserEcho``): each
    one's first echo, NaN for a beam with none."""
    return [e.echoes[0] if len(e.echoes) else math.nan for e in echoes]


#: a float32 NaN's bits (a beam with no echo)
_NAN_BITS = int(np.array(np.nan, dtype=np.float32).view(np.uint32))


def _first_echo_words(words: list, k: int) -> tuple[list, int]:
    """A ``LaserEcho[]`` from ``words`` (uint32, from word ``k``): its length, then per
    beam a count and that many float32s. Returns each beam's first float32's bits (NaN
    bits for none) and the word after the array; IndexError when the words run out."""
    count = words[k]
    if count > len(words) - k:
        raise IndexError(count)
    out, k = [_NAN_BITS] * count, k + 1
    for i in range(count):
        m = words[k]
        if m:
            out[i] = words[k + 1]
        k += 1 + m
    if k > len(words):
        raise IndexError(k)
    return out, k


def _multi_echo_fast(raw: bytes, ros2: bool):
    """A ``sensor_msgs/MultiEchoLaserScan`` read from its bytes, without rosbags'
    deserialiser (which builds an object per echo array: about 5 ms a 1081-beam message
    with intensities against 0.3-0.4 ms here; ``benchmarks/reading.py``): the fields
    :func:`read_bag` uses, with ``ranges`` the beams' first echoes (float32 array, NaN
    for none). ROS 1 serialisation, or ROS 2's little-endian CDR (4-byte aligned after
    its 4-byte encapsulation header). None when the bytes are not that layout to the last
    byte (another definition under the same name, big-endian CDR): the caller then
    deserialises them with rosbags, which names what is wrong."""
    n = len(raw)
    try:
        if ros2:
            if n < 4 or raw[0] != 0 or raw[1] != 1:
                return None
            sec, nsec, size = struct.unpack_from("<iII", raw, 4)
            frame = raw[16 : 16 + size].rstrip(b"\0")
            pos = 16 + size
            pos += -(pos - 4) % 4
        else:
            _, sec, nsec, size = struct.unpack_from("<IIII", raw, 0)
            frame = raw[16 : 16 + size]
            pos = 16 + size
        fields = struct.unpack_from("<7f", raw, pos)
        pos += 28
        words = np.frombuffer(raw, dtype="<u4", count=(n - pos) // 4, offset=pos).tolist()
        first, k = _first_echo_words(words, 0)
        _, k = _first_echo_words(words, k)
    except (struct.error, IndexError, ValueError):
        return None
    if n - (pos + 4 * k) not in ((0,) if not ros2 else (0, 1, 2, 3)):
        return None
    a0, a1, inc, t_inc, t_scan, r0, r1 = fields
    return SimpleNamespace(
        header=SimpleNamespace(
            stamp=SimpleNamespace(sec=sec, nanosec=nsec),
            frame_id=frame.decode("utf-8", "replace"),
        ),
        angle_min=a0, angle_max=a1, angle_increment=inc, time_increment=t_inc,
        scan_time=t_scan, range_min=r0, range_max=r1,
        ranges=np.array(first, dtype=np.uint32).view(np.float32),
    )  # fmt: skip


def _rotation(q) -> np.ndarray:
    """The rotation matrix of a ``geometry_msgs/Quaternion`` (normalised)."""
    x, y, z, w = float(q.x), float(q.y), float(q.z), float(q.w)
    n = math.sqrt(x * x + y * y + z * z + w * w) or 1.0
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _link(tr, links: dict) -> None:
    """Keep the first transform of ``tr``'s child frame: ``links[child] = (parent, R, t)``
    (points of the child in the parent's frame: ``R p + t``)."""
    child = tr.child_frame_id.lstrip("/")
    if child and child not in links:
        v = tr.transform.translation
        t = np.array([float(v.x), float(v.y), float(v.z)])
        links[child] = (tr.header.frame_id.lstrip("/"), _rotation(tr.transform.rotation), t)


def mounting(links: dict, laser: str, bases) -> tuple[Pose2 | None, str, bool]:
    """The laser frame's pose on the robot (a base frame), projected to the plane, from
    the transforms ``links`` (:func:`_link`), and whether the laser is upside down.

    Returns ``(pose, reason, upside_down)``: ``pose`` None and the reason when the chain
    is not there or the laser is tilted (its z axis more than about 25 degrees off the
    robot's z axis, or off its opposite). A laser upside down (its z axis within about 25
    degrees of the robot's pointing down: a roll of pi) sees the plane mirrored, a beam at
    angle ``a`` in its frame pointing at ``-a`` in the frame turned upright about its x
    axis; ``pose`` is then that upright frame's, and the beams are to be mirrored
    (``upside_down`` True)."""
    laser = laser.lstrip("/")
    R, t = np.eye(3), np.zeros(3)
    frame, hops = laser, 0
    while frame not in bases:
        if frame not in links or hops > 64:
            where = f"no transform from {'/'.join(bases)} to the scans' frame {laser!r}"
            return None, where, False
        parent, Rp, tp = links[frame]
        R, t = Rp @ R, Rp @ t + tp
        frame, hops = parent, hops + 1
    upside_down = R[2, 2] <= -0.9
    if upside_down:
        R = R @ np.diag([1.0, -1.0, -1.0])  # turned upright about its own x axis
    if R[2, 2] < 0.9:
        return None, f"the laser frame {laser!r} is tilted on {frame!r}", False
    return Pose2(float(t[0]), float(t[1]), math.atan2(R[1, 0], R[0, 0])), "", upside_down


BAG_SUFFIXES = (".bag", ".db3", ".mcap")


#: a message whose contents are not its connection's type (a damaged bag's index)
_DAMAGED = "unreadable: its contents are not the topic's message type (a damaged bag?)"


def _messages(reader, connections: list, name: str):
    """``reader.messages(connections=connections)``, its ``(connection, time_ns, raw)``
    triples, none for no connections (an empty list would mean every message to rosbags);
    a damaged bag's error while reading them (rosbags and its storage raise their own
    types: ``KeyError``, ``AssertionError``, ``UnicodeDecodeError``, ``ReaderError``,
    SQLite's ``CorruptError``) a :class:`ParseError` naming the bag."""
    if not connections:
        return
    it = iter(reader.messages(connections=connections))
    k = 0
    while True:
        try:
            item = next(it)
        except StopIteration:
            return
        except Exception as exc:  # noqa: BLE001  (rosbags raises its own types)
            topics = ", ".join(sorted({c.topic for c in connections}))
            raise ParseError(
                name, None,
                f"the bag is damaged: reading {topics} failed after {k} message(s) "
                f"({type(exc).__name__}: {exc})",
            ) from None  # fmt: skip
        k += 1
        yield item


def is_bag(path: str | os.PathLike) -> bool:
    """True for a ROS 1 ``.bag`` file or a ROS 2 bag (a directory with ``metadata.yaml``,
    or a ``.db3`` / ``.mcap`` file)."""
    p = Path(path)
    if p.is_dir():
        return (p / "metadata.yaml").is_file()
    return p.suffix in BAG_SUFFIXES


def read_bag(
    path: str | os.PathLike,
    topic: str | None = None,
    *,
    odom_topic: str | None = None,
    odom_frame: str = "odom",
    base_frame: str | None = None,
) -> list[Scan]:
    """The LaserScan messages of a ROS 1 or ROS 2 bag as scans, with odometry.

    Parameters
    ----------
    path : path
        A ROS 1 ``.bag`` file, or a ROS 2 bag directory (or its ``.db3`` / ``.mcap``).
    topic : str, optional
        The LaserScan topic (default: the only one in the bag).
    odom_topic : str, optional
        The ``nav_msgs/Odometry`` topic (default: the only one; tf when there is none).
    odom_frame, base_frame : str
        The tf frames of the odometry (parent) and the robot (child; default
        ``base_link``, else ``base_footprint``) when odometry comes from tf. With a
        ``nav_msgs/Odometry`` topic, the robot's frame for the laser's mounting is also
        its messages' ``child_frame_id``.

    Returns
    -------
    list of Scan
        In the order of the bag's messages.

    Raises
    ------
    ParseError
        See the module docstring.
    """
    try:
        from rosbags.highlevel import AnyReader  # noqa: PLC0415
    except ImportError as exc:  # pragma: no cover - optional dependency
        raise ScanCliqueError(
            f"reading ROS bags needs rosbags ({exc}): pip install 'scanclique[map]'"
        ) from None
    p = Path(path)
    name = str(path)
    if not p.exists():
        raise ParseError(name, None, "no such bag (file or ROS 2 bag directory)")
    bag = p.parent if p.is_file() and p.suffix in (".db3", ".mcap") else p
    if bag is not p and not (bag / "metadata.yaml").is_file():
        raise ParseError(
            name, None,
            f"a ROS 2 bag's {p.suffix} file without the bag's metadata.yaml beside it: "
            "rosbags reads a ROS 2 bag as its directory; give the directory, or recreate "
            f"metadata.yaml with 'ros2 bag reindex {bag}'",
        )  # fmt: skip
    try:
        reader = AnyReader([bag])
        reader.open()
    except Exception as exc:  # noqa: BLE001  (rosbags raises its own types)
        raise ParseError(
            name, None, f"not a readable ROS bag ({type(exc).__name__}: {exc})"
        ) from None
    try:
        conns = list(reader.connections)
        scans_c = [c for c in conns if c.msgtype in LASERS]
        if topic is not None:
            named = [c for c in conns if c.topic == topic]
            if not named:
                have = sorted({c.topic for c in conns})
                raise ParseError(name, None, f"topic {topic!r} is not in the bag (topics: {have})")
            bad = [c for c in named if c.msgtype not in LASERS]
            if bad:
                raise ParseError(
                    name, None,
                    f"topic {topic!r} holds {bad[0].msgtype}, expected sensor_msgs/LaserScan "
                    "or MultiEchoLaserScan",
                )  # fmt: skip
            scans_c = named
        else:
            topics = sorted({c.topic for c in scans_c})
            if not topics:
                raise ParseError(
                    name,
                    None,
                    "the bag holds no sensor_msgs/LaserScan (or MultiEchoLaserScan) topic",
                )
            if len(topics) > 1:
                raise ParseError(
                    name,
                    None,
                    f"the bag holds several laser topics {topics}: name one (read_bag's "
                    "topic=, read_scans' laser=, the CLI's --topic or --laser)",
                )
            topic = topics[0]
        # odometry: nav_msgs/Odometry, else tf
        odo_c = [c for c in conns if c.msgtype in ODOMETRY]
        if odom_topic is not None:
            odo_c = [c for c in odo_c if c.topic == odom_topic]
            if not odo_c:
                raise ParseError(
                    name,
                    None,
                    f"odometry topic {odom_topic!r} is not a nav_msgs/Odometry topic of the bag",
                )
        elif len({c.topic for c in odo_c}) > 1:
            odo_c = [c for c in odo_c if c.topic == sorted({c.topic for c in odo_c})[0]]
        tf_all = [c for c in conns if c.msgtype in TF]
        tf_c = tf_all if not odo_c else []
        static_c = [c for c in tf_all if c.topic.rstrip("/").endswith("tf_static")]
        o_times: list[float] = []
        o_poses: list[Pose2] = []
        seen: set[tuple[str, str]] = set()  # (parent, child) frames of the moving transforms
        bases = (base_frame,) if base_frame else ("base_link", "base_footprint")
        links: dict = {}  # child frame -> (parent, R, t): the robot's fixed frames
        for c, _t_ns, raw in _messages(reader, static_c, name):
            try:
                for tr in reader.deserialize(raw, c.msgtype).transforms:
                    _link(tr, links)
            except Exception as exc:  # noqa: BLE001
                raise ParseError(
                    name, None, f"{c.topic}: cannot deserialise {c.msgtype} ({exc})"
                ) from None
        for k, (c, t_ns, raw) in enumerate(_messages(reader, odo_c + tf_c, name)):
            try:
                msg = reader.deserialize(raw, c.msgtype)
            except Exception as exc:  # noqa: BLE001
                raise ParseError(
                    name, None, f"{c.topic}: cannot deserialise {c.msgtype} ({exc})"
                ) from None
            try:  # a non-finite pose is a ScanError of Pose2: say which message holds it
                if c.msgtype in ODOMETRY:
                    pp = msg.pose.pose
                    child = str(getattr(msg, "child_frame_id", "")).lstrip("/")
                    if child and not o_poses and child not in bases and base_frame is None:
                        bases = (child, *bases)  # the frame whose pose the odometry gives
                    o_times.append(_stamp(msg, t_ns))
                    o_poses.append(Pose2(pp.position.x, pp.position.y, _yaw(pp.orientation)))
                else:
                    for tr in msg.transforms:
                        if c not in static_c and len(seen) < 20:
                            seen.add(
                                (tr.header.frame_id.lstrip("/"), tr.child_frame_id.lstrip("/"))
                            )
                        if c not in static_c and tr.child_frame_id.lstrip("/") not in bases:
                            _link(tr, links)  # a fixed frame published on /tf
                        if (
                            tr.header.frame_id.lstrip("/") == odom_frame
                            and tr.child_frame_id.lstrip("/") in bases
                        ):
                            q = tr.transform
                            o_times.append(_stamp(tr, t_ns))
                            o_poses.append(
                                Pose2(q.translation.x, q.translation.y, _yaw(q.rotation))
                            )
            except ScanCliqueError as exc:
                raise ParseError(name, None, f"{c.topic} message {k}: {exc}") from None
            except (AttributeError, TypeError) as exc:  # a damaged bag's other message type
                raise ParseError(name, None, f"{c.topic} message {k}: {_DAMAGED} ({exc})") from None
        if tf_c and not o_poses:
            pairs = ", ".join(f"{a} -> {b}" for a, b in sorted(seen)) or "none"
            log.warning(
                "%s: the bag's tf has no %s -> %s transform (its moving transforms: %s): "
                "the scans have no odometry; name the frames with odom_frame= and "
                "base_frame= (scanclique map --odom-frame, --base-frame)",
                name, odom_frame, " or ".join(bases), pairs,
            )  # fmt: skip
        order = np.argsort(o_times, kind="stable")
        o_times = [o_times[k] for k in order]
        o_poses = [o_poses[k] for k in order]
        o_rows = np.array([p.as_array() for p in o_poses]).reshape(-1, 3)
        out: list[Scan] = []
        mount: Pose2 | None = None
        mirrored = False  # the laser is upside down (its beams mirrored, mounting())
        warned: set = set()  # topics whose time_increment was refused
        places: list = []  # per scan, each beam's place in its message
        # a MultiEchoLaserScan from its bytes (ROS 2's CDR or ROS 1's); rosbags else
        is2 = getattr(reader, "is2", None)
        bytewise = is2 if isinstance(is2, bool) else None
        for k, (c, t_ns, raw) in enumerate(_messages(reader, scans_c, name)):
            where = f"{name}:{c.topic}#{k}"
            fast = None
            if c.msgtype in MULTIECHO and bytewise is not None:
                fast = _multi_echo_fast(raw, bytewise)
            try:
                msg = fast or reader.deserialize(raw, c.msgtype)
            except Exception as exc:  # noqa: BLE001
                raise ParseError(
                    name,
                    None,
                    f"{c.topic} message {k}: cannot deserialise {c.msgtype.split('/')[-1]} ({exc})",
                ) from None
            try:
                r = msg.ranges if fast or c.msgtype not in MULTIECHO else _first_echoes(msg.ranges)
                r = np.asarray(r, dtype=float)
                inc = float(msg.angle_increment)
                a0 = float(msg.angle_min)
            except (AttributeError, TypeError, ValueError) as exc:
                raise ParseError(name, None, f"{c.topic} message {k}: {_DAMAGED} ({exc})") from None
            if not (math.isfinite(inc) and math.isfinite(a0)) or inc == 0.0:
                raise ParseError(
                    name, None,
                    f"{c.topic} message {k}: angle_min {a0} / angle_increment {inc} "
                    "do not define beams",
                )  # fmt: skip
            ang = a0 + inc * np.arange(r.size)
            t_inc = _time_increment(msg, r.size, name, c.topic, warned)
            idx = np.arange(r.size, dtype=float)  # each beam's place in the message's order
            if inc < 0:
                r, ang, idx = r[::-1].copy(), ang[::-1].copy(), idx[::-1].copy()
            span = float(msg.angle_max) - a0
            expect = int(round(span / inc)) + 1 if math.isfinite(span) else r.size
            if r.size == 0 or abs(expect - r.size) > 1:
                raise ParseError(
                    name, None,
                    f"{c.topic} message {k}: {r.size} ranges, but angle_min..angle_max by "
                    f"angle_increment gives {expect} beams",
                )  # fmt: skip
            if k == 0:
                try:
                    mount, why, mirrored = mounting(links, msg.header.frame_id, bases)
                except ScanCliqueError as exc:  # a non-finite transform on the way
                    raise ParseError(
                        name, None,
                        f"the transforms from the robot to {c.topic}'s frame "
                        f"{msg.header.frame_id!r}: {exc}",
                    ) from None  # fmt: skip
                if mirrored:
                    log.warning(
                        "%s: the laser frame %r is upside down on the robot: its beams are "
                        "mirrored (angle a -> -a) into the frame turned upright about its x "
                        "axis, mounted at %s",
                        name, msg.header.frame_id, mount,
                    )  # fmt: skip
                if o_poses and mount is None and msg.header.frame_id.lstrip("/") not in bases:
                    log.warning(
                        "%s: %s: the odometry is the robot's, taken as the laser's (a laser "
                        "mounted turned on the robot then disagrees with it)",
                        name,
                        why,
                    )
                elif o_poses and mount is not None:
                    log.info("%s: the laser is mounted at %s on the robot", name, mount)
            if mirrored:
                r, ang, idx = r[::-1].copy(), -ang[::-1], idx[::-1].copy()
            r, ang, idx = _wrap_beams(r, ang, idx)
            places.append(idx)
            t = _stamp(msg, t_ns)
            odo = pose_at(o_times, o_rows, t, tol=1e-9) if o_poses else None
            try:
                out.append(
                    Scan(
                        r, ang,
                        range_min=max(float(msg.range_min), 0.0),
                        range_max=float(msg.range_max),
                        timestamp=t,
                        odometry=odo if odo is None or mount is None else odo @ mount,
                        source=where,
                        beam_times=None if t_inc is None else t_inc * idx,
                    )
                )  # fmt: skip
            except ScanCliqueError as exc:  # named below by bag, topic and message
                why = str(exc).removeprefix(f"{where}: ")
                raise ParseError(name, None, f"{c.topic} message {k}: {why}") from None
        return _inferred_sweeps(out, places, name, topic)
    finally:
        reader.close()
