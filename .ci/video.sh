#!/usr/bin/env bash
# The `video` feature (video files through FFmpeg): installs FFmpeg's libraries and tools
# (Debian packages), then tests and lints rodtrack-video with the feature on.
# Non-interactive, run as root (CI). About 1.5 minutes on 2 cores with a warm target dir.
set -euo pipefail
cd "$(dirname "$0")/.."
export DEBIAN_FRONTEND=noninteractive
export CARGO_TERM_COLOR=never

echo "== video: system packages"
source .ci/packages.sh
apt_install "${video_pkgs[@]}"

echo "== video: tests"
cargo test --release -p rodtrack-video --features video

echo "== video: clippy"
# Release profile, after the release build above: the FFmpeg bindings' build script (bindgen)
# and the proc macros are reused, only the crates are checked again.
cargo clippy --release -p rodtrack-video --features video --all-targets --no-deps -- -D warnings

echo "== video: decode speed (1440x1080)"
cargo run --release -p rodtrack-video --features video --example decode_speed -- 60
