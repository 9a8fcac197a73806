#!/usr/bin/env bash
# Fetches and installs, one after the other, everything the later steps of .ci/run take from
# outside the repository (Debian packages, Python venvs: .ci/packages.sh). .ci/run starts it in
# the background while the workspace builds and waits for it before the first step that needs
# it; the steps then find their packages installed (and still install them if this failed).
set -uo pipefail
cd "$(dirname "$0")/.."
source .ci/packages.sh
target="${CARGO_TARGET_DIR:-$PWD/target}"
mkdir -p "$target"
status=0
run() { echo "-- prefetch: $*"; "$@" || { echo "-- prefetch failed: $*"; status=1; }; }
run apt_install "${marker_pkgs[@]}" "${video_pkgs[@]}" "${genicam_pkgs[@]}"
run chromium_install
run venv_install "$target/ci-python-venv" "${python_venv_pkgs[@]}"
run venv_install "$target/ci-zenoh-venv" "${zenoh_venv_pkgs[@]}"
exit $status
