"""Checks a ROS 2 bag of `rodtrack track --mcap BAG --mcap-ros2 --out ROWS.csv` with rosbags
(a reader of rosbag2 files independent of rodtrack) against the CSV of the same run.

    python .ci/ros2_bag.py BAG.mcap ROWS.csv [BALL.csv]

- rosbags opens the file as a rosbag2 MCAP storage file (profile ros2, its indexes, its
  chunks, uncompressed or lz4) and parses every channel's offered_qos_profiles;
- the schema the file carries describes ROS 2's sensor_msgs/msg/JointState: the same RIHS01
  type hash as rosbags' own definition of ROS 2 Humble's;
- every message decodes with the file's schema and with rosbags' own definition alike, and
  rosbags serialises it back to the same bytes;
- every message holds the CSV rows of its camera (or fused) and frame that have a value
  (status ok, predicted, conflict): rod<k>_slide in m and m/s, rod<k>_turn in rad and rad/s;
- with BALL.csv (`--ball-out` of the same run), every ball row with a place (ok, predicted) is
  one geometry_msgs/msg/PointStamped on `.../ball` (m, in the table frame `rodtrack/t1`, z the
  ball's radius: the same for every message) and one geometry_msgs/msg/Vector3Stamped on
  `.../ball/velocity` (m/s), stamped with its capture time, decoded with the file's schemas
  and rosbags' own definitions alike; a ball row without a place has no message.
"""

import csv
import sys
from pathlib import Path

from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

JS = "sensor_msgs/msg/JointState"
PS = "geometry_msgs/msg/PointStamped"
VS = "geometry_msgs/msg/Vector3Stamped"


def ball_rows(path: Path) -> dict:
    """(topic, ns) -> (x, y) in m and (vx, vy) in m/s of each ball row with a place."""
    want = {}
    with path.open() as f:
        for r in csv.DictReader(f):
            if r["status"] not in ("ok", "predicted"):
                continue
            s, ns = r["timestamp_s"].split(".")
            t = int(s) * 1_000_000_000 + int(ns) * 1000
            cam = "fused" if r["camera"] == "fused" else f"cam/cam{r['camera']}"
            m = lambda k: float(r[k]) * 1e-3
            want[(f"/rodtrack/t1/{cam}/ball", t)] = (m("x_mm"), m("y_mm"), 0.5e-6)
            want[(f"/rodtrack/t1/{cam}/ball/velocity", t)] = (m("vx_mm_s"), m("vy_mm_s"), 0.5e-4)
    return want


def main(bag: Path, rows: Path, ball: Path | None) -> None:
    want = {}
    balls = ball_rows(ball) if ball else {}
    with rows.open() as f:
        for r in csv.DictReader(f):
            s, ns = r["timestamp_s"].split(".")
            t = int(s) * 1_000_000_000 + int(ns)
            cam = "fused" if r["camera"] == "fused" else f"cam/cam{r['camera']}"
            joints = want.setdefault((f"/rodtrack/t1/{cam}/joint_states", t), [])
            if r["status"] in ("ok", "predicted", "conflict"):
                k = r["rod"]
                joints.append((f"rod{k}_slide", float(r["position_mm"]) * 1e-3,
                               float(r["velocity_mm_s"]) * 1e-3, 0.5e-7, 0.5e-6))
                joints.append((f"rod{k}_turn", float(r["angle_unwrapped_rad"]),
                               float(r["angular_velocity_rad_s"]), 0.5e-6, 0.5e-4))
    humble = get_typestore(Stores.ROS2_HUMBLE)
    seen = 0
    with AnyReader([bag]) as reader:
        types = {c.msgtype for c in reader.connections}
        assert types == ({JS, PS, VS} if ball else {JS}), reader.connections
        for c in reader.connections:
            assert c.ext.serialization_format == "cdr", c
            assert len(c.ext.offered_qos_profiles) == 1, c
        for ty in types:
            assert reader.typestore.hash_rihs01(ty) == humble.hash_rihs01(ty), ty
        topics = {c.topic for c in reader.connections}
        heights, ball_seen = set(), 0
        for c, t, raw in reader.messages():
            if c.msgtype != JS:
                msg, ref = reader.deserialize(raw, c.msgtype), humble.deserialize_cdr(raw, c.msgtype)
                assert bytes(humble.serialize_cdr(ref, c.msgtype)) == bytes(raw), (c.topic, t)
                assert msg.header.frame_id == "rodtrack/t1", msg.header.frame_id
                stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
                assert stamp == t, (c.topic, stamp, t)
                v = msg.point if c.msgtype == PS else msg.vector
                x, y, tol = balls[(c.topic, t)]
                assert abs(v.x - x) <= tol * 1.001 and abs(v.y - y) <= tol * 1.001, (c.topic, t, v, x, y)
                if c.msgtype == PS:
                    heights.add(v.z)
                else:
                    assert v.z == 0.0, v
                ball_seen += 1
                continue
            msg = reader.deserialize(raw, JS)
            ref = humble.deserialize_cdr(raw, JS)
            assert bytes(humble.serialize_cdr(ref, JS)) == bytes(raw), (c.topic, t)
            assert msg.name == ref.name and list(msg.position) == list(ref.position)
            stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            assert stamp == t, (c.topic, stamp, t)
            joints = want[(c.topic, t)]
            assert msg.name == [j[0] for j in joints], (c.topic, t, msg.name)
            for j, p, v in zip(joints, msg.position, msg.velocity, strict=True):
                assert abs(p - j[1]) <= j[3] * 1.001, (c.topic, t, j, p)
                assert abs(v - j[2]) <= j[4] * 1.001, (c.topic, t, j, v)
            assert len(msg.effort) == 0
            seen += 1
    assert seen == len(want), (seen, len(want))
    assert ball_seen == len(balls), (ball_seen, len(balls))
    print(f"{bag.name}: {seen} JointState messages on {len(topics)} topics "
          f"match {rows.name}; type hash {humble.hash_rihs01(JS)}")
    if ball:
        assert len(heights) == 1 and 0.005 < heights.pop() < 0.05, heights
        print(f"{bag.name}: {ball_seen} ball messages (PointStamped, Vector3Stamped) match {ball.name}")


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3]) if len(sys.argv) > 3 else None)
