"""The add-on builds into a zip, installs from it as a Blender extension, and registers and
unregisters cleanly (twice), leaving nothing behind.

    blender -b --factory-startup --python-exit-code 1 --python tests/blender/test_addon.py \
        [-- --out DIR]
"""

import importlib.util
import os
import sys
import tempfile
import zipfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import loom_testlib as lt  # noqa: E402

import addon_utils  # noqa: E402
import bpy  # noqa: E402

REPO_MODULE = "loom_ziptest"
MODULE = f"bl_ext.{REPO_MODULE}.loom"
CLASSES = ("LOOM_OT_bake_assign", "LOOM_OT_bake_cancel", "LOOM_OT_assign_atlas",
           "LOOM_OT_material_new", "LOOM_OT_scene_needs", "MATERIAL_PT_loom")
WM_PROPS = ("loom_bake_running", "loom_bake_cancel", "loom_bake_progress", "loom_bake_status")


def build_zip(out_dir):
    spec = importlib.util.spec_from_file_location("loom_build_zip",
                                                  os.path.join(lt.REPO, "addon", "build_zip.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    path = mod.build(os.path.join(out_dir, "loom.zip"))
    names = zipfile.ZipFile(path).namelist()
    for required in ("blender_manifest.toml", "__init__.py", "api.py",
                     "osl/loom_cloth_surface.osl", "osl/include/loom/closure_mapping.h"):
        assert required in names, f"{required} missing from the zip"
    assert not any("__pycache__" in n or n.endswith(".pyc") for n in names), names
    return path


def check_registered():
    for name in CLASSES:
        assert hasattr(bpy.types, name), f"{name} not registered"
    assert hasattr(bpy.types.Material, "loom"), "Material.loom missing"
    for p in WM_PROPS:
        assert hasattr(bpy.types.WindowManager, p), f"WindowManager.{p} missing"
    assert MODULE in bpy.context.preferences.addons, "preferences entry missing"
    prefs = bpy.context.preferences.addons[MODULE].preferences
    assert prefs.cache_dir.endswith(os.path.join("loom", "atlases")), prefs.cache_dir
    import loom.api  # the alias made at register time

    assert loom.api.__name__ == MODULE + ".api", loom.api.__name__
    assert callable(loom.api.bake) and callable(loom.api.assign)
    mat = bpy.data.materials.new("probe")
    assert mat.loom.quality == "preview" and mat.loom.mode == "AUTO"
    bpy.data.materials.remove(mat)
    assert _loom_handlers() == 3, "render_pre/load_post/save_post handlers missing"
    check_osl_paths()


def _loom_handlers():
    return sum(1 for name in ("render_pre", "load_post", "save_post")
               for fn in getattr(bpy.app.handlers, name)
               if getattr(fn, "__module__", "").endswith("osl_paths"))


def check_osl_paths():
    """A Script node's atlas path is stored '//'-relative and made absolute before rendering:
    moving the .blend with its atlas folder keeps the textures found. (A Script node exists in
    Blenders without OSL too; only its compiled inputs are missing, so add the string sockets a
    compiled loom_cloth_surface.osl would have.)"""
    import tempfile
    mod = sys.modules[MODULE + ".osl_paths"]
    assert mod.resolve("//atlas", "/a/b/scene.blend") == os.path.normpath("/a/b/atlas")
    assert mod.resolve("/abs/atlas", "/a/b/scene.blend") == "/abs/atlas"
    mat = bpy.data.materials.new("osl-probe")
    mat.use_nodes = True
    script = mat.node_tree.nodes.new("ShaderNodeScript")
    with tempfile.TemporaryDirectory() as d:
        script[mod.ATLAS_PROP] = "//moved.atlas"
        script[mod.FILES_PROP] = {"ply_frame": "ply_frame.tx"}
        inputs = getattr(script, "inputs")
        if "ply_frame" not in inputs:  # no OSL compiler here: no sockets were made
            try:
                inputs.new("NodeSocketString", "ply_frame")
            except (RuntimeError, AttributeError, TypeError):
                pass
        n = mod.refresh()
        assert n >= 1, "refresh did not see the Loom Script node"
        if "ply_frame" in inputs:
            got = inputs["ply_frame"].default_value
            want = os.path.join(mod.resolve("//moved.atlas", bpy.data.filepath), "ply_frame.tx")
            assert got == want, (got, want)
            assert os.path.isabs(got), got
            print(f"loom-test: Script node texture path resolved before render: {got}")
        else:
            print("loom-test: no string socket on a Script node here; checked resolve() only")
    bpy.data.materials.remove(mat)


def check_unregistered():
    for name in CLASSES:
        assert not hasattr(bpy.types, name), f"{name} still registered"
    assert not hasattr(bpy.types.Material, "loom"), "Material.loom left behind"
    for p in WM_PROPS:
        assert not hasattr(bpy.types.WindowManager, p), f"WindowManager.{p} left behind"
    assert "loom" not in sys.modules and "loom.api" not in sys.modules, "module aliases left"
    assert not hasattr(bpy.ops.loom, "bake_assign") or _op_missing("bake_assign")
    assert _loom_handlers() == 0, "handlers left behind after unregister"


def _op_missing(name):
    try:
        getattr(bpy.ops.loom, name).get_rna_type()
    except (KeyError, AttributeError):
        return True
    return False


def check_panel_draws():
    """Draw the material panel for an object without a Loom material and for a Loom one."""
    mesh = bpy.data.meshes.new("m")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    obj = bpy.data.objects.new("o", mesh)
    for mat in (None, bpy.data.materials.new("plain material")):
        log = lt.draw_material_panel(mat, obj)
        assert ("operator", "loom.material_new") in log, log
    mat["loom"] = {"managed": True}
    mat.loom.atlas_dir = "/nonexistent"
    mat.loom.mode_used = "OSL"  # as if built where OSL ran; the panel must warn here
    log = lt.draw_material_panel(mat, obj)
    for item in (("prop", "preset"), ("prop", "quality"), ("prop", "mode"),
                 ("operator", "loom.bake_assign")):
        assert item in log, (item, log)
    assert any(k == "label" and "UV map" in t for k, t in log), "no UV warning"
    import _cycles

    if not _cycles.with_osl:
        assert any(k == "label" and "OSL cannot run" in t for k, t in log), log
    bpy.data.materials.remove(mat)
    bpy.data.objects.remove(obj)
    print(f"loom-test: panel drew {len(log)} items")


def main():
    args = lt.parse_args()
    zpath = build_zip(args.out)
    print(f"loom-test: built {zpath}")

    # A throw-away local extension repository, so the user's own is untouched.
    repo_dir = tempfile.mkdtemp(prefix="loom-ext-zip-")
    bpy.context.preferences.extensions.repos.new(name=REPO_MODULE, module=REPO_MODULE,
                                                 custom_directory=repo_dir, source="USER")
    res = bpy.ops.extensions.package_install_files(filepath=zpath, repo=REPO_MODULE,
                                                   enable_on_install=True)
    assert res == {"FINISHED"}, f"package_install_files: {res}"
    assert os.path.isfile(os.path.join(repo_dir, "loom", "osl", "loom_cloth_surface.osl"))
    assert MODULE in bpy.context.preferences.addons, "not enabled after install"
    check_registered()
    check_panel_draws()

    for cycle in range(2):
        addon_utils.disable(MODULE, default_set=True)
        check_unregistered()
        errors = []
        addon_utils.enable(MODULE, default_set=True, handle_error=errors.append)
        assert not errors, f"re-enable {cycle}: {errors}"
        check_registered()
    addon_utils.disable(MODULE, default_set=True)
    check_unregistered()
    print("loom-test: installed from the zip, registered and unregistered 3 times")


lt.run(main)
