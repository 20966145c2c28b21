"""Loom's OSL sources as shipped with the add-on: where they are, the constants their headers
define, and the self-contained (include-flattened) text of a shader. No ``bpy`` here.

The add-on zip carries ``osl/`` next to this file (see ``build_zip.py``); a source checkout has
it at ``../osl`` relative to ``addon/`` (symlinks resolved, so a dev install that links
``addon/`` into an extension repository still finds it).
"""

from __future__ import annotations

import os
import re

SURFACE_SHADER = "loom_cloth_surface.osl"

_INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"\s*$')
_DEFINE = re.compile(r"^\s*#\s*define\s+(LOOM_[A-Z0-9_]+)\s+([-+0-9.eE]+)\s*(//.*)?$")


def osl_dir() -> str | None:
    """The directory holding ``loom_*.osl`` and ``include/loom/*.h``, or None."""
    here = os.path.dirname(os.path.realpath(__file__))
    for cand in (os.path.join(here, "osl"), os.path.join(os.path.dirname(here), "osl")):
        if os.path.isfile(os.path.join(cand, SURFACE_SHADER)) or os.path.isdir(
            os.path.join(cand, "include", "loom")
        ):
            return cand
    return None


def include_dirs() -> list[str]:
    d = osl_dir()
    return [os.path.join(d, "include")] if d else []


def header_constants() -> dict[str, float]:
    """``#define LOOM_NAME number`` from the shared headers (the single source of the constants
    that node mode needs: LOOM_HORIZON_DIRS, LOOM_HORIZON_SOFTNESS, LOOM_ALBEDO_LUT_SIZE,
    LOOM_SGGX_MIN_ROUGHNESS, ...)."""
    out: dict[str, float] = {}
    for inc in include_dirs():
        hdir = os.path.join(inc, "loom")
        for name in sorted(os.listdir(hdir)) if os.path.isdir(hdir) else []:
            if not name.endswith(".h"):
                continue
            with open(os.path.join(hdir, name), encoding="utf-8") as f:
                for line in f:
                    m = _DEFINE.match(line)
                    if m:
                        out[m.group(1)] = float(m.group(2))
    return out


def required_constants(required) -> dict[str, float]:
    """header_constants(); raises naming any of ``required`` that the headers lack."""
    c = header_constants()
    missing = [k for k in required if k not in c]
    if missing:
        raise RuntimeError(f"the shared OSL headers do not define {', '.join(missing)} (are the "
                           f"add-on's osl/ sources present? {osl_dir()})")
    return c


def flatten(path: str, include_paths: list[str] | None = None) -> str:
    """The text of the OSL file ``path`` with every quoted ``#include`` that resolves to a file
    (relative to the including file first, then ``include_paths``) replaced by that file's
    flattened text, each file at most once (the first occurrence; later ones become comments,
    which is what their include guards would do anyway). Includes that do not resolve, such as
    ``stdcycles.h``, stay: Blender's own oslc provides them.

    Why: a Script node with an internal text datablock is compiled from a temporary file, so
    relative includes cannot resolve; flattening makes the .blend self-contained.
    """
    include_paths = list(include_paths if include_paths is not None else include_dirs())
    seen: set[str] = set()
    return _flatten(os.path.realpath(path), include_paths, seen)


def _flatten(path: str, include_paths: list[str], seen: set[str]) -> str:
    seen.add(path)
    here = os.path.dirname(path)
    out: list[str] = []
    with open(path, encoding="utf-8") as f:
        lines = f.read().splitlines()
    for line in lines:
        m = _INCLUDE.match(line)
        if not m:
            out.append(line)
            continue
        target = _resolve(m.group(1), here, include_paths)
        if target is None:
            out.append(line)  # e.g. stdcycles.h: Blender's oslc has it on its include path
        elif target in seen:
            out.append(f"// (flattened) {m.group(1)} already included above")
        else:
            rel = os.path.basename(target)
            out.append(f"// ---- begin {m.group(1)} (inlined by the Loom add-on) ----")
            out.append(_flatten(target, include_paths, seen))
            out.append(f"// ---- end {rel} ----")
    return "\n".join(out)


def _resolve(name: str, here: str, include_paths: list[str]) -> str | None:
    for base in [here, *include_paths]:
        cand = os.path.join(base, name)
        if os.path.isfile(cand):
            return os.path.realpath(cand)
    return None


_COMMENTS = re.compile(r"//[^\n]*|/\*.*?\*/", re.S)


def code_fingerprint(path: str) -> str:
    """SHA-256 (16 hex digits) of a source's code with comments and whitespace removed: changes
    when the code changes, not when comments are edited."""
    import hashlib

    with open(path, encoding="utf-8") as f:
        code = _COMMENTS.sub(" ", f.read())
    return hashlib.sha256("".join(code.split()).encode("utf-8")).hexdigest()[:16]


def flattened_shader(name: str = SURFACE_SHADER) -> str:
    """The include-flattened text of the shipped shader ``name`` (loom_cloth_*.osl)."""
    d = osl_dir()
    if d is None or not os.path.isfile(os.path.join(d, name)):
        raise FileNotFoundError(f"{name} is not shipped with this add-on")
    return flatten(os.path.join(d, name))


def flattened_surface_shader() -> str:
    return flattened_shader(SURFACE_SHADER)
