#!/usr/bin/env bash
# The web console (rodtrack-console): installs Debian's chromium, then runs the console's tests
# with the browser required (headless chromium driven over the DevTools protocol: the page
# loads, shows frames, the plots advance, clicks become calibration points, the demo's
# calibration equals the CLI's), then measures the console's cost to the tracking (the
# `overhead` bench: share of the tracking time, target < 2 %; printed, not enforced, since this
# machine is shared: add `--max-percent 2` to enforce it).
# Non-interactive, run as root (CI). Release profile, as the test step before it: the console's
# tests and bench reuse what that step built (a debug build would compile the whole tree again).
# The console is linted by the workspace's clippy step.
set -euo pipefail
cd "$(dirname "$0")/.."
export DEBIAN_FRONTEND=noninteractive
export CARGO_TERM_COLOR=never

echo "== console: chromium"
source .ci/packages.sh
chromium_install

echo "== console: tests (browser required)"
RODTRACK_REQUIRE_BROWSER=1 cargo test --release -p rodtrack-console -- --test-threads 1

echo "== console: overhead (bench)"
cargo bench -p rodtrack-console --bench overhead -- --runs 3
