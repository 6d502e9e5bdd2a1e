#!/usr/bin/env bash
# rtmpm's Python package on the GPU machine.
#
# Here (CPU machine, Rust):   bash scripts/gpu/python.sh build   (after scripts/gpu/prepare.sh,
#   which empties .device/) builds the release wheel into .device/wheels/ (also what the
#   `python` suite of scripts/gpu/run.sh installs) and the release CLI into .device/rtmpm.
# There (GPU machine):        bash scripts/gpu/python.sh          (carry [".device"])
#   installs the wheel into a private folder (no network, no venv needed), then runs
#   1. the whole pytest suite (CPU tests and tests/test_gpu.py: DLPack with PyTorch, the CUDA
#      array interface with CuPy, setters on the GPU), with the CLI for the bit-for-bit tests;
#   2. the examples (PyTorch positions per frame, vibrating bar, 3 frames of the dam break);
#   3. bench/python_gpu.py: run_frame() overhead against `rtmpm run --no-output` on the
#      2M-particle dam break, and reading x of 2M particles against PCIe (PyTorch copies).
# Results and logs land in $OUT (default /tmp/out).
set -uo pipefail
cd "$(dirname "$0")/../.."
if [ "${1:-}" = "build" ]; then
  set -e
  python3 -m venv target/wheel-venv
  target/wheel-venv/bin/pip install --quiet --disable-pip-version-check "maturin>=1.9,<2"
  rm -rf .device/wheels && mkdir -p .device/wheels
  target/wheel-venv/bin/maturin build --release -m crates/rtmpm-py/Cargo.toml -o .device/wheels
  cargo build --release -p rtmpm
  cp target/release/rtmpm .device/rtmpm && strip .device/rtmpm
  ls -la .device/wheels .device/rtmpm
  exit 0
fi
export NCCL_NVLS_ENABLE=0
OUT=${OUT:-/tmp/out}
mkdir -p "$OUT"
PY=${PYTHON:-python3}
SITE=$(mktemp -d)
$PY -m pip install --quiet --no-index --no-deps --target "$SITE" .device/wheels/rtmpm-*.whl || exit 1
export PYTHONPATH="$SITE${PYTHONPATH:+:$PYTHONPATH}"
export RTMPM_CLI=$PWD/.device/rtmpm
$PY -c 'import rtmpm, sys; print("rtmpm", rtmpm.__version__, "python", sys.version.split()[0], rtmpm.cuda_available())' | tee "$OUT/python_env.txt"
rc=0
echo "== pytest"
$PY -m pytest -v -p no:cacheprovider crates/rtmpm-py/tests 2>&1 | tee "$OUT/python_pytest.log" | tail -60
[ "${PIPESTATUS[0]}" -eq 0 ] || rc=1
echo "== examples"
(cd "$OUT" && $PY "$OLDPWD/examples/python/torch_positions.py" --frames 10) 2>&1 | tee "$OUT/example_torch.log" | tail -12 || rc=1
(cd "$OUT" && $PY "$OLDPWD/examples/python/vibrating_bar.py" --backend cuda) 2>&1 | tee "$OUT/example_bar.log" | tail -5 || rc=1
(cd "$OUT" && $PY "$OLDPWD/examples/python/dam_break_energy.py" --frames 3) 2>&1 | tee "$OUT/example_dam.log" | tail -5 || rc=1
echo "== benchmark"
$PY bench/python_gpu.py --cli .device/rtmpm --frames ${FRAMES:-20} --repeat ${REPEAT:-3} --json "$OUT/python_bench.json" 2>&1 | tee "$OUT/python_bench.txt" || rc=1
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$OUT/python_bench.txt" 2>/dev/null
exit $rc
