"""Checks a ROS 2 bag of `rodtrack track --mcap BAG --mcap-ros2 --out ROWS.csv` with rosbags
(a reader of rosbag2 files independent of rodtrack) against the CSV of the same run.

    python .ci/ros2_bag.py BAG.mcap ROWS.csv

- rosbags opens the file as a rosbag2 MCAP storage file (profile ros2, its indexes, its
  chunks, uncompressed or lz4) and parses every channel's offered_qos_profiles;
- the schema the file carries describes ROS 2's sensor_msgs/msg/JointState: the same RIHS01
  type hash as rosbags' own definition of ROS 2 Humble's;
- every message decodes with the file's schema and with rosbags' own definition alike, and
  rosbags serialises it back to the same bytes;
- every message holds the CSV rows of its camera (or fused) and frame that have a value
  (status ok, predicted, conflict): rod<k>_slide in m and m/s, rod<k>_turn in rad and rad/s.
"""

import csv
import sys
from pathlib import Path

from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

JS = "sensor_msgs/msg/JointState"


def main(bag: Path, rows: Path) -> None:
    want = {}
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
        assert {c.msgtype for c in reader.connections} == {JS}, reader.connections
        for c in reader.connections:
            assert c.ext.serialization_format == "cdr", c
            assert len(c.ext.offered_qos_profiles) == 1, c
        assert reader.typestore.hash_rihs01(JS) == humble.hash_rihs01(JS)
        topics = {c.topic for c in reader.connections}
        for c, t, raw in reader.messages():
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
    print(f"{bag.name}: {seen} JointState messages on {len(topics)} topics "
          f"match {rows.name}; type hash {humble.hash_rihs01(JS)}")


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]))
