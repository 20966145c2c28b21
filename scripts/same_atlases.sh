#!/usr/bin/env bash
# Does a change of the baker leave every atlas as it was? Builds loom-bake at REV (default HEAD,
# the last commit) in a git worktree and the working tree's loom-bake, bakes the 11 presets (the
# four weaves and the seven sample fabrics) at QUALITY (default draft) with both, and compares
# each pair with scripts/compare_atlases.py (every texture byte for byte or texel for texel, the
# manifests but for the bake keys and timings), and a colour-only change of the organza likewise.
# For restructurings that must not change any result.
#   bash scripts/same_atlases.sh [REV] [QUALITY]
# Exit 0 when all 12 are the same, 1 when one differs (its differences printed).
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
rev=${1:-HEAD}
quality=${2:-draft}
case $quality in draft|preview|final|reference) ;;
  *) echo "same_atlases.sh: QUALITY must be draft, preview, final or reference, not \"$quality\"" >&2
     exit 2 ;;
esac
git -C "$here" rev-parse --verify --quiet "$rev^{commit}" >/dev/null ||
  { echo "same_atlases.sh: REV \"$rev\" is not a commit of $here" >&2; exit 2; }
work=$(mktemp -d)
cleanup() { git -C "$here" worktree remove --force "$work/ref" 2>/dev/null || true; rm -rf "$work"; }
trap cleanup EXIT

git -C "$here" worktree add --detach --quiet "$work/ref" "$rev"
LOOM_BUILD_DIR=$work/ref/build LOOM_TARGETS=loom-bake bash "$work/ref/scripts/build.sh" >/dev/null
LOOM_BUILD_DIR=$here/build LOOM_TARGETS=loom-bake bash "$here/scripts/build.sh" >/dev/null

# And a colour-only change of the organza, baked beside it: the bake that copies the
# colour-independent tables (raywave_simulation_key) instead of simulating them.
python3 - "$here/presets/samples/white_silk_organza.json" "$work/recoloured_organza.json" <<'PY'
import json, sys
spec = json.load(open(sys.argv[1]))
spec["name"] = "recoloured_organza"
spec["yarn"]["color"] = {"srgb": [0.2, 0.5, 0.8]}
json.dump(spec, open(sys.argv[2], "w"))
PY
status=0
specs=(plain twill satin basket "$here"/presets/samples/*.json "$work/recoloured_organza.json")
for s in "${specs[@]}"; do
  name=$(basename "$s" .json)
  for side in ref new; do
    exe=$work/ref/build/loom-bake
    [[ $side == new ]] && exe=$here/build/loom-bake
    t0=$SECONDS
    out=$("$exe" bake "$s" --quality "$quality" --progress=none -o "$work/atlas-$side/$name")
    [[ $name != recoloured_organza || $out == *'"reused_simulation":"/'* ]] ||
      { echo "$name $side: the colour-only bake did not reuse the organza's tables: $out" >&2
        status=1; }
    printf '%s %s: %d s\n' "$name" "$side" $((SECONDS - t0))
  done
  if python3 "$here/scripts/compare_atlases.py" "$work/atlas-ref/$name" "$work/atlas-new/$name"; then
    echo "$name: the same"
  else
    echo "$name: DIFFERS"
    status=1
  fi
done
exit $status
