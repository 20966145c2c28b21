"""What an atlas holds, read and checked for the whole add-on: its maps and tables as the
shaders (``osl/loom_cloth_*.osl`` and node mode) read them, and why an atlas cannot be shaded
(``atlas_problem``: an unreadable manifest, missing maps, tables in another layout than this
add-on's shared headers, a tier Blender cannot shade). The layouts come from loom-bake's
headers (baker/include/loom/atlas_files.h, ply_tables.h, render_tables.h)."""

from __future__ import annotations

import json
import os

from . import osl_source

SURFACE_MAPS = ("ply_frame", "ply_normal", "yarn_info", "albedo_reflect", "albedo_transmit",
                "spec_params", "horizon_0", "horizon_1")
SURFACE_LUT = "closure_lut"
# The per-texel fitted closures (fitted_closures.h), in atlases baked with model.closures
# "fitted": where present, both shaders render them instead of the per-sample mapping.
FITTED_TEXTURE = "fitted_closures"
HORIZON_STRIP = "horizon_strip"  # their V(V) in one read (fitted_closures.h)
# The repeat-averaged closures both tiers read far away (average_closures.h; the manifest's
# "average" section names it).
AVERAGE_TEXTURE = "average_closures"
RAYWAVE_MAPS = ("ply_frame", "ply_normal", "yarn_info", "horizon_0", "horizon_1")
# The lobe tables' layout the ray-wave shaders read: the manifest's
# raywave.yarns.<yarn>.node_layout, as loom-bake writes it (ply_tables.h: kAsgNodeLayout).
NODE_LAYOUT = "lobe-major/node-scales"
# The double-layer factors they read: raywave.shading.factors_layout (render_tables.h:
# kLayerFactorsLayout; double_layer_factors.h).
FACTORS_LAYOUT = "k_b,k_f"
# The headers' constants the ray-wave checks read.
RAYWAVE_CHECKED_CONSTANTS = ("LOOM_MICROFACET_ALBEDO_SIZE", "LOOM_ASG_INTEGRAL_LUT_SIZE",
                             "LOOM_RAYWAVE_PARTS", "LOOM_DOUBLE_LAYER_BLOCKS",
                             "LOOM_DIFFRACTION_ICDF_SIZE", "LOOM_NOISE_LEVELS")


def repeat_aspect(manifest) -> float:
    """Lx / Ly of the weave repeat (manifest repeat.size_um): the shader's Aspect."""
    try:
        lx, ly = (float(v) for v in manifest["repeat"]["size_um"])
        return lx / ly if lx > 0 and ly > 0 else 1.0
    except (KeyError, TypeError, ValueError):
        return 1.0


def tier_problem(tier: str, what: str = "atlas") -> str:
    """Why an atlas (or spec) of a model tier other than the surface one cannot be shaded here
    (yet)."""
    return (f"a \"{tier}\" {what}: Loom cannot shade the {tier} tier in Blender yet "
            f"(bake the spec with \"model\": {{\"tier\": \"surface\"}})")


def atlas_problem(atlas_dir: str) -> str | None:
    """None if the shaders (OSL and node mode) can read this atlas, else why not (an unreadable
    manifest, missing maps, tables in another layout than the shared headers', another tier)."""
    try:
        with open(os.path.join(atlas_dir, "manifest.json"), encoding="utf-8") as f:
            manifest = json.load(f)
        textures = manifest["textures"]
    except (OSError, ValueError, KeyError) as exc:
        return f"unreadable manifest: {exc}"
    tier = manifest.get("tier", "surface")
    if tier not in ("surface", "raywave"):
        return tier_problem(tier)
    problem = average_problem(manifest)
    if problem:
        return problem
    if tier == "raywave":
        return raywave_problem(manifest)
    missing = [m for m in (*SURFACE_MAPS, SURFACE_LUT) if m not in textures]
    if missing:
        return f"maps missing: {', '.join(missing)}"
    K = osl_source.required_constants(("LOOM_CLOSURE_LUT_SIZE", "LOOM_LUT_PANELS",
                                       "LOOM_LUT_SLICES"))
    n = int(K["LOOM_CLOSURE_LUT_SIZE"])
    want = [int(K["LOOM_LUT_PANELS"]) * n, 2 * n * int(K["LOOM_LUT_SLICES"])]
    got = list(textures[SURFACE_LUT].get("size", []))
    if got != want:
        return f"closure LUT is {got}, the shaders expect {want}"
    return fitted_problem(textures)


def fitted_problem(textures: dict) -> str | None:
    """None if the atlas has no per-texel fitted closures or has them in the layout
    fitted_closures.h reads (LOOM_FITTED_TILES tiles of the maps' width plus two), else why
    not."""
    if FITTED_TEXTURE not in textures:
        return None
    K = osl_source.required_constants(("LOOM_FITTED_TILES", "LOOM_HORIZON_DIRS"))
    try:
        w, h = (int(v) for v in textures["ply_frame"]["size"])
        got = [int(v) for v in textures[FITTED_TEXTURE]["size"]]
    except (KeyError, TypeError, ValueError):
        return "fitted closures or ply_frame without a size"
    want = [int(K["LOOM_FITTED_TILES"]) * (w + 2), h]
    if got != want:
        return f"fitted closures are {got}, the shaders expect {want}: re-bake the atlas"
    want = [int(K["LOOM_HORIZON_DIRS"]) * (w + 2), h]
    got = list(textures.get(HORIZON_STRIP, {}).get("size", []))
    if got != want:
        return f"the horizon strip is {got or 'missing'}, the shaders expect {want}: re-bake the atlas"
    return None


def average_problem(manifest: dict) -> str | None:
    """None if the atlas holds the repeat-averaged closures in the layout average_closures.h
    reads, else why not."""
    avg = manifest.get("average")
    tex = manifest.get("textures", {}).get(AVERAGE_TEXTURE)
    if not isinstance(avg, dict) or tex is None:
        return ("no repeat-averaged closures (the manifest's \"average\"; an atlas of an "
                "older loom-bake): re-bake the atlas with this version of loom-bake")
    K = osl_source.required_constants(("LOOM_AVERAGE_THETA", "LOOM_AVERAGE_PHI",
                                       "LOOM_AVERAGE_PANELS"))
    want = [int(K["LOOM_AVERAGE_PHI"]) + 1,
            2 * int(K["LOOM_AVERAGE_PANELS"]) * int(K["LOOM_AVERAGE_THETA"])]
    got = list(tex.get("size", []))
    if got != want:
        return f"averaged closures are {got}, the shaders expect {want}: re-bake the atlas"
    gap = avg.get("gap_mean")
    if not isinstance(gap, (int, float)) or not 0.0 <= gap < 1.0:
        return f"average.gap_mean is {gap!r}, expected a number in [0, 1)"
    return None


def average_gap_mean(manifest: dict) -> float:
    """The repeat's mean open fraction (average_closures_yarn_scale's gap_mean)."""
    return float(manifest["average"]["gap_mean"])


def average_osl_parameters(manifest: dict) -> tuple[dict, dict]:
    """(texture parameters -> atlas texture names, other parameters -> values) of the averaged
    closures in both tiers' OSL shaders."""
    return ({"average_closures_table": AVERAGE_TEXTURE},
            {"average_gap_mean": average_gap_mean(manifest)})


# ======================================================================= ray-wave atlases


def raywave_grid(manifest: dict) -> dict:
    """The lobe grids of a ray-wave atlas, which the OSL shader takes once for all tables: raise
    ValueError naming what differs when the yarns' or the components' grids are not one."""
    rw = manifest["raywave"]
    grids = []
    for y in ("warp", "weft"):
        for part in ("high", "refl"):
            g = rw["yarns"][y][part]
            grids.append(((g["theta_i"]["count"], g["theta_i"]["min"], g["theta_i"]["max"]),
                          (g["h"]["count"], g["h"]["min"], g["h"]["max"])))
    if any(g != grids[0] for g in grids):
        raise ValueError("the yarns' lobe tables use different (theta_i, h) grids; the ray-wave "
                         "shaders take one grid (not yet supported: bake both yarns at one "
                         "quality)")
    (m, th_lo, th_hi), (n, h_lo, h_hi) = grids[0]
    if (float(h_lo), float(h_hi)) != (-1.0, 1.0):
        raise ValueError(f"the lobe tables' h range is [{h_lo}, {h_hi}]; the ray-wave shaders "
                         f"take h in [-1, 1]")
    lobes = {part: {rw["yarns"][y][part]["lobes"] for y in ("warp", "weft")}
             for part in ("high", "refl")}
    if any(len(v) != 1 for v in lobes.values()):
        raise ValueError("the yarns' lobe tables have different lobe counts; the ray-wave shaders "
                         "take one count per component")
    dl = rw["double_layer"]
    return {"m": int(m), "n": int(n), "theta_min": float(th_lo), "theta_max": float(th_hi),
            "h_min": float(h_lo), "h_max": float(h_hi),
            "high_lobes": int(next(iter(lobes["high"]))),
            "refl_lobes": int(next(iter(lobes["refl"]))),
            "layer_theta_count": int(dl["theta_count"]), "layer_phi_count": int(dl["phi_count"]),
            "blend": float(dl.get("blend", 0.5))}


def raywave_diffraction(manifest: dict) -> dict | None:
    """The gap diffraction the shaders sample (diffraction_sampling.h), or None for delta
    transmission (no gap table: the non-wave variant, or yarns that touch). Raises KeyError when
    a gap table comes without its sampling table (an older loom-bake)."""
    dif = manifest["raywave"].get("diffraction", {})
    files = dif.get("files", {})
    if dif.get("mode") != "tables" or "gap" not in files:
        return None
    n = int(dif["gap_offsets"])
    return {"file": files["gap_sampling"], "tiles_x": n, "tiles_y": n,
            "size": int(dif["tile_size"]), "gap_fraction": [float(g) for g in dif["gap_fraction"]],
            "weft_yarns": int(manifest["repeat"]["weft_yarns"]),
            "warp_yarns": int(manifest["repeat"]["warp_yarns"])}


def raywave_noise(manifest: dict) -> dict | None:
    """The speckle noise tiles (speckle_noise.h), or None (wave.noise off). Raises KeyError when
    the tiles come without their blur levels (an older loom-bake)."""
    nz = manifest["raywave"].get("noise", {})
    files = nz.get("files", {})
    if "refl" not in files:
        return None
    return {"refl": files["refl"], "high": files["high"], "instances": int(nz["instances"]),
            "theta_count": int(nz["theta_count"]), "levels": int(nz["levels"])}


def raywave_problem(manifest: dict) -> str | None:
    """None if node mode (and the OSL shader) can read this ray-wave atlas, else why not."""
    try:
        rw = manifest["raywave"]
        textures = manifest["textures"]
        for y in ("warp", "weft"):
            if rw["yarns"][y].get("node_layout") != NODE_LAYOUT:
                return (f"its lobe tables are not in the {NODE_LAYOUT!r} layout this add-on reads "
                        f"(they are {rw['yarns'][y].get('node_layout')!r}): re-bake the atlas with "
                        f"this version of loom-bake")
        got = rw["shading"].get("factors_layout")
        if got != FACTORS_LAYOUT:
            return (f"raywave.shading.factors_layout is "
                    f"{'missing' if got is None else repr(got)}, not the {FACTORS_LAYOUT!r} this "
                    f"add-on reads (double-layer factors of an older loom-bake): re-bake the "
                    f"atlas with this version of loom-bake")
        raywave_grid(manifest)
        needed = set(RAYWAVE_MAPS) | {rw["shading"]["microfacet_albedo"], rw["shading"]["asg_integral"],
                              *rw["shading"]["factors"].values()}
        for y in ("warp", "weft"):
            files = rw["yarns"][y]["files"]
            needed |= {files["high"], files["refl"], files["tint"], files["residual"]}
        dif = raywave_diffraction(manifest)
        if dif:
            needed.add(dif["file"])
        nz = raywave_noise(manifest)
        if nz:
            needed |= {nz["refl"], nz["high"]}
    except (KeyError, TypeError) as exc:
        return (f"not a ray-wave atlas with render tables (manifest lacks {exc}): re-bake it "
                f"with this version of loom-bake")
    except ValueError as exc:
        return str(exc)
    missing = sorted(m for m in needed if m not in textures)
    if missing:
        return f"maps missing: {', '.join(missing)}"
    K = osl_source.required_constants(RAYWAVE_CHECKED_CONSTANTS)
    n = int(K["LOOM_MICROFACET_ALBEDO_SIZE"])
    got = list(textures[rw["shading"]["microfacet_albedo"]].get("size", []))
    if got != [n, n]:
        return f"microfacet albedo LUT is {got}, the shaders expect {[n, n]}"
    n = int(K["LOOM_ASG_INTEGRAL_LUT_SIZE"])
    got = list(textures[rw["shading"]["asg_integral"]].get("size", []))
    if got != [n, n]:
        return f"ASG integral LUT is {got}, the shaders expect {[n, n]}: re-bake the atlas"
    # The tables' sizes against the grids (raywave_lobes.h: asg_node_uv, asg_tint_uv).
    g = raywave_grid(manifest)
    rows, cols = g["m"] // 2 + 1, g["n"] // 2 + 1
    parts = int(K["LOOM_RAYWAVE_PARTS"])
    for y in ("warp", "weft"):
        files = rw["yarns"][y]["files"]
        want = {files["high"]: [parts * g["high_lobes"] * cols, rows],
                files["refl"]: [parts * g["refl_lobes"] * cols, rows],
                files["tint"]: [g["high_lobes"] * cols, rows],
                files["residual"]: [2 * g["n"], g["m"]]}
        for name, size in want.items():
            got = list(textures[name].get("size", []))
            if got != size:
                return f"{name} is {got}, the grids say {size}: re-bake the atlas"
    # The double-layer factors (double_layer_factors.h: double_layer_uv).
    want = [int(K["LOOM_DOUBLE_LAYER_BLOCKS"]) * (g["layer_phi_count"] + 2),
            g["layer_theta_count"]]
    for name in rw["shading"]["factors"].values():
        got = list(textures[name].get("size", []))
        if got != want:
            return f"{name} is {got}, the double-layer grids say {want}: re-bake the atlas"
    dif = raywave_diffraction(manifest)
    if dif:
        want = [int(K["LOOM_DIFFRACTION_ICDF_SIZE"]) * dif["tiles_x"],
                (dif["size"] + 1) * dif["tiles_y"]]
        got = list(textures[dif["file"]].get("size", []))
        if got != want:
            return f"{dif['file']} is {got}, the diffraction tables say {want}: re-bake the atlas"
    nz = raywave_noise(manifest)
    if nz:
        if nz["levels"] != int(K["LOOM_NOISE_LEVELS"]):
            return (f"its noise tiles have {nz['levels']} blur levels, the shaders read "
                    f"{int(K['LOOM_NOISE_LEVELS'])}: re-bake the atlas")
        want = [2 * nz["theta_count"], nz["theta_count"] * nz["instances"] * nz["levels"]]
        for name in (nz["refl"], nz["high"]):
            got = list(textures[name].get("size", []))
            if got != want:
                return f"{name} is {got}, the noise settings say {want}: re-bake the atlas"
    return None


def raywave_osl_parameters(manifest: dict) -> tuple[dict, dict]:
    """(texture parameters -> atlas texture names, other parameters -> values) of
    loom_cloth_raywave.osl for this atlas."""
    rw = manifest["raywave"]
    g = raywave_grid(manifest)
    tex = {m: m for m in RAYWAVE_MAPS}
    for y in ("warp", "weft"):
        files = rw["yarns"][y]["files"]
        tex[f"high_{y}"] = files["high"]
        tex[f"refl_{y}"] = files["refl"]
        tex[f"tint_{y}"] = files["tint"]
        tex[f"residual_{y}"] = files["residual"]
    tex["factors_front"] = rw["shading"]["factors"]["front"]
    tex["factors_back"] = rw["shading"]["factors"]["back"]
    tex["microfacet_albedo"] = rw["shading"]["microfacet_albedo"]
    tex["asg_integral_lut"] = rw["shading"]["asg_integral"]
    values = {"high_lobes": g["high_lobes"], "refl_lobes": g["refl_lobes"],
              "theta_count": g["m"], "h_count": g["n"], "theta_min": g["theta_min"],
              "theta_max": g["theta_max"], "layer_theta_count": g["layer_theta_count"],
              "layer_phi_count": g["layer_phi_count"], "double_layer_blend": g["blend"]}
    nz = raywave_noise(manifest)
    if nz:  # (without: the shader's defaults, empty names, give no noise)
        tex["noise_refl"], tex["noise_high"] = nz["refl"], nz["high"]
        values["noise_instances"] = nz["instances"]
    avg_tex, avg_values = average_osl_parameters(manifest)
    tex.update(avg_tex)
    values.update(avg_values)
    dif = raywave_diffraction(manifest)
    if dif:  # (without: the shader's defaults, diffraction_tiles_x = 0, give delta transmission)
        tex["diffraction_gap_sampling"] = dif["file"]
        values.update({"diffraction_tiles_x": dif["tiles_x"], "diffraction_tiles_y": dif["tiles_y"],
                       "diffraction_size": dif["size"], "weft_yarns": dif["weft_yarns"],
                       "warp_yarns": dif["warp_yarns"], "gap_fraction_x": dif["gap_fraction"][0],
                       "gap_fraction_y": dif["gap_fraction"][1]})
    return tex, values
