"""Loom's scripting API, for scripts and CI (``import loom.api`` once the add-on is enabled).

    import loom.api
    atlas = loom.api.bake("twill", quality="preview")          # blocking; cached
    mat = loom.api.assign(bpy.data.objects["Cloth"], atlas)    # Auto: OSL where it runs

Both functions raise ``loom.api.LoomError`` (a RuntimeError) with loom-bake's message on failure.
"""

from __future__ import annotations

import os

import bpy

from . import bakery, colour_config, fibers, manifest as _manifest, material as _material
from . import preferences, scene_needs as _scene_needs
from .bakery import LoomBakeError as LoomError, read_manifest
from .preferences import find_loom_bake

__all__ = ["bake", "assign", "LoomError", "find_loom_bake", "presets", "last_assign",
           "scene_needs", "update_fibers", "remove_fibers"]

# Set by assign(): what it did (mode and why); read it with last_assign().
_last: dict = {}


def resolve_cache_dir(cache_dir: str | None = None) -> str:
    """The atlas cache: the argument, the add-on preference, or ~/.cache/loom/atlases."""
    if cache_dir:
        return os.path.abspath(os.path.expanduser(cache_dir))
    p = preferences.get()
    if p is not None and p.cache_dir:
        return os.path.abspath(bpy.path.abspath(p.cache_dir))
    return bakery.default_cache_dir()


def presets(loom_bake: str | None = None) -> list[str]:
    exe = find_loom_bake(loom_bake)
    if exe is None:
        raise LoomError("loom-bake not found (preferences, $LOOM_BAKE or PATH)")
    return bakery.list_presets(exe)


def bake(spec: str, quality: str = "preview", loom_bake: str | None = None,
         cache_dir: str | None = None, force: bool = False, timeout: float | None = None) -> str:
    """Bake ``spec`` (preset name or spec file) at ``quality`` into the atlas cache and return
    the atlas directory. Blocks; reuses a cached atlas of the same canonical spec."""
    exe = find_loom_bake(loom_bake)
    if exe is None:
        raise LoomError("loom-bake not found: install the Loom package that carries it, pass "
                        "loom_bake=, set it in the add-on preferences, set $LOOM_BAKE, or put "
                        "it on PATH")
    cache = resolve_cache_dir(cache_dir)
    os.makedirs(cache, exist_ok=True)
    req = bakery.BakeRequest(spec=spec, quality=quality, loom_bake=exe, cache_dir=cache,
                             force=force, ocio_config=colour_config.staged(cache),
                             validate=_manifest.atlas_problem)
    status = bakery.bake_blocking(req, timeout=timeout)
    if status.state != "done":
        raise LoomError(status.message)
    return status.atlas_dir


def assign(obj, atlas_dir: str, mode: str = "auto", scale: float | None = None, *,
           size_factor: float = 1.0, material=None, interpolation: str = "Linear", scene=None,
           average: float | None = None):
    """Build a Loom material for ``atlas_dir`` on ``obj`` and return it.

    mode: "auto" (OSL where it can run, else nodes), "osl" (falls back to nodes, with the
    reason, where OSL cannot run), "nodes".
    scale: weave repeats per UV unit; None gives the weave its physical size on this object
    (from the mesh's UV-to-world ratio and the atlas's repeat size), times ``size_factor``.
    material: the material to (re)build; default the object's active material if Loom manages
    it (see material.is_loom_material), else a new one in the active slot.
    interpolation: atlas map filtering, "Linear" (default) or "Closest" (whole texels).
    average: the material's Average (1: the repeat-averaged closures, 0: every texel's); None
    drives it by the camera distance (scene_needs.average_drive: averaged where a repeat spans
    less than 2 pixels).
    What was done (mode and why) is printed and available from ``last_assign()``.
    """
    scene = scene or bpy.context.scene
    manifest = read_manifest(atlas_dir)
    _material.check_tier(manifest, atlas_dir)  # before any material is created or changed
    if scale is None:
        scale = _material.physical_repeats(obj, manifest, size_factor)
    mat = _material.ensure_material(obj, material)
    res = _material.build_material(mat, atlas_dir, mode=mode, scale=float(scale), scene=scene,
                                   interpolation=interpolation)
    drive = (_scene_needs.average_drive(obj, scene, float(scale)) if average is None else
             {"kind": "constant", "value": float(average), "reason": "given"})
    _material.set_average(mat, drive)
    if hasattr(mat, "loom"):
        mat.loom.scale_mode = "REPEATS"
        mat.loom.repeats = float(scale)
    warning = _material.uv_warning(obj)
    _last.clear()
    _last.update(material=mat.name, mode=res.mode, reason=res.reason, scale=res.scale,
                 atlas=os.path.abspath(atlas_dir), warning=warning)
    if warning:
        print(f"loom: warning: {warning}")
    print(f"loom: {mat.name}: {'OSL' if res.mode == 'OSL' else 'node'} mode ({res.reason}); "
          f"{res.scale:g} repeats per UV unit")
    return mat


def last_assign() -> dict:
    """{material, mode ('OSL'|'NODES'), reason, scale, atlas, warning} of the last assign()."""
    return dict(_last)


def scene_needs(obj, yarn_um: float, ply_um: float, plies: int, repeat_um: float,
                repeats_per_uv: float, scene=None) -> dict:
    """What ``obj`` needs in ``scene`` (default: the context's): ``{"tier": "surface" |
    "raywave", "transmission", "double_layer", "diffraction", "multi_ply", "yarn_px", "ply_px",
    "reasons": [...]}`` from the camera's view of its yarns and plies and from the lights behind
    it (``loom/scene_needs.py``). Sizes are the spec's, in micrometres; ``repeat_um`` is the
    weave repeat's length along u and ``repeats_per_uv`` the material's Scale."""
    return _scene_needs.scene_needs(obj, scene or bpy.context.scene, yarn_um, ply_um, plies,
                                    repeat_um, repeats_per_uv).as_dict()


def update_fibers(obj, scene=None, camera=None, loom_bake: str | None = None,
                  cache_dir: str | None = None, max_vertices: int | None = None) -> dict:
    """Fiber tier: real fibers (hair curves) on ``obj`` where ``camera`` (default the scene's)
    resolves them; call again after moving the camera. Returns what was done (see
    ``fibers.update_fibers``); raises LoomError with the reason, changing nothing, when it
    cannot (no Loom material, no UV map, a region over ``max_vertices``)."""
    exe = find_loom_bake(loom_bake)
    if exe is None:
        raise LoomError("loom-bake not found (preferences, $LOOM_BAKE or PATH)")
    return fibers.update_fibers(obj, scene, camera, loom_bake=exe,
                                cache_dir=resolve_cache_dir(cache_dir),
                                max_vertices=max_vertices or fibers.DEFAULT_MAX_VERTICES)


def remove_fibers(obj) -> bool:
    """Remove the fibers update_fibers made for ``obj``; True if there were any."""
    return fibers.remove_fibers(obj)
