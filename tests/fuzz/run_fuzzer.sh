#!/usr/bin/env bash
# One bounded libFuzzer run of one of Loom's fuzz targets (built by scripts/fuzz.sh, or by the
# sanitizer build of scripts/test.sh, which registers this as the CTest test fuzz.TARGET).
#   run_fuzzer.sh FUZZER TARGET OUT_DIR [SECONDS]
#     FUZZER: the fuzz_TARGET executable; TARGET: spec, manifest, cli_values, texture or wif
#     OUT_DIR: the corpus grows in OUT_DIR/TARGET (seeded from tests/fuzz/corpus/TARGET, and for
#       spec the built-in presets, for wif the sample drafts); a crash, a sanitizer report or a broken property leaves its
#       input in OUT_DIR/TARGET-crash-* and fails the run
#     SECONDS: default $LOOM_FUZZ_SECONDS, else 20
# Keep each finding as a test: copy the input into tests/fuzz/corpus/TARGET/ (replayed here at
# the start of every run, and by the unit tests for the manifest and texture corpora:
# tests/cpp/test_fuzz_corpus.cpp).
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
(($# == 3 || $# == 4)) || { echo "usage: run_fuzzer.sh FUZZER TARGET OUT_DIR [SECONDS]" >&2; exit 2; }
fuzzer=$1 target=$2 out=$3 seconds=${4:-${LOOM_FUZZ_SECONDS:-20}}
case $seconds in ''|*[!0-9]*|0)
  echo "run_fuzzer.sh: SECONDS must be a whole number of seconds >= 1, not \"$seconds\"" >&2
  exit 2 ;;
esac
[[ -d $here/tests/fuzz/corpus/$target ]] || {
  echo "run_fuzzer.sh: unknown target \"$target\" (no tests/fuzz/corpus/$target)" >&2; exit 2; }
corpus=$out/$target
mkdir -p "$corpus"
cp "$here/tests/fuzz/corpus/$target"/* "$corpus/"
[[ $target != spec ]] || cp "$here"/presets/*.json "$here"/presets/samples/*.json "$corpus/"
[[ $target != wif ]] || cp "$here"/presets/drafts/*.wif "$corpus/"
# fuzz_manifest adds a freshly baked manifest, fuzz_texture textures from the baker's writer.
export LOOM_FUZZ_SEED_OUT=$corpus/baked.json LOOM_FUZZ_SEED_DIR=$corpus
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
echo "== fuzz_$target: $seconds s (corpus $corpus) =="
if ! "$fuzzer" "$corpus" -max_total_time="$seconds" -timeout=60 -rss_limit_mb=4096 \
    -print_final_stats=1 -artifact_prefix="$out/$target-" 2>"$out/$target.log"; then
  echo "fuzz_$target FAILED: see $out/$target.log and $out/$target-*" >&2
  tail -n 40 "$out/$target.log" >&2
  exit 1
fi
grep -E "^stat::number_of_executed_units|^stat::new_units_added" "$out/$target.log" || true
