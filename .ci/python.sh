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
venv="$target/ci-python-venv"
rm -rf "$venv"
python3 -m venv "$venv"
"$venv/bin/pip" install -q --disable-pip-version-check maturin pytest numpy
# PyO3 builds for the venv's interpreter; maturin and pip are the venv's.
export PATH="$venv/bin:$PATH"
export PYO3_PYTHON="$venv/bin/python"

step "clippy (rodtrack-py with the feature python, all targets, -D warnings)"
cargo clippy -p rodtrack-py --features python --all-targets -- -D warnings

step "the abi3 wheel (release, target/wheels)"
rm -rf "$target/wheels"
maturin build --release --manifest-path python/Cargo.toml --out "$target/wheels"
wheel=$(ls "$target"/wheels/rodtrack-*-abi3-*.whl)
echo "$wheel"

step "pip install ./python (from source)"
pip install -q --disable-pip-version-check ./python
python -c "import rodtrack; print('rodtrack', rodtrack.__version__, 'from', rodtrack.__file__)"

step "pip install the abi3 wheel"
pip install -q --disable-pip-version-check --force-reinstall --no-deps "$wheel"

step "pytest python/tests (the rodtrack binary of target/release for the CSV comparisons)"
RODTRACK_BIN="$target/release/rodtrack" python -m pytest -q -rs python/tests

step "examples"
python python/examples/control_loop.py 1 | tail -3
python python/examples/gym_observation.py | tail -3

step "done"
