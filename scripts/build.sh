#!/usr/bin/env bash
# Configures and builds Loom (loom-bake, the library, the tests) in build/ (or $LOOM_BUILD_DIR).
# Extra arguments go to CMake's configure step, e.g. -DLOOM_SANITIZE=ON; $LOOM_TARGETS (a space
# separated list) builds only those targets. Compiles through ccache when it is installed
# (scripts/setup.sh installs it), with its cache in ${LOOM_CACHE:-~/.cache/loom}/ccache outside
# the clone and paths taken relative to the clone, so that a fresh clone (CI's) reuses the
# objects of earlier builds on the same machine.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${LOOM_BUILD_DIR:-$here/build}
bash "$here/scripts/setup.sh"
launcher=()
if command -v ccache >/dev/null; then
  export CCACHE_DIR=${CCACHE_DIR:-${LOOM_CACHE:-$HOME/.cache/loom}/ccache}
  export CCACHE_BASEDIR=$here CCACHE_NOHASHDIR=true
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=${LOOM_BUILD_TYPE:-RelWithDebInfo} \
  "${launcher[@]}" "$@" >/dev/null
targets=()
for t in ${LOOM_TARGETS:-}; do targets+=(--target "$t"); done
# Two parallel jobs: the reference machine has two cores and every job needs ~1 GiB.
cmake --build "$build" --parallel "${LOOM_JOBS:-2}" "${targets[@]}"
echo "loom: built $build${LOOM_TARGETS:+ ($LOOM_TARGETS)}"
