#!/usr/bin/env bash
# Fuzz Loom's parsers with libFuzzer (clang, AddressSanitizer + UndefinedBehaviorSanitizer):
# the fabric spec parser (tests/fuzz/fuzz_spec.cpp), an atlas's manifest with everything read
# from it (tests/fuzz/fuzz_manifest.cpp), loom-bake's command-line values
# (tests/fuzz/fuzz_cli_values.cpp), an atlas's texture files read through OpenImageIO
# (tests/fuzz/fuzz_texture.cpp) and WIF weaving drafts (tests/fuzz/fuzz_wif.cpp).
#   bash scripts/fuzz.sh [SECONDS_PER_TARGET [TARGET...]]
#     SECONDS_PER_TARGET: default 600 (scripts/test.sh runs each for 30 s as the CTest tests
#       fuzz.TARGET, and scripts/test.sh --full for 600 s)
#     TARGET: spec, manifest, cli_values, texture (default: all four)
# Builds the fuzzers in the fuzz build that scripts/test.sh uses (build-fuzz/, or
# $LOOM_FUZZ_BUILD_DIR) and runs each with tests/fuzz/run_fuzzer.sh: starting from the corpora in
# tests/fuzz/corpus (plus the built-in presets, a freshly baked manifest and textures freshly
# written by the baker's writer), growing them in out/fuzz/<target>; a crash, a sanitizer report
# or a broken property leaves its input in out/fuzz/<target>-crash-* and fails the script. Keep
# each finding as a test: copy the input into tests/fuzz/corpus/<target>/.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
seconds=${1:-600}
shift || true
all_targets=(spec manifest cli_values texture wif)  # as in CMakeLists.txt's LOOM_FUZZ block
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
bash "$here/scripts/build_san.sh" fuzz "${targets[@]}"

status=0
for target in "${targets[@]}"; do
  bash "$here/tests/fuzz/run_fuzzer.sh" "$build/fuzz_$target" "$target" "$here/out/fuzz" \
    "$seconds" || status=1
done
exit $status
