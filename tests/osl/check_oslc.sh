#!/usr/bin/env bash
# Compile Loom's OSL shaders with oslc, as Blender's Script node would.
#
#   tests/osl/check_oslc.sh            (exit 77, "skipped: oslc not found", without oslc; CTest reports it skipped)
#
# Environment:
#   OSLC              the compiler (default: oslc on PATH)
#   LOOM_OSL_INCLUDE  directory (or :-separated directories) holding Cycles' stdcycles.h, e.g.
#                     <blender>/<version>/scripts/addons_core/cycles/shader; when unset, a few
#                     usual Blender install locations are searched.
#
# Two checks per shader in osl/*.osl, and one per shared header:
#   1. the file as is, with -I osl/include (an external Script node);
#   2. the text the add-on puts in an internal text datablock: its includes flattened by
#      addon/osl_source.py, compiled *without* osl/include, proving the .blend is self-contained;
#   3. each osl/include/loom/*.h alone in an empty shader.
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
repo=$(cd "$here/../.." && pwd)
oslc=${OSLC:-oslc}

if ! command -v "$oslc" >/dev/null 2>&1; then
    echo "skipped: oslc not found (put Blender's or OSL's oslc on PATH, or set OSLC)"
    exit 77
fi

inc=()
if [[ -n ${LOOM_OSL_INCLUDE:-} ]]; then
    IFS=: read -ra dirs <<<"$LOOM_OSL_INCLUDE"
    for d in "${dirs[@]}"; do inc+=("-I$d"); done
else
    for d in /usr/share/blender/scripts/addons_core/cycles/shader \
             /usr/share/blender/*/scripts/addons_core/cycles/shader \
             /usr/share/blender/*/scripts/addons/cycles/shader \
             /opt/blender*/*/scripts/addons_core/cycles/shader; do
        if [[ -f $d/stdcycles.h ]]; then inc+=("-I$d"); break; fi
    done
fi
found=0
for flag in "${inc[@]}"; do [[ -f ${flag#-I}/stdcycles.h ]] && found=1; done
if ((found == 0)); then
    echo "error: stdcycles.h not found; set LOOM_OSL_INCLUDE to the directory of Cycles' stdcycles.h" >&2
    exit 1
fi

tmp=$(mktemp -d "${TMPDIR:-/tmp}/loom-oslc.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
status=0
shopt -s nullglob
shaders=("$repo"/osl/*.osl)
((${#shaders[@]} > 0)) || { echo "error: no shaders in $repo/osl" >&2; exit 1; }
for src in "${shaders[@]}"; do
    name=$(basename "$src" .osl)
    if "$oslc" -q "-I$repo/osl/include" "${inc[@]}" -o "$tmp/$name.oso" "$src"; then
        echo "PASS oslc $name.osl"
    else
        echo "FAIL oslc $name.osl"; status=1
    fi
    if command -v python3 >/dev/null 2>&1; then
        PYTHONPATH="$repo/addon" python3 -c '
import sys, osl_source
sys.stdout.write(osl_source.flatten(sys.argv[1]) + "\n")' "$src" >"$tmp/$name.flat.osl"
        if "$oslc" -q "${inc[@]}" -o "$tmp/$name.flat.oso" "$tmp/$name.flat.osl"; then
            echo "PASS oslc $name.osl (flattened, no Loom include path)"
        else
            echo "FAIL oslc $name.osl (flattened)"; status=1
        fi
    fi
done
# 3. Every shared header on its own (headers no shader includes yet are type-checked too).
for hdr in "$repo"/osl/include/loom/*.h; do
    hname=$(basename "$hdr" .h)
    printf '#include "stdcycles.h"\n#include "loom/%s.h"\nshader loom_header_%s() {}\n' \
        "$hname" "$hname" >"$tmp/header_$hname.osl"
    if "$oslc" -q "-I$repo/osl/include" "${inc[@]}" -o "$tmp/header_$hname.oso" "$tmp/header_$hname.osl"; then
        echo "PASS oslc loom/$hname.h"
    else
        echo "FAIL oslc loom/$hname.h"; status=1
    fi
done
exit $status
