#!/usr/bin/env bash
# The Python package (python/, docs/python.md): its Rust code linted with the feature
# `python` on, the abi3 wheel built into the repository's target dir (release profile), the
# package installed from source (`pip install ./python`) and from the wheel, and its tests.
# Runs after the workspace is built (`.ci/run`): the rodtrack crates and the `rodtrack` binary
# the tests compare against are already in target/.
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TERM_COLOR=never
start=$(date +%s)
step() { echo; echo "-- python: $* ($(( $(date +%s) - start )) s)"; }

# The repository's target dir (the workspace's), or CARGO_TARGET_DIR's when set.
target="${CARGO_TARGET_DIR:-$PWD/target}"

step "venv with maturin, pytest, numpy"
source .ci/packages.sh
venv="$target/ci-python-venv"
# rosbags: an independent reader of ROS 2 bags (the ROS 2 bag check below).
venv_install "$venv" "${python_venv_pkgs[@]}"
# PyO3 builds for the venv's interpreter; maturin and pip are the venv's.
export PATH="$venv/bin:$PATH"
export PYO3_PYTHON="$venv/bin/python"

step "the abi3 wheel (release, target/wheels)"
rm -rf "$target/wheels"
maturin build --release --manifest-path python/Cargo.toml --out "$target/wheels"
wheel=$(ls "$target"/wheels/rodtrack-*-abi3-*.whl)
echo "$wheel"

# Release profile, after the wheel's release build (build scripts and proc macros reused).
step "clippy (rodtrack-py with the feature python, all targets, -D warnings)"
cargo clippy --release -p rodtrack-py --features python --all-targets -- -D warnings

step "pip install ./python (from source)"
pip install -q --disable-pip-version-check ./python
python -c "import rodtrack; print('rodtrack', rodtrack.__version__, 'from', rodtrack.__file__)"

step "pip install the abi3 wheel"
pip install -q --disable-pip-version-check --force-reinstall --no-deps "$wheel"

step "pytest python/tests (the rodtrack binary of target/release for the CSV comparisons)"
RODTRACK_BIN="$target/release/rodtrack" python -m pytest -q -rs python/tests

step "ROS 2 bags of track --mcap-ros2 (plain and lz4 chunks, rods and ball) read by rosbags, checked against the CSVs"
bag="$target/ci-ros2-bag"
rm -rf "$bag"
cli="$target/release/rodtrack"
"$cli" simulate --scenario ball --frames 40 --out "$bag/rec" >/dev/null
"$cli" calibrate --inputs "$bag/rec/cam0.json" --inputs "$bag/rec/cam1.json" \
  --out "$bag/calib.toml" >/dev/null
for c in none lz4; do
  "$cli" track --calib "$bag/calib.toml" --input "$bag/rec/cam0" --input "$bag/rec/cam1" \
    --table t1 --out "$bag/rows-$c.csv" --ball-out "$bag/ball-$c.csv" --mcap "$bag/joints-$c.mcap" \
    --mcap-ros2 --mcap-compression "$c" >/dev/null
  python .ci/ros2_bag.py "$bag/joints-$c.mcap" "$bag/rows-$c.csv" "$bag/ball-$c.csv"
done

step "examples"
python python/examples/control_loop.py 1 | tail -3
python python/examples/gym_observation.py | tail -3

step "done"
