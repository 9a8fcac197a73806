#!/usr/bin/env bash
# The subscriber examples against real nodes on loopback: the Python one
# (python/examples/zenoh_subscriber.py, `eclipse-zenoh` from PyPI in a venv) and the Rust one
# (rodtrack-zenoh's example `fused_subscriber`, through the crate), side by side, against a
# fusion node listening on an explicit tcp/127.0.0.1 endpoint and two camera nodes on
# real-time sim:// sources connecting to it, multicast scouting off. The subscribers run for a
# bounded time; each one's output must hold every rod, finite positions and increasing frame
# ids. The camera nodes track the ball too (--zenoh-ball, the simulator's `ball` scenario). The
# fusion node also publishes for ROS 2 over rmw_zenoh (--ros2-domain 0: joint states, the
# ball's place and velocity), camera node 0 too (--ros2-domain 1: its joint states and its
# ball's place), each topic checked by .ci/ros2_zenoh.py against rmw_zenoh's rules (key
# expression, attachment, liveliness tokens, CDR through rosbags). Uses the release binary built with the feature `zenoh` (RODTRACK_BIN, default
# target/release/rodtrack) and the example built beside it (RODTRACK_EXAMPLE, default
# target/release/examples/fused_subscriber); started by .ci/zenoh.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
target="${CARGO_TARGET_DIR:-$PWD/target}"
bin="${RODTRACK_BIN:-$target/release/rodtrack}"
example="${RODTRACK_EXAMPLE:-$target/release/examples/fused_subscriber}"
venv="$target/ci-zenoh-venv"

source .ci/packages.sh
venv_install "$venv" "${zenoh_venv_pkgs[@]}"

tmp=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$tmp"
}
trap cleanup EXIT

"$bin" simulate --scenario exp3 --frames 20 --out "$tmp/rec" >/dev/null 2>"$tmp/sim.err" \
  || { cat "$tmp/sim.err"; exit 1; }
"$bin" calibrate --inputs "$tmp/rec/cam0.json" --inputs "$tmp/rec/cam1.json" --out "$tmp/c.toml" >/dev/null
port=$("$venv/bin/python" -c "import socket; s=socket.socket(); s.bind(('127.0.0.1', 0)); print(s.getsockname()[1])")
endpoint="tcp/127.0.0.1:$port"

"$bin" fuse --calib "$tmp/c.toml" --subscribe zenoh --publish zenoh --ros2-domain 0 \
    --zenoh-listen "$endpoint" --out "$tmp/fused.csv" 2>"$tmp/fuse.err" &
pids+=($!)
# The cameras' shared trigger: frame 0 a few seconds ahead (each node prerenders its frames
# first); 1200 frames at 200 fps: 6 s of rows.
t0=$(( $(date +%s%3N) + 4000 ))
for cam in 0 1; do
  "$bin" track --calib "$tmp/c.toml" --camera "cam$cam" \
      --input "sim://ball?camera=$cam&frames=20&loop=1&prerender=20&realtime=1&trigger_unix_ms=$t0" \
      --max-frames 1200 --publish zenoh --zenoh-ball --zenoh-connect "$endpoint" $( [ $cam = 0 ] && echo --ros2-domain 1 ) \
      2>"$tmp/cam$cam.err" &
  pids+=($!)
done

logs() { tail -n 5 "$tmp/sub.txt" "$tmp/sub_rs.txt" "$tmp/fuse.err" "$tmp/cam0.err" "$tmp/cam1.err"; }
timeout 30 "$example" "$endpoint" 8 >"$tmp/sub_rs.txt" 2>&1 &
rust_sub=$!
# Each ROS 2 topic: "domain topic node rods [type]" (.ci/ros2_zenoh.py's arguments).
ros2_topics=(
  "0 /rodtrack/default/joint_states rodtrack_fusion_default 8"
  "0 /rodtrack/default/ball rodtrack_fusion_default 0 geometry_msgs/msg/PointStamped"
  "0 /rodtrack/default/ball/velocity rodtrack_fusion_default 0 geometry_msgs/msg/Vector3Stamped"
  "1 /rodtrack/default/cam/cam0/joint_states rodtrack_camera_default_cam0 0"
  "1 /rodtrack/default/cam/cam0/ball rodtrack_camera_default_cam0 0 geometry_msgs/msg/PointStamped"
)
ros2_pids=()
for i in "${!ros2_topics[@]}"; do
  # shellcheck disable=SC2086 # the topic's arguments, split on purpose
  timeout 40 "$venv/bin/python" .ci/ros2_zenoh.py "$endpoint" 8 ${ros2_topics[$i]} >"$tmp/ros2_$i.txt" 2>&1 &
  ros2_pids+=($!)
done
timeout 30 "$venv/bin/python" python/examples/zenoh_subscriber.py "$endpoint" 8 >"$tmp/sub.txt" \
  || { echo "the Python subscriber failed"; logs; exit 1; }
wait "$rust_sub" || { echo "the Rust subscriber failed"; logs; exit 1; }
for i in "${!ros2_topics[@]}"; do
  wait "${ros2_pids[$i]}" || { echo "the ROS 2 (rmw_zenoh) check of ${ros2_topics[$i]} failed"; cat "$tmp/ros2_$i.txt"; logs; exit 1; }
  cat "$tmp/ros2_$i.txt"
done

for who in python:sub.txt rust:sub_rs.txt; do
"$venv/bin/python" - "${who%%:*}" "$tmp/${who#*:}" <<'PY' || { logs; exit 1; }
import math, sys
who = sys.argv[1]
lines = [l.split() for l in open(sys.argv[2]) if l.startswith("frame ")]
rows = [dict(zip(l[0::2], l[1::2])) for l in lines]
assert len(rows) >= 200, f"only {len(rows)} rows received"
rods = sorted({int(r["rod"]) for r in rows})
assert rods == list(range(8)), f"rods {rods}"
assert all(math.isfinite(float(r["position_mm"])) and math.isfinite(float(r["turn_rad"])) for r in rows)
frames = [int(r["frame"]) for r in rows]
assert all(b >= a for a, b in zip(frames, frames[1:])), "frame ids must not decrease"
assert len(set(frames)) >= 50, f"{len(set(frames))} frames"
print(f"{who} subscriber: {len(rows)} fused rows of {len(set(frames))} frames, rods {rods[0]}..{rods[-1]}, positions finite, frame ids increasing")
PY
done
