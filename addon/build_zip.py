#!/usr/bin/env python3
"""Build the installable Loom extension zip: addon/* plus the repository's osl/ as osl/.

    python3 addon/build_zip.py [-o OUT.zip]      (default: build/loom-<version>.zip)

Runs with any Python >= 3.8 (also Blender's). The zip is deterministic (sorted entries, fixed
timestamps), holds blender_manifest.toml at its root as Blender's extension installer expects,
and carries the OSL shaders and their shared headers so that OSL mode can flatten them into a
text datablock. Install with Edit > Preferences > Get Extensions > Install from Disk, or
`blender --command extension install-file -r user_default OUT.zip`.
"""

import argparse
import os
import re
import sys
import zipfile

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
SKIP_DIRS = {"__pycache__", ".git", ".pytest_cache"}
SKIP_FILES = {"build_zip.py"}
SKIP_SUFFIXES = (".pyc", ".pyo", ".zip", ".blend1")
EPOCH = (2024, 1, 1, 0, 0, 0)


def manifest_version() -> str:
    with open(os.path.join(HERE, "blender_manifest.toml"), encoding="utf-8") as f:
        m = re.search(r'^version\s*=\s*"([^"]+)"', f.read(), re.M)
    if not m:
        sys.exit("build_zip: no version in blender_manifest.toml")
    return m.group(1)


def files_under(root: str, prefix: str):
    for d, dirs, files in os.walk(root):
        dirs[:] = sorted(x for x in dirs if x not in SKIP_DIRS)
        for name in sorted(files):
            if name in SKIP_FILES or name.endswith(SKIP_SUFFIXES):
                continue
            path = os.path.join(d, name)
            rel = os.path.relpath(path, root).replace(os.sep, "/")
            yield path, prefix + rel


def build(out: str) -> str:
    entries = list(files_under(HERE, ""))
    osl = os.path.join(REPO, "osl")
    if os.path.isdir(os.path.join(HERE, "osl")):
        pass  # already inside addon/ (e.g. building from an unpacked zip)
    elif os.path.isdir(osl):
        entries += list(files_under(osl, "osl/"))
    else:
        sys.exit(f"build_zip: {osl} not found; OSL mode needs the shaders")
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    tmp = out + ".tmp"
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        for path, arc in sorted(entries, key=lambda e: e[1]):
            info = zipfile.ZipInfo(arc, EPOCH)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            with open(path, "rb") as f:
                z.writestr(info, f.read())
    os.replace(tmp, out)
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("-o", "--output", default=None)
    args = p.parse_args(argv)
    out = args.output or os.path.join(REPO, "build", f"loom-{manifest_version()}.zip")
    print(build(out))


if __name__ == "__main__":
    main()
