#!/usr/bin/env bash
# Coverage-guided fuzzing of rtmpm's readers with libFuzzer, on stable Rust.
#
#   scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]     (default: 15 s each; targets: scene ply vtu checkpoint bgeo resume)
#
# FUZZ_JOBS=N runs N targets at once (default: one per core; each target fuzzes on one core).
#
# cargo-fuzz needs nightly only for its sanitizers (-Zsanitizer); the coverage instrumentation
# that guides libFuzzer is stable rustc (-Cpasses=sancov-module and LLVM's sanitizer-coverage
# options, the flags cargo-fuzz itself passes). So the targets in fuzz/ are ordinary
# libfuzzer-sys targets (`cargo fuzz run scene` works on nightly too) built here with those flags;
# debug assertions and overflow checks are on, and libFuzzer's -malloc_limit_mb turns any huge
# allocation into a failure, -timeout any hang. A failure prints the input and exits 1: add the
# input as a regression test (see crates/rtmpm-scene/tests/fuzz_regressions.rs).
set -euo pipefail
cd "$(dirname "$0")/.."
secs="${1:-15}"
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(scene ply vtu checkpoint bgeo resume)

host="$(rustc -vV | sed -n 's/^host: //p')"
export CARGO_TARGET_DIR="$PWD/target/fuzz"
# --target keeps these flags off build scripts (they cannot link the coverage callbacks).
RUSTFLAGS="-Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares --cfg fuzzing -Cdebug-assertions -Coverflow-checks" \
  cargo build --quiet --release --manifest-path fuzz/Cargo.toml --target "$host" --bins

# libFuzzer uses one core, so the targets run side by side, as many at once as there are cores
# (FUZZ_JOBS to change it): each still fuzzes for SECONDS on a core of its own, and on 2 cores
# the 4 targets take 2 x SECONDS instead of 4 x SECONDS. The reports follow in target order.
fuzz_one() {
  local t=$1 corpus="target/fuzz-corpus/$1" artifacts="target/fuzz-artifacts/$1" dict=() rc=0
  mkdir -p "$corpus" "$artifacts"
  [ -f "fuzz/dicts/$t.dict" ] && dict=(-dict="fuzz/dicts/$t.dict")
  "$CARGO_TARGET_DIR/$host/release/$t" "$corpus" "fuzz/seeds/$t" "${dict[@]}" \
    -max_total_time="$secs" -timeout=10 -rss_limit_mb=3072 -malloc_limit_mb=1024 \
    -max_len=65536 -print_final_stats=1 -artifact_prefix="$artifacts/" \
    >"target/fuzz-$t.log" 2>&1 || rc=$?
  echo "$rc" >"target/fuzz-$t.rc"
}
jobs_max="${FUZZ_JOBS:-$(nproc)}"
for t in "${targets[@]}"; do
  rm -f "target/fuzz-$t.rc"
  while [ "$(jobs -rp | wc -l)" -ge "$jobs_max" ]; do wait -n || true; done
  fuzz_one "$t" &
done
wait

status=0
for t in "${targets[@]}"; do
  echo "== fuzz $t (${secs}s)"
  if [ "$(cat "target/fuzz-$t.rc" 2>/dev/null || echo 1)" != 0 ]; then
    status=1
    tail -n 40 "target/fuzz-$t.log"
    echo "fuzz target $t FAILED: the input is in target/fuzz-artifacts/$t/"
  else
    grep -E "stat::number_of_executed_units|stat::new_units_added" "target/fuzz-$t.log" \
      | tr '\n' ' ' || true
    echo
  fi
done
exit "$status"
