#!/usr/bin/env bash
# Sets up, builds and runs every Loom test: the C++ unit tests (also under AddressSanitizer and
# UndefinedBehaviorSanitizer), a bounded fuzzing run of the parsers (scripts/fuzz.sh, 45 s for
# each of its four targets), the Blender tests (headless, in the Blender that scripts/blender.sh
# finds or provisions) and the OSL compile check (skipped with a message when oslc is absent).
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

echo "== build (release) =="
LOOM_BUILD_DIR=$here/build bash "$here/scripts/build.sh"
echo "== build (ASan + UBSan) =="
LOOM_BUILD_DIR=$here/build-asan LOOM_BUILD_TYPE=Debug bash "$here/scripts/build.sh" -DLOOM_SANITIZE=ON

export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
echo "== C++ tests under ASan + UBSan =="
ctest --test-dir "$here/build-asan" -L cpp --output-on-failure -j 2

echo "== fuzzing, bounded (libFuzzer, ASan + UBSan) =="
bash "$here/scripts/fuzz.sh" "${LOOM_FUZZ_SECONDS:-45}"

echo "== all tests (C++, Blender, OSL) =="
ctest --test-dir "$here/build" --output-on-failure -j 2
