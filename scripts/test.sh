#!/usr/bin/env bash
# Sets up, builds and runs every Loom test:
#   - the C++ unit tests (CTest label cpp), built once, with AddressSanitizer +
#     UndefinedBehaviorSanitizer, in build-san/, and a bounded run of each libFuzzer target
#     (label fuzz, $LOOM_FUZZ_SECONDS each, default 20) from build-fuzz/ (scripts/build_san.sh);
#   - the Blender tests (label blender, headless, in the Blender that scripts/blender.sh finds or
#     provisions), the OSL compile check (label osl, skipped with a message when oslc is
#     absent) and the Flamenco job type's check (label farm, Node.js), from the release build in
#     build/, which builds only what they run.
#   bash scripts/test.sh [--full]
# --full adds the long sweeps (LOOM_FULL=1: the C++ tests' full randomised sweeps, the
# Blender parity renders at 64 samples instead of 16, the organza's first two diffraction pairs) and
# fuzzes each target for 600 s.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
case ${1:-} in
  --full) export LOOM_FULL=1 LOOM_FUZZ_SECONDS=${LOOM_FUZZ_SECONDS:-600} ;;
  "") ;;
  *) echo "test.sh: unknown argument \"$1\" (allowed: --full)" >&2; exit 2 ;;
esac
phase() { printf '== %s (%s) ==\n' "$1" "$(date +%T)"; }
t0=$SECONDS

# The Blender the tests use, provisioned (on a machine without it: debootstrap, mostly download
# and unpacking) while the builds compile; the Blender phase waits for it.
phase "Blender for the tests, found or provisioned in the background"
bash "$here/scripts/setup.sh"  # (debootstrap among the Debian packages)
mkdir -p "$here/build"
bash "$here/scripts/blender.sh" info >"$here/build/blender-provision.log" 2>&1 &
provision=$!

phase "build (release: loom-bake and the tools the Blender tests run)"
LOOM_BUILD_DIR=$here/build LOOM_TARGETS="loom-bake loom_tamper_atlas" \
  bash "$here/scripts/build.sh" "-DLOOM_TEST_SETS=blender;osl"
phase "build (ASan + UBSan: the C++ tests)"
bash "$here/scripts/build_san.sh" cpp
phase "build (clang, ASan + UBSan, libFuzzer: the fuzzers)"
bash "$here/scripts/build_san.sh" fuzz

# The ray-wave atlases the C++ tests only read are baked by the release loom-bake, a fifth of the
# time (tests/cpp/test_util.h: Baker); the tests that bake still do so under the sanitizers.
export LOOM_TEST_FIXTURE_BAKE=$here/build/loom-bake
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
status=0
phase "C++ tests under ASan + UBSan"
# Three at a time on two cores: the tests also wait (on a shared atlas another test is baking,
# on loom-bake processes and files), and a third fills those waits (the whole label: 607 s
# against 677 s two at a time, one run each on 2026-12-07).
ctest --test-dir "$here/build-san" -L cpp --output-on-failure -j 3 || status=1
phase "bounded fuzzing (libFuzzer, ASan + UBSan)"
ctest --test-dir "$here/build-fuzz" -L fuzz --output-on-failure -j 2 || status=1
wait "$provision" ||
  echo "scripts/blender.sh info failed (build/blender-provision.log); blender.provision says why"
phase "Blender, OSL and farm tests"
ctest --test-dir "$here/build" -L 'blender|osl|farm' --output-on-failure -j 2 || status=1
phase "done in $((SECONDS - t0)) s"
exit $status
