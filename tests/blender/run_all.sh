#!/usr/bin/env bash
# Run Loom's Blender-in-the-loop tests and the OSL compile check; print PASS/FAIL per test.
#
#   LOOM_BAKE=/path/to/loom-bake tests/blender/run_all.sh [-k PATTERN] [--keep]
#
# Blender comes from scripts/blender.sh (LOOM_BLENDER, blender on PATH, or the Debian chroot).
# loom-bake runs on the host: the tests inside Blender reach it through a wrapper made with
# `scripts/blender.sh host-exec-wrapper`, and the atlas for the render checks is baked on the
# host first. Outputs go to $LOOM_TEST_OUT (default: a fresh directory under /tmp, removed on
# success unless --keep). Exit status: 0 if every test passed.
set -uo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
repo=$(cd "$here/../.." && pwd)
blender="$repo/scripts/blender.sh"
pattern=""
keep=0
while (($#)); do
    case $1 in
        -k) pattern=$2; shift ;;
        --keep) keep=1 ;;
        -h|--help) sed -n '2,11p' "$0"; exit 0 ;;
        *) echo "run_all.sh: unknown argument $1" >&2; exit 2 ;;
    esac
    shift
done

: "${LOOM_BAKE:?set LOOM_BAKE to the loom-bake executable}"
LOOM_BAKE=$(readlink -f "$LOOM_BAKE")
[[ -x $LOOM_BAKE ]] || { echo "run_all.sh: $LOOM_BAKE is not executable" >&2; exit 2; }

out=${LOOM_TEST_OUT:-$(mktemp -d /tmp/loom-blender-tests.XXXXXX)}
mkdir -p "$out"
echo "run_all.sh: outputs in $out"
"$blender" info || { echo "run_all.sh: no usable Blender" >&2; exit 1; }

# A private copy: a concurrent rebuild of loom-bake must not change it halfway through the run.
mkdir -p "$out/bin"
cp "$LOOM_BAKE" "$out/bin/loom-bake"
LOOM_BAKE=$out/bin/loom-bake
"$blender" host-exec-wrapper "$LOOM_BAKE" "$out/loom-bake" || exit 1
echo "run_all.sh: baking the test atlas (plain, preview) on the host"
"$LOOM_BAKE" bake plain -o "$out/atlas-plain" --quality preview --progress=none >/dev/null || {
    echo "FAIL bake test atlas"; exit 1; }

results=()
failed=0
run_test() {  # name, command...
    local name=$1 t0 rc
    shift
    if [[ -n $pattern && $name != *$pattern* ]]; then return; fi
    t0=$SECONDS
    "$@" >"$out/$name.log" 2>&1
    rc=$?
    if ((rc == 0)); then
        results+=("PASS $name ($((SECONDS - t0)) s)")
    else
        results+=("FAIL $name (exit $rc, log: $out/$name.log)")
        failed=1
        tail -n 15 "$out/$name.log" | sed 's/^/    /'
    fi
    echo "${results[-1]}"
}

py() {  # blender test script, args...
    local script=$1
    shift
    "$blender" run -b --factory-startup --python-exit-code 1 --python "$here/$script" -- "$@"
}

run_test extension_manifest "$blender" run -b --factory-startup -c extension validate "$repo/addon"
run_test blender_runs py test_blender_runs.py "$out/blender_runs"
run_test addon py test_addon.py --out "$out/addon"
run_test transcription py test_transcription.py
run_test bake_assign py test_bake_assign.py --loom-bake "$out/loom-bake" --out "$out/bake_assign"
run_test render py test_render.py --atlas "$out/atlas-plain" --out "$out/render"
run_test parity py test_parity.py --loom-bake "$out/loom-bake" --atlas "$out/atlas-plain" \
    --out "$out/parity" --json "$out/parity/parity.json"
run_test demo "$blender" run -b "$repo/blend/demo_surface.blend" --python-exit-code 1 \
    --python "$repo/blend/render_demo.py" -- --atlas "$out/atlas-plain" \
    --out "$out/demo.png" --res 96 72 --samples 4
run_test oslc "$repo/tests/osl/check_oslc.sh"

echo "---- summary"
printf '%s\n' "${results[@]}"
if ((failed == 0 && keep == 0)) && [[ -z ${LOOM_TEST_OUT:-} ]]; then
    rm -rf "$out"
fi
exit $failed
