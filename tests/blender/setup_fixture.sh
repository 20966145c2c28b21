#!/usr/bin/env bash
# CTest fixture for the Blender tests: a wrapper through which Blender (possibly inside Loom's
# Debian chroot) runs the host's loom-bake, and the test atlases baked on the host (the
# final-quality organza is a fixture of its own, blender.fixture_final in tests/CMakeLists.txt,
# baked while the first tests run).
#   setup_fixture.sh LOOM_BAKE OUT_DIR LOOM_TAMPER_ATLAS
set -euo pipefail
bake=$(readlink -f "$1")
out=$2
tamper=$(readlink -f "$3")
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
rm -rf "$out"
mkdir -p "$out/bin"
# A private copy: a rebuild of loom-bake during the tests must not change it halfway.
cp "$bake" "$out/bin/loom-bake"
bash "$repo/scripts/blender.sh" host-exec-wrapper "$out/bin/loom-bake" "$out/bin/loom-bake-wrapper"
"$out/bin/loom-bake" bake plain -o "$out/atlas-plain" --quality preview --progress=none
# The same cloth with per-texel fitted closures (model.closures "fitted", fitted_closures.h).
"$out/bin/loom-bake" presets plain | python3 -c '
import json, sys
d = json.load(sys.stdin)
d["name"], d["model"]["closures"] = "plain_fitted", "fitted"
json.dump(d, sys.stdout)' > "$out/plain_fitted.json"
"$out/bin/loom-bake" bake "$out/plain_fitted.json" -o "$out/atlas-plain-fitted" --quality preview \
  --progress=none
# The seven sample fabrics (ray-wave presets) at draft, for the ray-wave node-mode tests.
# Two bakes at a time: much of a draft bake runs on one core.
printf '%s\n' white_silk_organza orange_polyester_satin beige_silk_satin cream_cotton_twill \
  gray_wool_twill black_polyester_plain blue_cotton_satin |
  xargs -P 2 -I{} "$out/bin/loom-bake" bake {} -o "$out/raywave/{}" --quality draft --progress=none
# The organza's non-wave variant (delta transmission through the gaps), for the diffraction
# cross check of test_raywave_render.py.
"$out/bin/loom-bake" presets white_silk_organza | python3 -c '
import json, sys
d = json.load(sys.stdin)
d["name"], d["wave"] = "white_silk_organza_delta", {"diffraction": False}
json.dump(d, sys.stdout)' > "$out/organza_delta.json"
"$out/bin/loom-bake" bake "$out/organza_delta.json" -o "$out/raywave-delta/white_silk_organza" \
  --quality draft --progress=none
# blend/sample_scenes.py's index for its smoke test: the organza's full model and delta variant.
printf '{"white_silk_organza": {"diffraction": "%s", "delta": "%s"}}\n' \
  "$(readlink -f "$out/raywave/white_silk_organza")" \
  "$(readlink -f "$out/raywave-delta/white_silk_organza")" > "$out/sample_atlases.json"
# Atlases holding texels the baker never writes (out of range; NaN and infinities), for the
# shaders' texel guard (texel_guard.h) in node mode: the plain surface atlas and a ray-wave one.
"$tamper" "$out/atlas-plain" "$out/tampered/plain-range" --mode range
"$tamper" "$out/atlas-plain" "$out/tampered/plain-nonfinite" --mode nonfinite
"$tamper" "$out/raywave/cream_cotton_twill" "$out/tampered/twill-range" --mode range
"$tamper" "$out/raywave/cream_cotton_twill" "$out/tampered/twill-nonfinite" --mode nonfinite
echo "fixture ready in $out"
