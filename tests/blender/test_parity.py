"""Parity: node mode in Cycles against loom-bake's closure emulator.

A flat swatch (z = 0, UV = world xy) filled with many weave repeats is seen by an orthographic
camera from direction wo and lit by one sun from direction wi (both in the tangent frame, which
here is the world frame: x = warp = u, y = weft = v, z = normal). Direct light only (no bounces,
black world), so every pixel is radiance L = f(wi, wo) E |cos theta_i| averaged over the pixel's
footprint. With the atlas maps read texel by texel (Image Texture interpolation 'Closest') and
many repeats in view, the image mean is the mean of f over the texels of one repeat, which is what
``loom-bake eval bsdf --average --evaluator closures`` computes with Cycles' own formulas in C++.

Units are checked in the same run with a white Diffuse BSDF swatch: L = E cos theta_i / pi.

Run (inside Blender):
    blender -b --factory-startup --python-exit-code 1 --python tests/blender/test_parity.py -- \
        --loom-bake LOOM_BAKE --atlas ATLAS [--samples 16] [--res 64] [--tolerance 0.03] \
        [--nonfinite]
LOOM_BAKE must run where Blender runs (inside the chroot: a host-exec wrapper). Without
--atlas, the plain preset is baked into --out through loom.api.bake.
"""

import json
import math
import os
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import loom_testlib as lt  # noqa: E402

import bpy  # noqa: E402

# (wi towards the light, wo towards the viewer), tangent frame. Chosen to cover: normal
# incidence, off-specular, mirror configurations in the warp and the weft planes (the glossy
# lobe), a generic azimuth, grazing light, light from behind (translucency), and the cloth seen
# from below (back faces: Cycles flips the normal, the model mirrors z), lit from below and
# from above.
PAIRS = [
    ((0.0, 0.0, 1.0), (0.0, 0.0, 1.0)),
    ((0.5, 0.0, 0.866), (0.0, 0.0, 1.0)),
    ((0.5, 0.0, 0.866), (-0.5, 0.0, 0.866)),
    ((0.0, 0.6, 0.8), (0.0, -0.6, 0.8)),
    ((0.3, 0.4, 0.866), (-0.6, 0.2, 0.775)),
    ((0.8, 0.0, 0.6), (0.0, 0.7, 0.714)),
    ((0.2, 0.1, -0.975), (0.0, 0.3, 0.954)),
    ((0.3, -0.2, -0.933), (-0.2, 0.4, -0.894)),
    ((0.1, 0.5, 0.86), (0.4, 0.0, -0.917)),
]
# With --diffraction (fabrics with open gaps): light from behind a little off straight through,
# in the arms of the gap diffraction's cross (direction sums s = wi.xy + wo.xy along x, along y,
# and seen off the normal; diffraction_sampling.h), where the sampled lobes carry the light.
DIFFRACTION_PAIRS = [
    ((0.06, 0.0, -0.9982), (0.0, 0.0, 1.0)),
    ((0.0, 0.07, -0.99755), (0.0, 0.0, 1.0)),
    ((-0.17, -0.1, -0.9804), (0.25, 0.1, 0.963)),
]
# The sampled diffraction lobes are noisy: on the organza, a standard error of the mean of about
# 3 % at 64 samples, 1.4 % at 256 and 0.7 % at 1024, so these pairs start at 1024 rather than
# reach it after two renders that cannot pass.
DIFFRACTION_SAMPLES = 1024
# At 1024 samples a pair costs about four minutes of one core (64 x 64 pixels, measured on
# the organza): the fast run keeps the third pair only (the x arm seen off the normal: the
# marginal and the conditional look-ups, the tiles, the view-dependent weight), and
# scripts/test.sh --full (LOOM_FULL=1) adds the first two (the x and the y arm seen along the
# normal). The y arm stays in the fast run through blender.raywave_render (node mode: both
# arms of the cross against its diagonals); the emulator these pairs compare with is checked
# against the model along and across an arm by DiffractionSampling.ClosuresMatchTheModelInTheArms.
DIFFRACTION_FULL_ONLY = {len(PAIRS), len(PAIRS) + 1}
# Node mode is compared with the emulator's node-mode backend (loom-bake eval --backend nodes):
# Cycles' SVM Translucent BSDF lifts its normal with ensure_valid_specular_reflection when the
# material's Bump Map Correction is on (kernel/svm/closure.h), OSL's translucent() does not; the
# emulator models both. (Ray-wave atlases have one mixture for both backends: on this flat swatch
# the shading normal is the geometric one, so nothing is lifted; loom-bake says "backend": "any".)
# With --nonfinite: Cycles and the C++ evaluators do not read a NaN or Inf texel as the same
# value (Blender 4.3's Cycles does not sanitise half images, and its SVM image textures turn a
# stored 0 into 2^-15, measured, and by the same conversion a NaN or Inf into a finite 65536 or
# more), so the texel guard brings them to different in-range values and no parity is expected.
# What must hold: every pixel finite and the mean radiance at most E cos(theta_i), a BSDF
# averaging 1/sr (pi times a white Lambertian: the tampered atlases render below 0.3 with the
# guard; node mode without it rendered up to 6e8 on the tampered plain atlas).
SUN = 3.0
REPEATS_PER_METER = 173.3  # irrational-ish: no aliasing with the pixel grid


def extra_args(p):
    # 16 samples of 64 x 64 pixels: a standard error of the mean below 1 % on the regular pairs
    # (0.5 % or less measured at 64 samples), so a 3 % bias still stands out by 3 standard errors
    # or more; a pair that misses is rendered again with more (below). LOOM_FULL=1
    # (scripts/test.sh --full): 64 from the start.
    p.add_argument("--samples", type=int, default=64 if os.environ.get("LOOM_FULL") else 16)
    p.add_argument("--res", type=int, default=64)
    p.add_argument("--tolerance", type=float, default=0.03)
    p.add_argument("--max-samples", type=int, default=1024,
                   help="re-render a pair that misses the tolerance with up to this many samples")
    p.add_argument("--interpolation", default="Closest", choices=["Closest", "Linear"])
    p.add_argument("--pairs", default="", help="comma-separated pair indices (default all)")
    p.add_argument("--json", default=None, help="write the measured numbers here")
    p.add_argument("--diffraction", action="store_true",
                   help="also the pairs in the gap diffraction's cross (DIFFRACTION_PAIRS)")
    p.add_argument("--average", action="store_true",
                   help="the material at Average 1 (the repeat-averaged closures, "
                        "average_closures.h) against `eval bsdf --evaluator average`; also "
                        "reports the render against the model averaged over the repeat")
    p.add_argument("--nonfinite", action="store_true",
                   help="the atlas holds NaN and +-Inf texels (tests/tools/tamper_atlas.cpp): "
                        "check finite, bounded renders instead of the parity (see the comment above SUN)")


def eval_bsdf(loom_bake, atlas, pairs, evaluator):
    """f averaged over the repeat for each (wi, wo) pair, from one loom-bake call (one JSON line
    per pair, in order)."""
    dirs = []
    for wi, wo in pairs:
        dirs += ["--wi", ",".join(f"{c:.6f}" for c in wi), "--wo", ",".join(f"{c:.6f}" for c in wo)]
    out = subprocess.run(
        [loom_bake, "eval", "bsdf", "--atlas", atlas, "--average", "--evaluator", evaluator,
         *(["--backend", "nodes"] if evaluator == "closures" else []), *dirs],
        capture_output=True, text=True, check=True).stdout
    rows = [json.loads(line)["f"] for line in out.splitlines() if line.strip()]
    assert len(rows) == len(pairs), f"loom-bake eval bsdf: {len(rows)} answers for {len(pairs)} pairs"
    return rows


def setup(args):
    """The swatch, an orthographic camera and a sun; point_at() turns them for each pair."""
    scene = lt.empty_scene()
    scene.cycles.samples = args.samples
    scene.cycles.max_bounces = 0  # direct light only
    scene.cycles.light_sampling_threshold = 0.0  # no stochastic shadow-ray termination
    scene.cycles.sample_clamp_direct = 0.0
    scene.render.resolution_x = scene.render.resolution_y = args.res
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False

    plane = lt.add_plane("Swatch", half=60.0, uv_per_meter=1.0)

    cam_data = bpy.data.cameras.new("Ortho")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 1.0
    cam_data.clip_end = 100.0
    cam = bpy.data.objects.new("Camera", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam

    sun_data = bpy.data.lights.new("Sun", type="SUN")
    sun_data.energy = SUN
    sun_data.angle = 0.0  # a delta light: no penumbra noise
    sun = bpy.data.objects.new("Sun", sun_data)
    scene.collection.objects.link(sun)
    return scene, plane


def point_at(scene, wi, wo):
    """The camera looks along -wo from 10 m away, the sun shines along -wi."""
    cam = scene.camera
    cam.location = tuple(10.0 * c for c in wo)
    lt.look_along(cam, tuple(-c for c in wo))
    lt.look_along(bpy.data.objects["Sun"], tuple(-c for c in wi))


def render_control(scene, plane, control, path):
    """The same view and light on the white Lambertian `control` material (the units check);
    the swatch's material is put back afterwards."""
    mat = plane.data.materials[0]
    plane.data.materials[0] = control
    try:
        return lt.render_to_exr(scene, path)
    finally:
        plane.data.materials[0] = mat


def main():
    args = lt.parse_args(extra_args)
    lt.enable_addon()
    import loom.api

    loom_bake = loom.api.find_loom_bake(args.loom_bake)
    assert loom_bake, "no loom-bake (--loom-bake or $LOOM_BAKE)"
    atlas = args.atlas or loom.api.bake("plain", "preview", loom_bake=loom_bake,
                                        cache_dir=os.path.join(args.out, "cache"))
    pairs = list(enumerate(PAIRS + (DIFFRACTION_PAIRS if args.diffraction else [])))
    if not os.environ.get("LOOM_FULL") and not args.pairs:
        pairs = [p for p in pairs if p[0] not in DIFFRACTION_FULL_ONLY]
    if args.pairs:
        keep = {int(i) for i in args.pairs.split(",")}
        pairs = [p for p in pairs if p[0] in keep]

    # One scene and one material for every pair (building a ray-wave group takes seconds).
    t0 = time.monotonic()
    scene, plane = setup(args)
    loom.api.assign(plane, atlas, mode="nodes", scale=REPEATS_PER_METER,
                    interpolation=args.interpolation, average=1.0 if args.average else 0.0)
    assert loom.api.last_assign()["mode"] == "NODES"
    # Node mode computes each quantity once (nodes_expr.op_node): no node repeats another's work.
    repeats = lt.repeated_operations(plane.active_material.node_tree)
    assert not repeats, f"{len(repeats)} nodes repeat another's operation: {repeats[:5]}"
    control = lt.diffuse_material()
    print(f"loom-parity: scene and material built in {time.monotonic() - t0:.1f} s", flush=True)

    pairs = [(idx, lt.unit(wi), lt.unit(wo)) for idx, (wi, wo) in pairs]
    if not args.nonfinite:
        dirs = [(wi, wo) for _, wi, wo in pairs]
        f_closures = eval_bsdf(loom_bake, atlas, dirs, "average" if args.average else "closures")
        f_model = eval_bsdf(loom_bake, atlas, dirs, "model")
    rows, failures = [], []
    for n, (idx, wi, wo) in enumerate(pairs):
        cos_i = abs(wi[2])
        point_at(scene, wi, wo)
        if args.nonfinite:
            img = lt.render_to_exr(scene, os.path.join(args.out, f"nonfinite_{idx}.exr"))
            got = [img.channel_mean(c) for c in range(3)]
            bound = SUN * cos_i
            print(f"loom-parity pair {idx} (non-finite texels): render RGB {got[0]:.5f} "
                  f"{got[1]:.5f} {got[2]:.5f}, finite {img.finite()}, bound {bound:.3f}",
                  flush=True)
            if not img.finite():
                failures.append(f"pair {idx}: non-finite pixels")
            elif not all(0.0 <= g <= bound for g in got):
                failures.append(f"pair {idx}: mean radiance {got} outside [0, E cos = {bound}]")
            rows.append(dict(pair=idx, wi=wi, wo=wo, render=got, bound=bound))
            continue
        f_c, f_m = f_closures[n], f_model[n]
        expect = [c * SUN * cos_i for c in f_c]
        # A mean over texels read 'Closest' is spiky where narrow lobes meet few texels. A render
        # is accepted only when every channel is within the tolerance by two standard errors of
        # its mean (so fewer samples cannot hide a bias that more would show); otherwise the
        # pair is rendered again with 4x the samples, and the last render allowed by
        # --max-samples is judged on the tolerance alone, as a bias does not shrink with samples.
        samples = args.samples if idx < len(PAIRS) else max(args.samples, DIFFRACTION_SAMPLES)
        while True:
            scene.cycles.samples = samples
            t0 = time.monotonic()
            img = lt.render_to_exr(scene, os.path.join(args.out, f"parity_{idx}.exr"))
            dt = time.monotonic() - t0
            assert img.finite(), "non-finite pixels"
            got = [img.channel_mean(c) for c in range(3)]
            rel = [abs(g - e) / max(abs(e), 1e-6) for g, e in zip(got, expect)]
            lit = [c for c in range(3) if expect[c] > 1e-4]
            worst = max((rel[c] for c in lit), default=0.0)
            stderr = [img.channel_stderr(c) / max(abs(expect[c]), 1e-6) for c in range(3)]
            worst_bound = max((rel[c] + 2.0 * stderr[c] for c in lit), default=0.0)
            if worst_bound <= args.tolerance or samples * 4 > args.max_samples:
                break
            print(f"loom-parity pair {idx}: {100 * worst:.2f}% at {samples} samples, "
                  f"{100 * worst_bound:.2f}% with two standard errors of the mean: rendering "
                  f"again with {samples * 4}", flush=True)
            samples *= 4

        # Units: the same view and light on a white Lambertian swatch.
        ctrl = render_control(scene, plane, control,
                              os.path.join(args.out, f"control_{idx}.exr"))
        ctrl_got = ctrl.rgb_mean()
        # One-sided Lambertian about the normal Cycles turns towards the viewer.
        ctrl_expect = SUN * cos_i / math.pi if wi[2] * wo[2] > 0 else 0.0

        mean_got, mean_exp = sum(got) / 3, sum(expect) / 3
        rel_mean = abs(mean_got - mean_exp) / max(mean_exp, 1e-6)
        row = dict(pair=idx, wi=wi, wo=wo, render=got, closures=expect,
                   model=[c * SUN * cos_i for c in f_m], rel=rel, stderr=stderr, rel_mean=rel_mean,
                   control=ctrl_got, control_expect=ctrl_expect, seconds=dt, samples=samples)
        rows.append(row)
        print(f"loom-parity pair {idx}: wi={tuple(round(c, 3) for c in wi)} "
              f"wo={tuple(round(c, 3) for c in wo)}  render RGB "
              f"{got[0]:.5f} {got[1]:.5f} {got[2]:.5f}  closures {expect[0]:.5f} "
              f"{expect[1]:.5f} {expect[2]:.5f}  model-mean {sum(row['model']) / 3:.5f}  "
              f"rel.err {max(rel):.4f} (mean {rel_mean:.4f})  control {ctrl_got:.5f} vs "
              f"{ctrl_expect:.5f}  [{samples} samples, {dt:.1f} s]", flush=True)
        if ctrl_expect > 0 and abs(ctrl_got - ctrl_expect) > 0.01 * ctrl_expect:
            failures.append(f"pair {idx}: diffuse control {ctrl_got:.5f} != E cos/pi "
                            f"{ctrl_expect:.5f} (units or colour management)")
        # Every channel within the tolerance (the darkest channels included).
        if worst > args.tolerance:
            failures.append(f"pair {idx}: render {got} vs closures {expect} "
                            f"({100 * worst:.2f}% > {100 * args.tolerance:.0f}% in a channel)")
    if args.average:
        # What the averaged closures lose against the model averaged over the repeat (reported;
        # `loom-bake eval average` measures it over the sphere).
        lit = [r for r in rows if sum(r["model"]) / 3 > 1e-4]
        rel_model = [abs(sum(r["render"]) - sum(r["model"])) / sum(r["model"]) for r in lit]
        print(f"loom-parity average: render against the model averaged over the repeat, mean "
              f"relative error {sum(rel_model) / max(len(rel_model), 1):.4f} over {len(lit)} "
              f"pairs (worst {max(rel_model, default=0.0):.4f})", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    compared = sum(1 for r in rows if max(r.get("closures", r["render"])) > 1e-4)
    assert compared >= 5 or args.pairs, (f"only {compared} pairs bright enough to compare "
                                         f"(closures > 1e-4)")
    assert not failures, "; ".join(failures)


lt.run(main)
