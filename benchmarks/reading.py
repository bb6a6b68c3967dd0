"""Reading ROS bags: milliseconds per laser message, ``scanclique.io.read_bag`` against
rosbags' own deserialiser, side by side.

The first scans of a shared log (``fr079-raw``: 360 beams) are written into bags the way
a robot records them, with ``rosbags`` (no ROS install): ``sensor_msgs/LaserScan`` and
``sensor_msgs/MultiEchoLaserScan`` (a second echo on every third beam and an intensity
per echo, as a Hokuyo UTM-30LX-EW publishes; Cartographer's Deutsches Museum bags), each
as a ROS 1 ``.bag`` and a ROS 2 bag. Each bag is read by ``read_bag`` (a
MultiEchoLaserScan from its bytes, :func:`scanclique.io.rosbag._multi_echo_fast`) and by
``read_bag`` with rosbags deserialising every message (what it did before session 35),
and the two readings are checked identical. Best of ``--repeat`` runs each, and the ratio.

    python benchmarks/reading.py
    python benchmarks/reading.py --scans 300 --out /tmp/reading

Writes benchmarks/results/reading-<date>.json and .md.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import common  # noqa: E402

from scanclique.datasets import load_log  # noqa: E402
from scanclique.io import rosbag  # noqa: E402

LASERSCAN, MULTIECHO = "sensor_msgs/msg/LaserScan", "sensor_msgs/msg/MultiEchoLaserScan"


def message(ts, kind: str, scan, k: int, ros1: bool):
    """``scan`` as a message of ``kind`` for the typestore ``ts``."""
    T = ts.types
    sec, nsec = divmod(int(round(scan.timestamp * 1e9)), 1_000_000_000)
    stamp = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
    head = {"seq": k} if ros1 else {}
    header = T["std_msgs/msg/Header"](**head, stamp=stamp, frame_id="laser")
    r = np.asarray(scan.ranges, np.float32)
    inc = float(scan.angles[1] - scan.angles[0])
    common_fields = dict(
        header=header, angle_min=float(scan.angles[0]), angle_max=float(scan.angles[-1]),
        angle_increment=inc, time_increment=0.0, scan_time=0.025,
        range_min=float(scan.range_min), range_max=float(scan.range_max),
    )  # fmt: skip
    if kind == LASERSCAN:
        return T[kind](**common_fields, ranges=r, intensities=np.ones_like(r))
    echo = T["sensor_msgs/msg/LaserEcho"]
    ranges = [echo(echoes=np.array([v, v + 1.5] if i % 3 == 0 else [v], np.float32))
              for i, v in enumerate(r)]  # fmt: skip
    bright = [echo(echoes=np.ones(len(e.echoes), np.float32)) for e in ranges]
    return T[kind](**common_fields, ranges=ranges, intensities=bright)


def write(path: Path, scans, kind: str, ros1: bool) -> None:
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if ros1:
        from rosbags.rosbag1 import Writer

        ser, writer = ts.serialize_ros1, Writer(path)
    else:
        from rosbags.rosbag2 import Writer

        ser, writer = ts.serialize_cdr, Writer(path, version=9)
    with writer as w:
        c = w.add_connection("/scan", kind, typestore=ts)
        for k, s in enumerate(scans):
            w.write(c, int(round(s.timestamp * 1e9)), ser(message(ts, kind, s, k, ros1), kind))


def best_ms(path: Path, repeat: int, n: int) -> tuple[float, list]:
    best, out = np.inf, None
    for _ in range(repeat):
        t = time.perf_counter()
        out = rosbag.read_bag(path)
        best = min(best, time.perf_counter() - t)
    return 1e3 * best / n, out


def same(a: list, b: list) -> bool:
    return len(a) == len(b) and all(
        np.array_equal(x.ranges, y.ranges, equal_nan=True)
        and np.array_equal(x.angles, y.angles)
        and (x.timestamp, x.range_min, x.range_max) == (y.timestamp, y.range_min, y.range_max)
        for x, y in zip(a, b, strict=True)
    )


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--log", default="fr079-raw", help="a registered log whose scans are written")
    ap.add_argument("--scans", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", default=None, help="path stem (default: benchmarks/results/...)")
    args = ap.parse_args(argv)
    if not common.log_available(args.log, (args.log,)):
        return
    t0 = time.perf_counter()
    scans = load_log(args.log)[: args.scans]
    beams = scans[0].n_beams
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for kind in (LASERSCAN, MULTIECHO):
            for ros1 in (True, False):
                path = Path(tmp) / f"{kind.split('/')[-1]}-{'ros1' if ros1 else 'ros2'}"
                path = path.with_suffix(".bag") if ros1 else path
                write(path, scans, kind, ros1)
                ours, a = best_ms(path, args.repeat, len(scans))
                fast = rosbag._multi_echo_fast
                rosbag._multi_echo_fast = lambda raw, ros2: None  # rosbags deserialises all
                try:
                    theirs, b = best_ms(path, args.repeat, len(scans))
                finally:
                    rosbag._multi_echo_fast = fast
                rows.append({
                    "message": kind.split("/")[-1], "bag": "ROS 1" if ros1 else "ROS 2",
                    "messages": len(scans), "beams": beams, "read_bag_ms": ours,
                    "rosbags_ms": theirs, "ratio": theirs / ours, "identical": same(a, b),
                })  # fmt: skip
                print(rows[-1], flush=True)
    lines = [
        f"Log `{args.log}`, its first {len(scans)} scans ({beams} beams); best of "
        f"{args.repeat} readings; ms per message.",
        "",
        "| message | bag | read_bag ms | with rosbags deserialising ms | ratio | identical |",
        "|---|---|---|---|---|---|",
    ]
    lines += [
        f"| {r['message']} | {r['bag']} | {r['read_bag_ms']:.3f} | {r['rosbags_ms']:.3f} | "
        f"x{r['ratio']:.2f} | {r['identical']} |"
        for r in rows
    ]
    common.publish(args.out, "reading", "Reading ROS bags (benchmarks/reading.py)", lines, t0, rows)


if __name__ == "__main__":
    main()
