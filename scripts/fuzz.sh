#!/usr/bin/env bash
# Coverage-guided fuzzing of rtmpm's readers with libFuzzer, on stable Rust.
#
#   scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]     (default: 15 s each; targets: scene ply vtu checkpoint)
#
# cargo-fuzz needs nightly only for its sanitizers (-Zsanitizer); the coverage instrumentation
# that guides libFuzzer is stable rustc (-Cpasses=sancov-module and LLVM's sanitizer-coverage
# options, the flags cargo-fuzz itself passes). So the targets in fuzz/ are ordinary
# libfuzzer-sys targets (`cargo fuzz run scene` works on nightly too) built here with those flags;
# debug assertions and overflow checks are on, and libFuzzer's -malloc_limit_mb turns any huge
# allocation into a failure, -timeout any hang. A failure prints the input and exits 1: add the
# input as a regression test (see crates/rtmpm-core/tests/fuzz_regressions.rs).
set -euo pipefail
cd "$(dirname "$0")/.."
secs="${1:-15}"
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(scene ply vtu checkpoint)

host="$(rustc -vV | sed -n 's/^host: //p')"
export CARGO_TARGET_DIR="$PWD/target/fuzz"
# --target keeps these flags off build scripts (they cannot link the coverage callbacks).
RUSTFLAGS="-Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares --cfg fuzzing -Cdebug-assertions -Coverflow-checks" \
  cargo build --quiet --release --manifest-path fuzz/Cargo.toml --target "$host" --bins

status=0
for t in "${targets[@]}"; do
  corpus="target/fuzz-corpus/$t"
  artifacts="target/fuzz-artifacts/$t"
  mkdir -p "$corpus" "$artifacts"
  dict=()
  [ -f "fuzz/dicts/$t.dict" ] && dict=(-dict="fuzz/dicts/$t.dict")
  echo "== fuzz $t (${secs}s)"
  if ! "$CARGO_TARGET_DIR/$host/release/$t" "$corpus" "fuzz/seeds/$t" "${dict[@]}" \
      -max_total_time="$secs" -timeout=10 -rss_limit_mb=3072 -malloc_limit_mb=1024 \
      -max_len=65536 -print_final_stats=1 -artifact_prefix="$artifacts/" \
      >"target/fuzz-$t.log" 2>&1; then
    status=1
    tail -n 40 "target/fuzz-$t.log"
    echo "fuzz target $t FAILED: the input is in $artifacts/"
  else
    grep -E "stat::number_of_executed_units|stat::new_units_added" "target/fuzz-$t.log" \
      | tr '\n' ' ' || true
    echo
  fi
done
exit "$status"
