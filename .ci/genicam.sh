#!/usr/bin/env bash
# The `genicam` feature (GenICam cameras through Aravis): installs Aravis' libraries and its
# fake GigE Vision camera (Debian packages), then tests and lints rodtrack-genicam with the
# feature on. The tests start and kill `arv-fake-gv-camera-0.8` on 127.0.0.1 and 127.0.0.2
# (added to `lo` by the pair test: needs root and iproute2). RODTRACK_REQUIRE_GENICAM makes a
# missing fake camera a failure instead of a skip.
# Non-interactive, run as root (CI). About 2 minutes on 2 cores with a warm target dir.
set -euo pipefail
cd "$(dirname "$0")/.."
export DEBIAN_FRONTEND=noninteractive
export CARGO_TERM_COLOR=never
export RODTRACK_REQUIRE_GENICAM=1

echo "== genicam: system packages"
source .ci/packages.sh
apt_install "${genicam_pkgs[@]}"

echo "== genicam: tests (fake GigE cameras on loopback)"
# One test at a time: the fake cameras listen on fixed addresses. Bounded: each test has its
# own deadlines; `timeout` is the last resort.
timeout 600 cargo test --release -p rodtrack-genicam --features genicam -- --test-threads=1 --nocapture

echo "== genicam: clippy"
# Release profile, after the release build above (build scripts and proc macros reused).
cargo clippy --release -p rodtrack-genicam --features genicam --all-targets --no-deps -- -D warnings
