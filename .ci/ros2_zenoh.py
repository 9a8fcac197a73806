"""Checks what `rodtrack fuse --publish zenoh --ros2-domain D` (or a camera node, `track
--publish zenoh --ros2-domain D`) publishes for ROS 2 over rmw_zenoh, as an rmw_zenoh subscriber and ROS 2's graph would read it, with parsers that are
not rodtrack's:
- the data's key expression is the one rmw_zenoh's subscription declares for the topic
  (`/rodtrack/<table>/joint_states`, a camera node's `/rodtrack/<table>/cam/<camera>/joint_states`) of type `sensor_msgs/msg/JointState` (`<domain>/<topic
  without its slashes>/<DDS type>/<type hash>`), the type hash computed by rosbags from ROS 2's
  own definition; the samples are received through zenoh-ext's advanced subscriber, as
  rmw_zenoh's subscriptions receive them;
- every sample carries rmw_zenoh's attachment, read with zenoh-ext's deserializer as
  rmw_zenoh's `AttachmentData` reads it (int64 sequence number, int64 source timestamp, a
  sequence of exactly 16 bytes, nothing after): sequence numbers go up by one, timestamps are
  recent, the GID is the XXH3-128 hash of the publisher's liveliness token (Python's xxhash);
- the liveliness tokens parse as rmw_zenoh's graph cache parses them (`Entity::make` from a key
  expression): a node token (`NN`) and a publisher token (`MP`) of the same session and node,
  the topic, type, hash and QoS (every policy at rmw_zenoh's default) as above;
- every payload decodes with rosbags' CDR reader as the topic's type and rosbags serialises it
  back to the same bytes; a joint state has two joints per rod, finite values; the ball's
  place (geometry_msgs/msg/PointStamped) and velocity (geometry_msgs/msg/Vector3Stamped) are
  finite, in the table frame (`rodtrack/<table>`), the place on the table at the ball's
  height.
Usage: python ros2_zenoh.py ENDPOINT SECONDS DOMAIN TOPIC NODE RODS [TYPE] (RODS: the rods every
run must show, 0..RODS-1; 0: at least one; TYPE: the topic's ROS 2 type, default
sensor_msgs/msg/JointState)"""
import json
import math
import sys
import threading
import time

import xxhash
import zenoh
from rosbags.typesys import Stores, get_typestore
from zenoh.ext import Int64, UInt8, declare_advanced_subscriber, z_deserialize

endpoint, seconds, domain, topic, node, n_rods = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), sys.argv[4], sys.argv[5], int(sys.argv[6])
JS = "sensor_msgs/msg/JointState"
ros_type = sys.argv[7] if len(sys.argv) > 7 else JS
humble, jazzy = get_typestore(Stores.ROS2_HUMBLE), get_typestore(Stores.ROS2_JAZZY)
type_hash = humble.hash_rihs01(ros_type)
assert type_hash == jazzy.hash_rihs01(ros_type), f"Humble's and Jazzy's {ros_type} differ"
package, _, type_name = ros_type.split("/")
dds_type = f"{package}::msg::dds_::{type_name}_"
key = f"{domain}/{topic.strip('/')}/{dds_type}/{type_hash}"

samples, lock = [], threading.Lock()


def on_sample(s):
    a = s.attachment
    with lock:
        samples.append((str(s.key_expr), s.payload.to_bytes(), None if a is None else a.to_bytes(), time.time_ns()))


conf = zenoh.Config()
conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
conf.insert_json5("scouting/multicast/enabled", "false")
with zenoh.open(conf) as session:
    sub = declare_advanced_subscriber(session, key, on_sample)
    time.sleep(seconds)
    tokens = [str(r.ok.key_expr) for r in session.liveliness().get(f"@ros2_lv/{domain}/**", timeout=5.0) if r.ok]
    sub.undeclare()

# The liveliness tokens, split as rmw_zenoh's Entity::make splits them.
QOS_DEFAULTS = ["", "", ",", ",", ",", ",,"]  # reliability, durability, history, deadline, lifespan, liveliness
nodes, pubs = {}, []
for t in tokens:
    p = t.split("/")
    assert p[0] == "@ros2_lv" and p[1] == str(domain), t
    kind = p[5]
    if kind == "NN":
        assert len(p) == 9, f"a node token has 9 parts: {t}"
        nodes[(p[2], p[3])] = p[8].replace("%", "/")
    elif kind == "MP":
        assert len(p) == 13, f"a publisher token has 13 parts: {t}"
        qos = p[12].split(":")
        assert len(qos) == 6 and qos == QOS_DEFAULTS, f"QoS {p[12]}: rmw_zenoh's defaults expected"
        if p[9].replace("%", "/") == topic:
            pubs.append((t, p))
assert len(pubs) == 1, f"one publisher token of {topic} expected, got {tokens}"
pub_token, p = pubs[0]
assert (p[2], p[3]) in nodes, f"no node token of session {p[2]}, node {p[3]}: {tokens}"
assert nodes[(p[2], p[3])] == node and p[8] == node, f"node {node} expected: {pub_token}"
assert p[6] == "%" and p[7] == "%", "enclave and namespace '/'"
assert p[9].replace("%", "/") == topic and p[10] == dds_type and p[11] == type_hash, pub_token
gid = xxhash.xxh3_128_intdigest(pub_token.encode()).to_bytes(16, "little")

assert len(samples) >= 100, f"only {len(samples)} samples on {key}"
seqs, names = [], set()
for k, payload, att, recv_ns in samples:
    assert k == key, k
    assert att is not None, "a sample without rmw_zenoh's attachment"
    seq, stamp_ns, sample_gid = z_deserialize(tuple[Int64, Int64, list[UInt8]], zenoh.ZBytes(att))
    assert bytes(sample_gid) == gid, "the attachment's GID is not the publisher token's hash"
    assert abs(recv_ns - stamp_ns) < 5e9, f"source timestamp {stamp_ns} vs received {recv_ns}"
    seqs.append(seq)
    msg = humble.deserialize_cdr(payload, ros_type)
    assert humble.serialize_cdr(msg, ros_type) == payload, "rosbags serialises the message differently"
    if ros_type != JS:
        table = topic.split("/")[2]
        assert msg.header.frame_id == f"rodtrack/{table}", msg.header.frame_id
        v = msg.point if hasattr(msg, "point") else msg.vector
        assert all(math.isfinite(c) for c in (v.x, v.y, v.z)), v
        if hasattr(msg, "point"):
            assert abs(v.x) < 1.0 and abs(v.y) < 0.5 and 0.005 < v.z < 0.05, f"ball at {v} m"
        else:
            assert abs(v.x) < 20.0 and abs(v.y) < 20.0 and v.z == 0.0, f"ball velocity {v} m/s"
        continue
    assert len(msg.name) == len(msg.position) == len(msg.velocity) and len(msg.effort) == 0
    assert all(math.isfinite(v) for v in list(msg.position) + list(msg.velocity))
    for i in range(0, len(msg.name), 2):
        rod = msg.name[i].removesuffix("_slide").removeprefix("rod")
        assert msg.name[i] == f"rod{rod}_slide" and msg.name[i + 1] == f"rod{rod}_turn", msg.name
        assert abs(msg.position[i]) < 1.0, f"rod {rod}: slide {msg.position[i]} m"
        names.add(int(rod))
assert seqs == list(range(seqs[0], seqs[0] + len(seqs))), "sequence numbers must go up by one"
if ros_type == JS:
    assert names == set(range(n_rods)) if n_rods else names, f"rods {sorted(names)}"
what = f"rods {min(names)}..{max(names)}" if ros_type == JS else "values finite, in the table frame"
print(f"ROS 2 over rmw_zenoh: {len(samples)} {type_name} samples on {key}, sequence {seqs[0]}..{seqs[-1]}, "
      f"attachments and GID as rmw_zenoh's, node '{nodes[(p[2], p[3])]}' and publisher tokens, {what}")
