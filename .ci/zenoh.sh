#!/usr/bin/env bash
# The camera network (feature `zenoh`) and the binary with every optional feature: runs
# rodtrack-zenoh's unit tests and the network test (real `rodtrack` processes on loopback: two
# camera nodes on sim:// sources and a fusion node on explicit tcp/127.0.0.1
# endpoints, multicast scouting off; a camera node killed and restarted), bounded in time; an
# MCAP recording replayed on the network (`replay`); the web console fed from the network
# (`console --subscribe zenoh`: rows, statuses, previews); the ball and its events; lints the binary and rodtrack-zenoh with
# `video`, `genicam` and `zenoh` on (one feature set, built once); a short run of the latency
# benchmark across processes (`bench-zenoh`: its numbers are printed, not checked; it fails on
# rows lost); the Python and the Rust subscriber examples against a fusion node and camera
# nodes (.ci/zenoh_python.sh, eclipse-zenoh in a venv).
# Runs after .ci/video.sh and .ci/genicam.sh (their system packages are installed).
# Non-interactive, run as root (CI).
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TERM_COLOR=never
features=rodtrack/video,rodtrack/genicam,rodtrack/zenoh

echo "== zenoh: unit tests, the three-process network test and the replay (loopback)"
timeout 900 cargo test --release -p rodtrack -p rodtrack-zenoh --features "$features" \
    --lib --test zenoh_network --test zenoh_ball --test zenoh_events --test zenoh_replay \
    --test zenoh_console -- --test-threads=1

# Release profile, after the release build above: zenoh's build scripts and proc macros (and
# FFmpeg's bindings) are reused, only the crates are checked again.
echo "== zenoh: clippy (the binary and rodtrack-zenoh with every feature, -D warnings)"
cargo clippy --release -p rodtrack -p rodtrack-zenoh --features "$features" --all-targets -- -D warnings

echo "== zenoh: the binary with every feature, and the Rust subscriber example"
cargo build --release -p rodtrack -p rodtrack-zenoh --features "$features" \
    --bin rodtrack --example fused_subscriber
bin="${CARGO_TARGET_DIR:-target}/release/rodtrack"
"$bin" fuse --help | head -3

echo "== zenoh: latency across processes (bench-zenoh: 2 camera nodes and a fusion node, 3 s)"
timeout 180 "$bin" bench-zenoh --frames 600

echo "== zenoh: the Python and Rust subscriber examples against real nodes (loopback)"
timeout 300 bash .ci/zenoh_python.sh
