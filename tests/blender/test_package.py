"""The installed extension package (issue 34): Blender's own installer put it among the user's
extensions (tests/blender/package_inside.sh); enabled from there, with no $LOOM_BAKE, no
preference and no loom-bake on PATH, it finds the loom-bake it carries, bakes a preset and
renders it (finite, not black) in node mode.

    blender -b --factory-startup --python-exit-code 1 --python tests/blender/test_package.py \
        -- --out DIR
"""

import importlib
import os
import shutil
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import loom_testlib as lt  # noqa: E402

import addon_utils  # noqa: E402
import bpy  # noqa: E402

MODULE = "bl_ext.user_default.loom"


def main():
    args = lt.parse_args()
    assert "LOOM_BAKE" not in os.environ, "the test must run without $LOOM_BAKE"
    assert shutil.which("loom-bake") is None, f"a loom-bake on PATH: {shutil.which('loom-bake')}"
    errors = []
    mod = addon_utils.enable(MODULE, default_set=True, handle_error=lambda e: errors.append(e))
    assert mod is not None and not errors, f"enabling the installed {MODULE} failed: {errors}"
    installed = os.path.dirname(os.path.abspath(mod.__file__))
    assert installed.startswith(os.path.abspath(bpy.utils.user_resource("EXTENSIONS"))), installed
    api = importlib.import_module(MODULE + ".api")
    exe = api.find_loom_bake()
    assert exe == os.path.join(installed, "bin", "loom-bake"), f"found {exe}, not the package's"

    atlas = api.bake("plain", quality="draft", cache_dir=os.path.join(args.out, "cache"))
    scene = lt.empty_scene()
    cloth = lt.add_plane("Cloth", half=0.05)
    api.assign(cloth, atlas, mode="nodes")
    lt.top_view(scene, 0.1, height=1.0, sun_direction=(0.3, 0.2, -1.0))
    scene.render.resolution_x = scene.render.resolution_y = 32
    scene.cycles.samples = 4
    img = lt.render_to_exr(scene, os.path.join(args.out, "package.exr"))
    mean = img.rgb_mean()
    print(f"loom-test package: {exe}, atlas {atlas}, mean {mean:.4f}")
    assert img.finite(), "non-finite pixels"
    assert mean > 0.01, f"the cloth rendered black ({mean})"


lt.run(main)
