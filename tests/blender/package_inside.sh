#!/usr/bin/env bash
# tests/blender/test_package.sh's part inside the Blender's environment (the chroot, if that is
# the Blender in use): run the unpacked loom-bake, validate, install and use the package.
#   bash tests/blender/package_inside.sh SOURCE_DIR ZIP OUT_DIR
set -euo pipefail
src=$1 zip=$2 out=$3
blender=(bash "$src/scripts/blender.sh" run -b --factory-startup)
export HOME=$out/home  # Blender's user folders (where the extension is installed), not the user's
mkdir -p "$HOME"
unset LOOM_BAKE

python3 - "$zip" "$out/unpacked" <<'PY'
import sys, zipfile
zipfile.ZipFile(sys.argv[1]).extractall(sys.argv[2])
PY
chmod +x "$out/unpacked/bin/loom-bake"  # (zipfile drops Unix permissions, as installers may)
if ldd "$out/unpacked/bin/loom-bake" | grep "not found"; then
  echo "package: the packaged loom-bake misses libraries here" >&2
  exit 1
fi
"$out/unpacked/bin/loom-bake" --version
"$out/unpacked/bin/loom-bake" check plain >/dev/null

"${blender[@]}" --command extension validate "$zip"
"${blender[@]}" --command extension install-file -r user_default -e "$zip"
"${blender[@]}" --python-exit-code 1 --python "$src/tests/blender/test_package.py" -- \
  --out "$out/render"
