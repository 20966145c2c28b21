#!/usr/bin/env python3
"""Are two atlases the same result? Each texture's two files (the node file, OpenEXR, and the
texture, maketx's tiled TIFF) byte for byte (the manifests' hashes, checked against the files
themselves), or else texel for texel at every MIP level with no difference allowed and the same
metadata but for the date (idiff, iinfo): OpenImageIO writes a TIFF's tiles in an order that
varies from run to run, and bakers before 2026-12-06 wrote the time of the bake into both files.
And the manifests field by field, except what differs between two bakes of one spec by design:
the bake key and the simulation key (they hold the baker binary's hash), the timings (fields
named "seconds" or "*_seconds"), where a colour-only bake copied its tables from
(raywave.reused_from) and the hashes of files found the same texel for texel.

    python3 scripts/compare_atlases.py ATLAS_A ATLAS_B

Exit 0 when they are the same, 1 with one line per difference, 2 on bad input.
"""

import concurrent.futures
import hashlib
import json
import os
import subprocess
import sys

VOLATILE = {"bake_key", "simulation_key", "reused_from"}


def stable(v):
    """The manifest without the fields that differ by design."""
    if isinstance(v, dict):
        return {k: stable(x) for k, x in v.items()
                if k not in VOLATILE and k != "seconds" and not k.endswith("_seconds")}
    if isinstance(v, list):
        return [stable(x) for x in v]
    return v


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def differences(a, b, path=""):
    """Paths at which two JSON values differ."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            p = f"{path}.{k}" if path else k
            if k not in a or k not in b:
                out.append(f"{p}: only in {'B' if k not in a else 'A'}")
            else:
                out += differences(a[k], b[k], p)
        return out
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in differences(x, y, f"{path}[{i}]")]
    return [] if a == b else [f"{path}: {json.dumps(a)[:80]} != {json.dumps(b)[:80]}"]


def load(atlas):
    path = os.path.join(atlas, "manifest.json")
    try:
        with open(path) as f:
            m = json.load(f)
    except (OSError, ValueError) as e:
        print(f"compare_atlases: {path}: {e}", file=sys.stderr)
        sys.exit(2)
    # The hashes stand for the files only if the files hold them.
    for name, t in m.get("textures", {}).items():
        for key, hkey in (("file", "sha256"), ("node_file", "node_sha256")):
            got = sha256(os.path.join(atlas, t[key]))
            if got != t[hkey]:
                print(f"compare_atlases: {atlas}: textures.{name}.{key} does not hold its "
                      f"{hkey}", file=sys.stderr)
                sys.exit(2)
    return m


def same_texture(a, b):
    """Two image files with the same texels at every MIP level and the same metadata but for
    the date."""
    same = subprocess.run(["idiff", "-a", "-fail", "0", "-warn", "0", a, b],
                          capture_output=True, text=True).returncode == 0
    info = [[line for line in subprocess.run(["iinfo", "-a", "-v", f], capture_output=True,
                                             text=True, check=True).stdout.replace(f, "FILE")
             .splitlines() if "DateTime" not in line] for f in (a, b)]
    return same and info[0] == info[1]


def main():
    if len(sys.argv) != 3:
        print("usage: compare_atlases.py ATLAS_A ATLAS_B", file=sys.stderr)
        sys.exit(2)
    a, b = load(sys.argv[1]), load(sys.argv[2])
    # Files whose bytes differ: compared texel for texel, a few at a time.
    todo = []
    for name, t in a.get("textures", {}).items():
        u = b.get("textures", {}).get(name)
        for key, hkey in (("file", "sha256"), ("node_file", "node_sha256")):
            if u and t[hkey] != u[hkey] and t[key] == u[key]:
                todo.append((t, u, key, hkey))
    with concurrent.futures.ThreadPoolExecutor(max_workers=os.cpu_count() or 2) as pool:
        same = list(pool.map(lambda w: same_texture(os.path.join(sys.argv[1], w[0][w[2]]),
                                                    os.path.join(sys.argv[2], w[1][w[2]])), todo))
    for (t, u, key, hkey), ok in zip(todo, same):
        if ok:
            u[hkey] = t[hkey]
    diff = differences(stable(a), stable(b))
    for d in diff:
        print(d)
    sys.exit(1 if diff else 0)


if __name__ == "__main__":
    main()
