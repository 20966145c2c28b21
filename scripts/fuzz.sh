#!/usr/bin/env bash
# Fuzz Loom's parsers with libFuzzer (clang, AddressSanitizer + UndefinedBehaviorSanitizer):
# the fabric spec parser (tests/fuzz/fuzz_spec.cpp) and an atlas's manifest with everything read
# from it (tests/fuzz/fuzz_manifest.cpp).
#   bash scripts/fuzz.sh [SECONDS_PER_TARGET]     (default 600; scripts/test.sh runs 45)
# Starts from the corpora in tests/fuzz/corpus (plus the built-in presets and a freshly baked
# manifest) and grows them in out/fuzz/<target>; a crash, a sanitizer report or a broken
# property leaves its input in out/fuzz/<target>-crash-* and fails the script. Keep each finding
# as a test: copy the input into tests/fuzz/corpus/<target>/ (the bounded run replays it).
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
seconds=${1:-600}
build=${LOOM_FUZZ_BUILD_DIR:-$here/build-fuzz}
out=$here/out/fuzz
bash "$here/scripts/setup.sh"
CC=clang CXX=clang++ cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DLOOM_FUZZ=ON -DLOOM_SANITIZE=ON -DLOOM_BUILD_TESTS=OFF >/dev/null
cmake --build "$build" --parallel "${LOOM_JOBS:-2}" --target fuzz_spec fuzz_manifest

export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
mkdir -p "$out/spec" "$out/manifest"
cp "$here"/tests/fuzz/corpus/spec/* "$here"/presets/*.json "$here"/presets/samples/*.json \
  "$out/spec/"
cp "$here"/tests/fuzz/corpus/manifest/* "$out/manifest/"
export LOOM_FUZZ_SEED_OUT=$out/manifest/baked.json

status=0
for target in spec manifest; do
  echo "== fuzz_$target: $seconds s =="
  if ! "$build/fuzz_$target" "$out/$target" -max_total_time="$seconds" -timeout=60 \
      -rss_limit_mb=4096 -print_final_stats=1 -artifact_prefix="$out/$target-" \
      2>"$out/$target.log"; then
    status=1
    echo "fuzz_$target FAILED: see $out/$target.log and $out/$target-*" >&2
    tail -n 40 "$out/$target.log" >&2
  else
    grep -E "^stat::number_of_executed_units|^stat::new_units_added" "$out/$target.log" || true
  fi
done
exit $status
