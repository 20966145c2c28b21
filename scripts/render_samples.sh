#!/usr/bin/env bash
# The ray-wave supplement's sample scenes (blend/sample_scenes.py): bakes each sample fabric in
# the variants its figures compare (delta transmission vs diffraction back-lit; Perlin off/on x
# wave noise off/on front-lit), renders them headless in node mode and writes a contact sheet.
#   bash scripts/render_samples.sh [--quality Q] [--samples N] [--res W H] [--fabrics A,B,...]
#                                  [--save-blend] [--out DIR]
# Output (default out/samples): <fabric>_<front|back>_<variant>.png, samples.json (render
# times), sheet.png (a row per fabric: front-lit nonoise, perlin_nonoise, diffraction (the full
# model), perlin, then back-lit delta, diffraction) and, with --save-blend, the scenes.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
quality=draft
samples=32
res=(256 256)
fabrics=orange_polyester_satin,white_silk_organza,cream_cotton_twill,gray_wool_twill,black_polyester_plain,beige_silk_satin,blue_cotton_satin
out=$here/out/samples
save=()
while (($#)); do
  case $1 in
    --quality) quality=$2; shift ;;
    --samples) samples=$2; shift ;;
    --res) res=("$2" "$3"); shift 2 ;;
    --fabrics) fabrics=$2; shift ;;
    --out) out=$2; shift ;;
    --save-blend) save=(--save-blend) ;;
    -h|--help) sed -n '2,9p' "$0"; exit 0 ;;
    *) echo "render_samples.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
  shift
done
case $quality in draft|preview|final|reference) ;; *)
  echo "render_samples.sh: --quality: expected draft, preview, final or reference, got $quality" >&2
  exit 2 ;;
esac

LOOM_BUILD_DIR=$here/build bash "$here/scripts/build.sh"
bake=$here/build/loom-bake
mkdir -p "$out/atlases"
out=$(cd "$out" && pwd)
index=$out/atlases.json
echo "{" > "$index.tmp"
first=1
IFS=, read -ra list <<<"$fabrics"
for f in "${list[@]}"; do
  echo "== bake $f ($quality): 5 variants =="
  entries=()
  # variant: Perlin, wave noise, diffraction
  for v in "diffraction false true true" "delta false true false" "perlin true true true" \
           "perlin_nonoise true false true" "nonoise false false true"; do
    read -r name perlin noise diffraction <<<"$v"
    spec=$out/atlases/${f}_$name.json
    "$bake" presets "$f" | python3 -c '
import json, sys
d = json.load(sys.stdin)
name, perlin, noise, diffraction = sys.argv[1:5]
d["name"] = name
d.setdefault("components", {})["perlin"] = perlin == "true"
d["wave"] = {"noise": noise == "true", "diffraction": diffraction == "true"}
json.dump(d, sys.stdout, indent=1)' "${f}_$name" "$perlin" "$noise" "$diffraction" > "$spec"
    "$bake" bake "$spec" -o "$out/atlases/${f}_$name" --quality "$quality" --progress=none
    entries+=("\"$name\": \"$out/atlases/${f}_$name\"")
  done
  ((first)) || echo "," >> "$index.tmp"
  first=0
  (IFS=,; echo "\"$f\": {${entries[*]}}") >> "$index.tmp"
done
echo "}" >> "$index.tmp"
mv "$index.tmp" "$index"

echo "== render (node mode, ${res[0]}x${res[1]}, $samples samples) =="
bash "$here/scripts/blender.sh" run -b --factory-startup --python-exit-code 1 \
  --python "$here/blend/sample_scenes.py" -- --atlases "$index" --out "$out" \
  --samples "$samples" --res "${res[0]}" "${res[1]}" "${save[@]}"

cells=()
for f in "${list[@]}"; do
  for v in front_nonoise front_perlin_nonoise front_diffraction front_perlin back_delta \
           back_diffraction; do
    cells+=("$out/${f}_$v.png")
  done
done
oiiotool "${cells[@]}" --mosaic:pad=4 "6x${#list[@]}" -o "$out/sheet.png"
echo "loom: sample scenes in $out (contact sheet $out/sheet.png)"
