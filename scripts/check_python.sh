#!/usr/bin/env bash
# The Python package in CI: build the wheel in a fresh virtual environment (maturin, from PyPI),
# install it, run the pytest suite (crates/rtmpm-py/tests; the GPU tests skip without a GPU) and
# two examples. The wheel is built with the dev profile at opt-level 3 and line tables only, the
# settings of the test profile (Cargo.toml), and with the features `rigid` and `interop`, which
# give rtmpm-rigid, rtmpm-io and rtmpm-cuda the test stage's --all-features: the crates `cargo test` built are
# reused (only the bindings, pyo3 and numpy compile; with the default features those
# crates compiled again too, about a minute on 2 cores), and the wheel runs rigid bodies,
# which the pytest suite then checks.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=target/ci-python
rm -rf "$venv" target/ci-wheels
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet --disable-pip-version-check "maturin>=1.9,<2" "numpy>=1.21" "pytest>=7" "pytest-timeout>=2"
CARGO_PROFILE_DEV_OPT_LEVEL=3 CARGO_PROFILE_DEV_DEBUG=line-tables-only "$venv/bin/maturin" build --profile dev -m crates/rtmpm-py/Cargo.toml --features rigid,interop -o target/ci-wheels
"$venv/bin/pip" install --quiet --disable-pip-version-check --no-deps target/ci-wheels/rtmpm-*.whl
# The command line for the bit-for-bit tests (built by `cargo test --workspace --all-features`).
export RTMPM_CLI=${RTMPM_CLI:-$PWD/target/debug/rtmpm}
[ -x "$RTMPM_CLI" ] || cargo test --quiet --workspace --all-features --no-run
# A test that hangs fails after 300 s with every thread's stack instead of stalling CI.
"$venv/bin/python" -m pytest -q -p no:cacheprovider --timeout 300 crates/rtmpm-py/tests
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$venv/bin/python" examples/python/vibrating_bar.py --out "$tmp/bar.png"
"$venv/bin/python" examples/python/dam_break_energy.py --frames 2 --out "$tmp/energy.png"
"$venv/bin/python" examples/python/floating_box_track.py --frames 2 --out "$tmp/box.csv"
"$venv/bin/python" examples/python/scripted_spoon.py --frames 3 --out "$tmp/spoon.csv"
"$venv/bin/python" examples/python/batch_push.py --worlds 2 --frames 2 --out "$tmp/push.csv"
