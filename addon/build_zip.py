#!/usr/bin/env python3
"""Build the installable Loom extension zip: addon/* plus the repository's osl/ as osl/.

    python3 addon/build_zip.py [-o OUT.zip] [--baker PREFIX --platform linux-x64]

(default: build/loom-<version>[-<platform>].zip). With --baker, the zip also carries PREFIX's
bin/ (loom-bake, executable) and lib/ (the libraries it needs, scripts/package.sh gathers them),
and its manifest names the one platform they run on, as Blender asks of extensions with binaries.

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


def with_platform(manifest: str, platform: str) -> str:
    """The manifest text with `platforms = [platform]` (after blender_version_min)."""
    if re.search(r"^platforms\s*=", manifest, re.M):
        sys.exit("build_zip: blender_manifest.toml already names platforms")
    line = f'platforms = ["{platform}"]\n'
    m = re.search(r"^blender_version_min\s*=.*\n", manifest, re.M)
    if not m:
        sys.exit("build_zip: no blender_version_min in blender_manifest.toml")
    return manifest[:m.end()] + line + manifest[m.end():]


def build(out: str, baker: str | None = None, platform: str | None = None) -> str:
    entries = list(files_under(HERE, ""))
    osl = os.path.join(REPO, "osl")
    if os.path.isdir(os.path.join(HERE, "osl")):
        pass  # already inside addon/ (e.g. building from an unpacked zip)
    elif os.path.isdir(osl):
        entries += list(files_under(osl, "osl/"))
    else:
        sys.exit(f"build_zip: {osl} not found; OSL mode needs the shaders")
    if baker:
        exe = os.path.join(baker, "bin", "loom-bake")
        if not (os.path.isfile(exe) and os.access(exe, os.X_OK)):
            sys.exit(f"build_zip: --baker {baker}: no executable bin/loom-bake in it")
        entries += list(files_under(os.path.join(baker, "bin"), "bin/"))
        if os.path.isdir(os.path.join(baker, "lib")):
            entries += list(files_under(os.path.join(baker, "lib"), "lib/"))
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    tmp = out + ".tmp"
    try:
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
            for path, arc in sorted(entries, key=lambda e: e[1]):
                info = zipfile.ZipInfo(arc, EPOCH)
                info.compress_type = zipfile.ZIP_DEFLATED
                info.external_attr = (0o100755 if arc.startswith("bin/") else 0o100644) << 16
                with open(path, "rb") as f:
                    data = f.read()
                if arc == "blender_manifest.toml" and platform:
                    data = with_platform(data.decode("utf-8"), platform).encode("utf-8")
                z.writestr(info, data)
        os.replace(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("-o", "--output", default=None)
    p.add_argument("--baker", default=None,
                   help="an install prefix holding bin/loom-bake and lib/ to carry")
    p.add_argument("--platform", default=None,
                   help="the platform the carried baker runs on, e.g. linux-x64 (with --baker)")
    args = p.parse_args(argv)
    if bool(args.baker) != bool(args.platform):
        p.error("--baker and --platform go together")
    suffix = f"-{args.platform}" if args.platform else ""
    out = args.output or os.path.join(REPO, "build", f"loom-{manifest_version()}{suffix}.zip")
    print(build(out, args.baker, args.platform))


if __name__ == "__main__":
    main()
