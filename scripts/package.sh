#!/usr/bin/env bash
# Builds the self-contained Blender extension: dist/loom-<version>-linux-x64.zip (or -o OUT.zip)
# holding the add-on, the OSL sources and headers it reads, and loom-bake with the shared
# libraries it needs in lib/ (found through its run path $ORIGIN/../lib): nothing is needed from
# the system beyond glibc. Install it with Edit > Preferences > Get Extensions > Install from
# Disk, or `blender --command extension install-file -r user_default -e OUT.zip`.
#   bash scripts/package.sh [-o OUT.zip]
# loom-bake is built (release) in $LOOM_BUILD_DIR (default build/) when it is not up to date.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
out=
while (($#)); do
  case $1 in
    -o) out=${2:?-o needs a file name}; shift 2 ;;
    -h|--help) sed -n '2,8p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "package.sh: unknown argument \"$1\" (allowed: -o OUT.zip)" >&2; exit 2 ;;
  esac
done
[[ $(uname -s)-$(uname -m) == Linux-x86_64 ]] ||
  { echo "package.sh: builds linux-x64 packages only (this is $(uname -s)-$(uname -m))" >&2; exit 2; }
version=$(sed -n 's/^version *= *"\(.*\)"/\1/p' "$here/addon/blender_manifest.toml")
out=${out:-$here/dist/loom-$version-linux-x64.zip}
build=${LOOM_BUILD_DIR:-$here/build}

LOOM_BUILD_DIR=$build LOOM_TARGETS=loom-bake bash "$here/scripts/build.sh"
stage=$(mktemp -d "${TMPDIR:-/tmp}/loom-package.XXXXXX")
trap 'rm -rf "$stage"' EXIT
cmake --install "$build" --prefix "$stage" --component baker --strip >/dev/null
mkdir -p "$stage/lib"
# Every library loom-bake loads (ldd lists them all, dependencies of dependencies too) but
# glibc's own, which must come from the system it runs on.
missing=$(ldd "$stage/bin/loom-bake" | awk '/not found/ {print $1}')
[[ -z $missing ]] || { echo "package.sh: loom-bake needs libraries not found: $missing" >&2; exit 1; }
ldd "$stage/bin/loom-bake" | awk '$2 == "=>" && $3 ~ /^\// {print $1, $3}' |
  while read -r soname path; do
    case $soname in
      libc.so.*|libm.so.*|libmvec.so.*|libpthread.so.*|libdl.so.*|librt.so.*|libresolv.so.*|\
      libutil.so.*|ld-linux*) continue ;;
    esac
    cp -L "$path" "$stage/lib/$soname"
    chmod 0644 "$stage/lib/$soname"
    strip --strip-unneeded "$stage/lib/$soname"
  done
"$stage/bin/loom-bake" --version >/dev/null  # runs from the staged tree
python3 "$here/addon/build_zip.py" -o "$out" --baker "$stage" --platform linux-x64 >/dev/null
echo "$out ($(du -h "$out" | cut -f1), $(ls "$stage/lib" | wc -l) libraries)"
