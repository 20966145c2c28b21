"""Hand Blender's colour management config to loom-bake.

loom-bake converts the spec's sRGB colours to scene linear with OpenColorIO. It should use the
config this Blender renders with, so the yarn colours mean what the user's colour pickers mean.
loom-bake may run where Blender's own files are not visible at the same path (Loom's test set-up
runs it outside Blender's chroot; a remote or containerised baker is the same case), so the config
directory (config.ocio and the LUT folders it searches) is copied once into the atlas cache, keyed
by its content, and that copy is passed with --ocio-config.
"""

import hashlib
import os
import shutil

import bpy


def blender_config_dir() -> str | None:
    """Blender's colormanagement directory, or None (then loom-bake's built-in config is used;
    for Blender's default config the two agree: sRGB is IEC 61966-2-1 over Rec.709 primaries)."""
    env = os.environ.get("OCIO")
    if env and os.path.isfile(env):
        return os.path.dirname(os.path.abspath(env))
    d = bpy.utils.system_resource("DATAFILES", path="colormanagement")
    if d and os.path.isfile(os.path.join(d, "config.ocio")):
        return d
    return None


def staged(cache_dir: str) -> str | None:
    """Path of config.ocio in a copy of Blender's config inside ``cache_dir`` (made once)."""
    src = blender_config_dir()
    if src is None:
        return None
    with open(os.path.join(src, "config.ocio"), "rb") as f:
        key = hashlib.sha256(f.read()).hexdigest()[:16]
    dst = os.path.join(cache_dir, f"ocio-{key}")
    if not os.path.isfile(os.path.join(dst, "config.ocio")):
        tmp = f"{dst}.tmp-{os.getpid()}"
        shutil.rmtree(tmp, ignore_errors=True)
        shutil.copytree(src, tmp)
        try:
            os.replace(tmp, dst)
        except OSError:  # another Blender staged it first
            shutil.rmtree(tmp, ignore_errors=True)
    return os.path.join(dst, "config.ocio")
