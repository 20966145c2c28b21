#!/usr/bin/env bash
# Measures the surface tier: whole-process bake time (median of N runs) and peak memory, atlas
# size per quality preset, the closure-mapping error per weave preset, and the Google Benchmark
# micro-benchmarks. Writes out/bench/bench.md and out/bench/bench.json.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
runs=${LOOM_BENCH_RUNS:-5}
LOOM_BUILD_DIR=$here/build bash "$here/scripts/build.sh" >/dev/null
bake=$here/build/loom-bake
out=$here/out/bench
mkdir -p "$out"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

median() { sort -g | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR+1)/2] : (a[NR/2] + a[NR/2+1]) / 2}'; }

{
  echo "# Surface tier measurements ($(date -u +%Y-%m-%d), $(nproc) cores)"
  echo
  echo "## Bake of the default fabric, median of $runs whole-process runs"
  echo
  echo "| quality | bake s (median) | peak RSS MiB | atlas MiB |"
  echo "|---|---|---|---|"
} > "$out/bench.md"
echo "[" > "$out/bench.json"
first=1
for q in draft preview final reference; do
  : > "$tmp/t"
  : > "$tmp/m"
  for ((i = 0; i < runs; i++)); do
    /usr/bin/time -f "%e %M" -o "$tmp/time" "$bake" bake default -o "$tmp/atlas-$q" --quality "$q" --force --progress=none >/dev/null
    read -r secs kb < "$tmp/time"
    echo "$secs" >> "$tmp/t"
    echo "$kb" >> "$tmp/m"
  done
  t=$(median < "$tmp/t")
  m=$(median < "$tmp/m")
  size=$(du -sb "$tmp/atlas-$q" | cut -f1)
  awk -v q="$q" -v t="$t" -v m="$m" -v s="$size" 'BEGIN { printf "| %s | %s | %.0f | %.2f |\n", q, t, m / 1024, s / 1048576 }' >> "$out/bench.md"
  [[ $first == 1 ]] || echo "," >> "$out/bench.json"
  first=0
  printf '{"quality":"%s","bake_seconds_median":%s,"peak_rss_kb":%s,"atlas_bytes":%s}' "$q" "$t" "$m" "$size" >> "$out/bench.json"
done
echo "]" >> "$out/bench.json"

{
  echo
  echo "## Closure-mapping error (model vs Cycles closure mixture), preview quality"
  echo
  echo "Relative L1 over the sphere of light directions, 64 texels x 24 views (loom-bake eval mapping)."
  echo
  echo "| weave | mean rel. L1 | worst rel. L1 | mean energy err. | worst energy err. |"
  echo "|---|---|---|---|---|"
} >> "$out/bench.md"
for p in plain twill satin basket; do
  "$bake" bake "$p" -o "$tmp/$p" --progress=none >/dev/null
  "$bake" eval mapping --atlas "$tmp/$p" > "$tmp/map.json"
  python3 - "$p" "$tmp/map.json" >> "$out/bench.md" <<'PY'
import json, sys
m = json.load(open(sys.argv[2]))
print(f"| {sys.argv[1]} | {m['mean_relative_l1']:.3f} | {m['worst_relative_l1']:.3f} | "
      f"{m['mean_energy_error']:.3f} | {m['worst_energy_error']:.3f} |")
PY
done

{
  echo
  echo "## Micro-benchmarks (Google Benchmark, median of 5 repetitions)"
  echo
  echo '```'
  "$here/build/loom-bench" --benchmark_repetitions=5 --benchmark_report_aggregates_only=true 2>/dev/null | grep -E "median|Benchmark"
  echo '```'
} >> "$out/bench.md"
cat "$out/bench.md"
echo "loom: wrote $out/bench.md"
