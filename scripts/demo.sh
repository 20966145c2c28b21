#!/usr/bin/env bash
# The main job: set up, build, bake the built-in default fabric and render the demo scene
# (blend/demo_surface.blend) headless to a PNG; prints where it is.
#   bash scripts/demo.sh [--quality Q] [--samples N] [--res W H]
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
quality=preview
extra=()
while (($#)); do
  case $1 in
    --quality) quality=$2; shift ;;
    --samples) extra+=(--samples "$2"); shift ;;
    --res) extra+=(--res "$2" "$3"); shift 2 ;;
    -h|--help) sed -n '2,4p' "$0"; exit 0 ;;
    *) echo "demo.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
  shift
done

LOOM_BUILD_DIR=$here/build bash "$here/scripts/build.sh"
out=$here/out
mkdir -p "$out"
echo "== bake the default fabric ($quality) =="
"$here/build/loom-bake" bake default -o "$out/atlas-default" --quality "$quality"
echo "== render blend/demo_surface.blend =="
bash "$here/scripts/blender.sh" run -b "$here/blend/demo_surface.blend" --python-exit-code 1 \
  --python "$here/blend/render_demo.py" -- --atlas "$out/atlas-default" \
  --out "$out/demo_surface.png" "${extra[@]}"
echo "loom: demo rendered to $out/demo_surface.png"
