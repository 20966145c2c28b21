#!/usr/bin/env bash
# The self-contained extension package (scripts/package.sh, issue 34), checked in the Blender
# the tests use: with scripts/blender.sh's Debian trixie chroot, a Linux other than the one that
# built it, with none of the build machine's libraries. The package's loom-bake runs from the
# unpacked zip; Blender validates the zip, installs it with its own extension installer, and the
# installed add-on finds its own loom-bake (no $LOOM_BAKE, no preference, none on PATH), bakes
# and renders (tests/blender/test_package.py).
#   bash tests/blender/test_package.sh SOURCE_DIR BUILD_DIR OUT_DIR
set -euo pipefail
src=$1 build=$2 out=$3
rm -rf "$out"
mkdir -p "$out"
zip=$out/loom-linux-x64.zip
LOOM_BUILD_DIR=$build bash "$src/scripts/package.sh" -o "$zip"
env -u LOOM_BAKE bash "$src/scripts/blender.sh" exec bash "$src/tests/blender/package_inside.sh" \
  "$src" "$zip" "$out"
