#!/usr/bin/env bash
# The ball's events on the camera network against one in-process session, over seeds of the
# `goals` scenario (docs/network.md, "Events"): for each seed, two camera nodes
# (`track --publish zenoh --zenoh-ball`) and a fusion node (`fuse --events-out`) on loopback,
# then `track --events-out` of the same frames with both cameras in one process; prints each
# seed's events and whether the two files are identical.
# Usage: bench/network_events.sh [SEEDS] [FRAMES]   (default "1 2 3 4 5" and 1200)
# RODTRACK: the binary, built with the zenoh feature (default target/release/rodtrack).
set -euo pipefail
seeds=${1:-"1 2 3 4 5"}
frames=${2:-1200}
bin=${RODTRACK:-target/release/rodtrack}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
port=$((17400 + RANDOM % 500))
for seed in $seeds; do
  d="$out/s$seed"
  mkdir -p "$d"
  "$bin" simulate --scenario goals --seed "$seed" --every 100000 --out "$d/rec" >/dev/null 2>&1
  "$bin" calibrate --inputs "$d/rec/cam0.json" --inputs "$d/rec/cam1.json" --out "$d/cal.toml" >/dev/null 2>&1
  port=$((port + 1))
  # Recording-mode sources (every frame delivered, none dropped): no camera is ever lost.
  "$bin" fuse --calib "$d/cal.toml" --subscribe zenoh --out "$d/fused.csv" \
    --events-out "$d/net.jsonl" --zenoh-listen "tcp/127.0.0.1:$port" --loss-frames 100000 \
    >/dev/null 2>"$d/fuse.err" &
  fusion=$!
  sleep 2
  nodes=()
  for c in 0 1; do
    "$bin" track --calib "$d/cal.toml" --camera "cam$c" \
      --input "sim://goals?camera=$c&seed=$seed&frames=$frames" --publish zenoh --zenoh-ball \
      --preview-fps 0 --zenoh-connect "tcp/127.0.0.1:$port" >/dev/null 2>"$d/cam$c.err" &
    nodes+=($!)
  done
  wait "${nodes[@]}"
  sleep 1
  kill -INT "$fusion"
  wait "$fusion"
  "$bin" track --calib "$d/cal.toml" --input "sim://goals?camera=0&seed=$seed&frames=$frames" \
    --input "sim://goals?camera=1&seed=$seed&frames=$frames" --out "$d/ref.csv" \
    --events-out "$d/ref.jsonl" >/dev/null 2>&1
  same=no
  cmp -s "$d/ref.jsonl" "$d/net.jsonl" && same=yes
  echo "seed $seed: $(grep -c '"goal"' "$d/ref.jsonl") goals, $(grep -c '"shot"' "$d/ref.jsonl") shots, $(wc -l <"$d/ref.jsonl") events in process; $(wc -l <"$d/net.jsonl") on the network; identical: $same"
done
