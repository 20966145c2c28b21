#!/usr/bin/env bash
# Fuzz Loom's parsers with libFuzzer (clang, AddressSanitizer + UndefinedBehaviorSanitizer):
# the fabric spec parser (tests/fuzz/fuzz_spec.cpp), an atlas's manifest with everything read
# from it (tests/fuzz/fuzz_manifest.cpp), loom-bake's command-line values
# (tests/fuzz/fuzz_cli_values.cpp) and an atlas's texture files read through OpenImageIO
# (tests/fuzz/fuzz_texture.cpp).
#   bash scripts/fuzz.sh [SECONDS_PER_TARGET [TARGET...]]
#     SECONDS_PER_TARGET: default 600; scripts/test.sh runs 45 (4 targets: 3 minutes in all)
#     TARGET: spec, manifest, cli_values, texture (default: all four)
# Starts from the corpora in tests/fuzz/corpus (plus the built-in presets, a freshly baked
# manifest and textures freshly written by the baker's writer) and grows them in
# out/fuzz/<target>; a crash, a sanitizer report or a broken property leaves its input in
# out/fuzz/<target>-crash-* and fails the script. Keep each finding as a test: copy the input
# into tests/fuzz/corpus/<target>/ (the bounded run replays it, and so do the unit tests for the
# manifest and texture corpora: tests/cpp/test_fuzz_corpus.cpp).
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
seconds=${1:-600}
shift || true
all_targets=(spec manifest cli_values texture)  # as in CMakeLists.txt's LOOM_FUZZ block
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=("${all_targets[@]}")
for t in "${targets[@]}"; do
  case " ${all_targets[*]} " in *" $t "*) ;; *)
    echo "fuzz.sh: unknown target \"$t\" (allowed: ${all_targets[*]})" >&2; exit 2 ;;
  esac
done
case $seconds in ''|*[!0-9]*|0)
  echo "fuzz.sh: SECONDS_PER_TARGET must be a whole number of seconds >= 1, not \"$seconds\"" >&2
  exit 2 ;;
esac
build=${LOOM_FUZZ_BUILD_DIR:-$here/build-fuzz}
out=$here/out/fuzz
bash "$here/scripts/setup.sh"
CC=clang CXX=clang++ cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DLOOM_FUZZ=ON -DLOOM_SANITIZE=ON -DLOOM_BUILD_TESTS=OFF >/dev/null
cmake --build "$build" --parallel "${LOOM_JOBS:-2}" --target "${targets[@]/#/fuzz_}"

export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
for t in "${all_targets[@]}"; do mkdir -p "$out/$t"; done
cp "$here"/tests/fuzz/corpus/spec/* "$here"/presets/*.json "$here"/presets/samples/*.json \
  "$out/spec/"
cp "$here"/tests/fuzz/corpus/manifest/* "$out/manifest/"
cp "$here"/tests/fuzz/corpus/cli_values/* "$out/cli_values/"
cp "$here"/tests/fuzz/corpus/texture/* "$out/texture/"
export LOOM_FUZZ_SEED_OUT=$out/manifest/baked.json
export LOOM_FUZZ_SEED_DIR=$out/texture

status=0
for target in "${targets[@]}"; do
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
