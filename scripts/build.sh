#!/usr/bin/env bash
# Configures and builds Loom (loom-bake, the library, the tests) in build/ (or $LOOM_BUILD_DIR).
# Extra arguments go to CMake's configure step, e.g. -DLOOM_SANITIZE=ON.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${LOOM_BUILD_DIR:-$here/build}
bash "$here/scripts/setup.sh"
cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=${LOOM_BUILD_TYPE:-RelWithDebInfo} "$@" >/dev/null
# Two parallel jobs: the reference machine has two cores and every job needs ~1 GiB.
cmake --build "$build" --parallel "${LOOM_JOBS:-2}"
echo "loom: built $build/loom-bake"
