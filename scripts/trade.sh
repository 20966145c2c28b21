#!/usr/bin/env bash
# The speed/accuracy trade (bench/trade.py): for each tier (surface, raywave) and quality preset
# on the weave presets and the sample fabrics, bake time and peak memory (median of whole-process
# runs), atlas size, render time (per sample, and whole) as a ratio to a Principled BSDF with
# sheen (one Blender run per fabric and tier, node mode), error against the reference preset
# (BSDF relative L1 by the C++ model; image relative RMSE, beside the reference rendered with
# another seed), the closure-mapping error, and the error of the model and of the closures against
# the fiber-level truth (eval error --truth: every tier against the same fibers).
#   bash scripts/trade.sh [--fabrics A,B] [--tiers surface,raywave] [--raywave-fabrics A,B]
#                         [--qualities draft,final] [--runs 3] [--samples 16] [--res 96]
#                         [--timing-samples 64]
#                         [--repeats 3] [--light front|back] [--no-render] [--truth-rays 200000]
#                         [--lobes FABRIC:QUALITY:THETA_I:H:SIGMA|none] [--out DIR] [--resume]
#   bash scripts/trade.sh --merge DIR1,DIR2 --out DIR  (join earlier runs: one table, one plot)
# Writes DIR (default out/trade): trade.csv, trade.json, trade.md (the summary), pareto.png
# (error against render-time ratio) and lobes.png (each fitted lobe at one (theta_i, h, sigma)
# beside the simulation). Everything (11 fabrics x 2 tiers x 4 presets, 3 runs) takes hours on
# 2 cores, mostly the ray-wave reference bakes; --runs 1 or a subset of --fabrics is quicker.
# Each fabric and tier, once measured, is kept in DIR/done.json: --resume (same settings, same
# loom-bake binary) measures only the rest, so a long run can be split over several sittings.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
case ${1:-} in -h|--help) sed -n '2,20p' "$0"; exit 0 ;; esac
case " $* " in
  *" --merge"*) ;;  # joins earlier runs: measures nothing, needs no build
  *)
    bash "$here/scripts/setup.sh"
    LOOM_BUILD_DIR=$here/build bash "$here/scripts/build.sh" >/dev/null
    ;;
esac
# Debian's python3 (its numpy and matplotlib), whatever python3 comes first on PATH.
exec /usr/bin/python3 "$here/bench/trade.py" --bake "$here/build/loom-bake" "$@"
