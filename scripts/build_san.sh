#!/usr/bin/env bash
# The sanitizer builds (AddressSanitizer + UndefinedBehaviorSanitizer, -O2 -g1) that
# scripts/test.sh runs its C++ tests and fuzzers from:
#   bash scripts/build_san.sh cpp    build-san/: g++, the C++ unit tests (CTest label cpp) and
#                                    the loom-bake they run
#   bash scripts/build_san.sh fuzz [TARGET...]
#                                    build-fuzz/: clang (libFuzzer), the fuzz targets (CTest
#                                    label fuzz: tests/fuzz/run_fuzzer.sh), default all five
# $LOOM_SAN_BUILD_DIR / $LOOM_FUZZ_BUILD_DIR choose other directories.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
what=${1:-}
shift || true
case $what in
  cpp)
    LOOM_BUILD_DIR=${LOOM_SAN_BUILD_DIR:-$here/build-san} LOOM_TARGETS="loom-bake loom_tests" \
      bash "$here/scripts/build.sh" -DLOOM_SANITIZE=ON "-DLOOM_TEST_SETS=cpp" \
      -DLOOM_BUILD_BENCH=OFF ;;
  fuzz)
    targets=("$@")
    ((${#targets[@]})) || targets=(spec manifest cli_values texture wif)
    CC=clang CXX=clang++ LOOM_BUILD_DIR=${LOOM_FUZZ_BUILD_DIR:-$here/build-fuzz} \
      LOOM_TARGETS="${targets[*]/#/fuzz_}" bash "$here/scripts/build.sh" -DLOOM_SANITIZE=ON \
      -DLOOM_FUZZ=ON "-DLOOM_TEST_SETS=fuzz" -DLOOM_BUILD_BENCH=OFF ;;
  *) echo "build_san.sh: say cpp or fuzz, not \"$what\"" >&2; exit 2 ;;
esac
