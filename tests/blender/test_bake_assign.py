"""Bake & assign through the add-on: loom.api.bake (loom-bake as a subprocess, cached), the
Bake & Assign operator's blocking path, error reporting, cancellation, and node mode, with no
Script node anywhere when this Blender has no OSL.

    blender -b --factory-startup --python-exit-code 1 --python tests/blender/test_bake_assign.py \
        -- --loom-bake LOOM_BAKE [--out DIR]

LOOM_BAKE must run where Blender runs: for the Debian chroot of scripts/blender.sh, a wrapper
made with `scripts/blender.sh host-exec-wrapper HOST_LOOM_BAKE WRAPPER`.
"""

import json
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import loom_testlib as lt  # noqa: E402

import bpy  # noqa: E402


def script_nodes():
    trees = [m.node_tree for m in bpy.data.materials if m.node_tree]
    trees += list(bpy.data.node_groups)
    return [n for t in trees for n in t.nodes if n.bl_idname == "ShaderNodeScript"]


class FakeOp:
    """Stands in for an operator instance, so that the modal Bake & Assign operator's invoke /
    modal / cancel code can be driven without a window (blender -b has none): the operator
    class's own functions are bound to this object."""

    def __init__(self, cls):
        self._cls = cls
        self.reports = []
        for name, prop in getattr(cls, "__annotations__", {}).items():  # the properties' defaults
            setattr(self, name, getattr(prop, "keywords", {}).get("default"))

    def report(self, level, message):
        self.reports.append((set(level), message))

    def __getattr__(self, name):
        return getattr(self._cls, name).__get__(self)


class FakeWM:
    """The window-manager calls the modal operator makes, recorded."""

    def __init__(self):
        self.loom_bake_running = self.loom_bake_cancel = False
        self.loom_bake_progress, self.loom_bake_status = 0.0, ""
        self.windows, self.calls, self.progress = [], [], []

    def event_timer_add(self, step, window=None):
        self.calls.append("timer_add")
        return object()

    def event_timer_remove(self, timer):
        self.calls.append("timer_remove")

    def modal_handler_add(self, op):
        self.calls.append("modal_handler_add")

    def progress_begin(self, a, b):
        self.calls.append("progress_begin")

    def progress_update(self, v):
        self.progress.append(v)

    def progress_end(self):
        self.calls.append("progress_end")


class FakeWorkspace:
    def __init__(self):
        self.status = []

    def status_text_set(self, text):
        self.status.append(text)


def drive_modal(obj, mat, esc_after=None, timeout=120.0, op_cls=None):
    """invoke, then TIMER events (and an Esc after ``esc_after`` s) until the operator ends."""
    from types import SimpleNamespace

    op_cls = op_cls or bpy.types.LOOM_OT_bake_assign
    wm, ws = FakeWM(), FakeWorkspace()
    ctx = SimpleNamespace(window=object(), window_manager=wm, workspace=ws, material=mat,
                          object=obj, scene=bpy.context.scene,
                          preferences=bpy.context.preferences)
    op = FakeOp(op_cls)
    res = op.invoke(ctx, SimpleNamespace(type="NONE", value="NOTHING"))
    assert res == {"RUNNING_MODAL"}, (res, op.reports)
    assert wm.loom_bake_running and "modal_handler_add" in wm.calls
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        time.sleep(0.1)
        if esc_after is not None and time.monotonic() - t0 > esc_after:
            res = op.modal(ctx, SimpleNamespace(type="ESC", value="PRESS"))
        else:
            res = op.modal(ctx, SimpleNamespace(type="TIMER", value="NOTHING"))
        # Other events pass through: the UI stays usable during a bake.
        assert op.modal(ctx, SimpleNamespace(type="MOUSEMOVE", value="NOTHING")) in (
            {"PASS_THROUGH"}, {"FINISHED"}, {"CANCELLED"})
        if res != {"PASS_THROUGH"}:
            break
    assert not wm.loom_bake_running, "loom_bake_running left set"
    assert "timer_remove" in wm.calls and "progress_end" in wm.calls, wm.calls
    assert ws.status and ws.status[-1] is None, "status text not cleared"
    return res, op, wm


def check_scene_model(plane, mat):
    """Bake & Assign with Model "By Scene" in three scenes (see the caller)."""
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 960, 540
    scene.render.resolution_percentage = 100
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))  # 50 mm, 36 mm sensor
    scene.collection.objects.link(cam)
    scene.camera = cam
    lt.look_along(cam, (0.0, 0.0, -1.0))
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", type="SUN"))
    scene.collection.objects.link(sun)
    mat.loom.preset = "white_silk_organza"
    mat.loom.quality = "draft"
    mat.loom.model = "SCENE"
    mat.loom.scale_mode = "PHYSICAL"
    cases = (("far", 2.0, (0.0, 0.0, -1.0)), ("close, lit from behind", 0.02, (0.0, 0.0, 1.0)),
             ("close, lit from the front", 0.02, (0.3, 0.0, -0.95)))
    for what, dist, light_dir in cases:
        cam.location = (0.0, 0.0, dist)
        lt.look_along(sun, light_dir)  # the direction the light travels
        with bpy.context.temp_override(object=plane, material=mat):
            res = bpy.ops.loom.bake_assign()
        assert res == {"FINISHED"}, (what, res)
        with open(os.path.join(mat.loom.atlas_dir, "manifest.json"), encoding="utf-8") as f:
            m = json.load(f)
        report = mat.loom.needs_report
        print(f"loom-test: By Scene, {what}: {m['tier']} atlas; " + report.replace("\n", "; "))
        if what == "far":
            assert m["tier"] == "surface", (what, m["tier"], report)
            assert "surface tier" in report, report
            continue
        assert m["tier"] == "raywave", (what, m["tier"], report)
        rw = m["raywave"]
        assert rw["yarns"]["warp"]["simulation"]["includes_multi_ply"], "3-ply yarns: multi-ply"
        behind = "behind" in what
        assert (rw["diffraction"]["mode"] == "tables") == behind, (what, rw["diffraction"])
        assert (rw["double_layer"]["mode"] == "tables") == behind, (what, rw["double_layer"])
        assert m["spec"]["components"]["double_layer"] == behind
        groups = [n.node_tree for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeGroup"]
        assert len(groups) == 1 and groups[0].get("loom_tier") == "raywave", groups
    # As Specified: the preset's own tier and components, whatever the camera.
    mat.loom.model = "SPEC"
    cam.location = (0.0, 0.0, 2.0)
    with bpy.context.temp_override(object=plane, material=mat):
        assert bpy.ops.loom.bake_assign() == {"FINISHED"}
    with open(os.path.join(mat.loom.atlas_dir, "manifest.json"), encoding="utf-8") as f:
        m = json.load(f)
    assert m["tier"] == "raywave" and m["raywave"]["diffraction"]["mode"] == "tables", m["tier"]
    print("loom-test: As Specified bakes the preset's ray-wave tier with a far camera")
    for obj in (cam, sun):
        bpy.data.objects.remove(obj)
    mat.loom.model = "SCENE"
    mat.loom.scale_mode = "REPEATS"
    mat.loom.preset = "plain"


def link_signature(tree, out=None):
    """The links of ``tree`` and of every group it uses, by tree name: what a material renders
    with (a link cut shades its socket with the default value, a black material)."""
    out = {} if out is None else out
    if tree.name in out:
        return out
    out[tree.name] = sorted((lk.from_node.name, lk.from_socket.identifier, lk.to_node.name,
                             lk.to_socket.identifier) for lk in tree.links)
    for n in tree.nodes:
        if n.bl_idname == "ShaderNodeGroup" and n.node_tree is not None:
            link_signature(n.node_tree, out)
    return out


def check_second_material(plane, mat, loom):
    """5d'. Building another ray-wave material leaves a first one as it was: materials of one
    atlas share its groups and every ray-wave material the function groups (nodes_expr.call),
    which each build rebuilds in place; a socket removed on the way cut the first material's
    links (it rendered black)."""
    before = link_signature(mat.node_tree)
    other = loom.api.bake("white_silk_organza", quality="draft")
    for atlas in (other, mat.loom.atlas_dir):  # another atlas, then the same one
        loom.api.assign(plane, atlas, mode="nodes", scale=1.0,
                        material=bpy.data.materials.new("Loom second"))
        plane.material_slots[0].material = mat
        after = link_signature(mat.node_tree)
        cut = {t: len(set(before[t]) - set(after.get(t, []))) for t in before}
        assert not any(cut.values()), f"links cut in the first material: {cut}"
    print(f"loom-test: a second ray-wave material (another atlas, then the same) leaves the "
          f"first one's {sum(len(v) for v in before.values())} links in {len(before)} trees")


def main():
    args = lt.parse_args()
    import _cycles

    assert args.loom_bake, "--loom-bake (or $LOOM_BAKE) is required"
    mod = lt.enable_addon()
    import loom.api
    from loom import bakery

    prefs = bpy.context.preferences.addons[mod.__name__].preferences
    cache = os.path.join(args.out, "cache")
    prefs.loom_bake_path = args.loom_bake
    prefs.cache_dir = cache
    assert loom.api.find_loom_bake() == os.path.abspath(args.loom_bake)

    # Presets come from loom-bake.
    presets = loom.api.presets()
    assert "plain" in presets and "twill" in presets, presets
    # The add-on's fallback list (shown before loom-bake is found) is the same list in the same
    # order: Blender stores the preset choice by index.
    assert presets == list(bakery.FALLBACK_PRESETS), (presets, bakery.FALLBACK_PRESETS)

    # 1. Blocking bake through the API (uses the preferences), then a cached re-bake.
    t0 = time.monotonic()
    atlas = loom.api.bake("plain", quality="draft")
    t_bake = time.monotonic() - t0
    assert os.path.isfile(os.path.join(atlas, "manifest.json")), atlas
    assert os.path.dirname(atlas) == os.path.abspath(cache), atlas
    with open(os.path.join(atlas, "manifest.json")) as f:
        m = json.load(f)
    assert m["quality"] == "draft"
    # The spec's sRGB colours went through this Blender's OCIO config (staged in the cache).
    from loom import colour_config
    ocio = colour_config.staged(cache)
    assert ocio and m["colour"]["config"] == ocio, (m["colour"], ocio)
    assert m["colour"]["to"] == "scene_linear", m["colour"]
    job = bakery.BakeJob(bakery.BakeRequest("plain", "draft", args.loom_bake, cache,
                                            ocio_config=ocio))
    job.start()
    st = job.wait(timeout=120)
    assert st.state == "done" and st.reused and st.atlas_dir == atlas, st
    print(f"loom-test: baked {atlas} in {t_bake:.1f} s; re-bake reused it")

    # 2. A spec file with the same content as a preset maps to the same cache entry.
    spec_file = os.path.join(args.out, "my_plain.json")
    with open(spec_file, "w") as f:
        f.write(bakery.run_loom_bake(args.loom_bake, ["presets", "plain"]))
    assert loom.api.bake(spec_file, quality="draft") == atlas, "equal specs, different atlases"

    # 3. Errors are reported with loom-bake's message.
    try:
        loom.api.bake("no_such_preset_xyz", quality="draft")
    except loom.api.LoomError as exc:
        assert "no_such_preset_xyz" in str(exc), str(exc)
        print(f"loom-test: error reported: {exc}")
    else:
        raise AssertionError("baking an unknown preset did not fail")
    try:
        loom.api.bake("plain", quality="ultra")
    except loom.api.LoomError as exc:
        assert "quality" in str(exc)
    else:
        raise AssertionError("an unknown quality did not fail")

    # 4. Cancelling kills the process.
    job = bakery.BakeJob(bakery.BakeRequest("satin", "final", args.loom_bake, cache, force=True))
    job.start()
    deadline = time.monotonic() + 30
    while job.status.state == "checking" and time.monotonic() < deadline:
        job.poll()
        time.sleep(0.02)
    st = job.cancel()
    assert st.state == "cancelled", st
    proc = job._proc.proc
    assert proc.poll() is not None, "loom-bake still running after cancel"
    print("loom-test: cancel killed loom-bake")

    # 5. The operator (blocking path, as scripts call it) on a material flagged for Loom.
    scene = lt.empty_scene()
    plane = lt.add_plane("Cloth", half=0.5)
    bpy.context.view_layer.objects.active = plane
    with bpy.context.temp_override(object=plane):
        assert bpy.ops.loom.material_new() == {"FINISHED"}
    mat = plane.active_material
    assert mat is not None and mat.loom.managed
    mat.loom.source = "PRESET"
    mat.loom.preset = "plain"
    mat.loom.quality = "draft"
    mat.loom.mode = "AUTO"
    mat.loom.scale_mode = "REPEATS"
    mat.loom.repeats = 12.5
    with bpy.context.temp_override(object=plane, material=mat):
        res = bpy.ops.loom.bake_assign()
    assert res == {"FINISHED"}, res
    assert mat.loom.atlas_dir == atlas, (mat.loom.atlas_dir, atlas)
    expect_mode = "OSL" if _cycles.with_osl else "NODES"
    assert mat.loom.mode_used == expect_mode, (mat.loom.mode_used, mat.loom.status)
    group_nodes = [n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeGroup"]
    if expect_mode == "NODES":
        assert len(group_nodes) == 1 and group_nodes[0].node_tree.name == "Loom Surface (plain)"
        assert abs(group_nodes[0].inputs["Scale"].default_value - 12.5) < 1e-6
        # Scale edits apply in place.
        mat.loom.repeats = 20.0
        assert abs(group_nodes[0].inputs["Scale"].default_value - 20.0) < 1e-6
    print(f"loom-test: operator built {mat.name} in {mat.loom.mode_used} mode: {mat.loom.status}")

    # 5b. The modal path (what the panel's button runs), driven with a stand-in window manager:
    #     progress reported, material built; and Esc kills a running bake.
    mat.loom.quality = "preview"  # not cached yet: a real bake with progress
    res, op, wm = drive_modal(plane, mat)
    assert res == {"FINISHED"}, (res, op.reports)
    assert wm.progress and max(wm.progress) == 1.0 and wm.progress == sorted(wm.progress), \
        wm.progress
    assert mat.loom.atlas_dir.startswith(os.path.abspath(cache)) and "preview" in mat.loom.atlas_dir
    print(f"loom-test: modal bake: {len(wm.progress)} progress updates, reports {op.reports}")
    mat.loom.quality = "final"
    res, op, wm = drive_modal(plane, mat, esc_after=1.5)
    assert res == {"CANCELLED"}, (res, op.reports)
    assert op._job.status.state == "cancelled" and op._job._proc.proc.poll() is not None
    assert "preview" in mat.loom.atlas_dir, "a cancelled bake changed the material"
    print("loom-test: Esc cancelled the modal bake and killed loom-bake")
    mat.loom.quality = "draft"
    loom.api.assign(plane, atlas, mode="nodes", scale=12.5)

    # 5c. A ray-wave atlas without render tables (here: a surface manifest relabelled) is
    #     refused with the reason, before any material is created or changed.
    import tempfile

    fake = tempfile.mkdtemp(prefix="loom-raywave-")
    with open(os.path.join(atlas, "manifest.json"), encoding="utf-8") as f:
        manifest = json.load(f)
    manifest["tier"] = "raywave"
    with open(os.path.join(fake, "manifest.json"), "w", encoding="utf-8") as f:
        json.dump(manifest, f)
    before = (mat.name, len(bpy.data.materials), [s.material for s in plane.material_slots])
    try:
        loom.api.assign(plane, fake, mode="nodes", scale=1.0)
    except loom.api.LoomError as exc:
        assert "not a ray-wave atlas with render tables" in str(exc), str(exc)
    else:
        raise AssertionError("a ray-wave atlas without render tables was assigned")
    after = (mat.name, len(bpy.data.materials), [s.material for s in plane.material_slots])
    assert before == after, (before, after)
    print("loom-test: a ray-wave atlas without render tables is refused; nothing changed")
    # 5d. Bake & Assign of a sample fabric (a ray-wave preset) builds the ray-wave node group.
    mat.loom.preset = "orange_polyester_satin"
    t0 = time.monotonic()
    with bpy.context.temp_override(object=plane, material=mat):
        res = bpy.ops.loom.bake_assign()
    assert res == {"FINISHED"}, res
    assert mat.loom.mode_used == "NODES", mat.loom.mode_used
    groups = [n.node_tree for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeGroup"]
    assert len(groups) == 1 and groups[0].get("loom_tier") == "raywave", groups
    lobes = [n for n in groups[0].nodes if n.bl_idname == "ShaderNodeGroup"
             and n.node_tree.name.startswith(groups[0].name + " lobe")]
    with open(os.path.join(mat.loom.atlas_dir, "manifest.json"), encoding="utf-8") as f:
        rw = json.load(f)["raywave"]["yarns"]["warp"]
    assert len(lobes) == rw["high"]["lobes"] + rw["refl"]["lobes"], len(lobes)
    print(f"loom-test: a ray-wave preset bakes and assigns: {len(lobes)} lobes, "
          f"{len(groups[0].nodes)} nodes ({time.monotonic() - t0:.1f} s)")
    check_second_material(plane, mat, loom)
    mat.loom.preset = "plain"
    loom.api.assign(plane, atlas, mode="nodes", scale=12.5)

    # 5e. Model "By Scene" (scene_needs.py): what is baked follows the camera and the lights.
    #     The white silk organza at its real size: a far camera bakes the surface tier; a close
    #     one (yarns 100 um, about 7 px at 2 cm) the ray-wave tier, with diffraction and the
    #     double layer only when a light is behind the cloth.
    check_scene_model(plane, mat)

    # 6. The API in every mode; without OSL nothing may leave a Script node behind.
    for mode in ("auto", "osl", "nodes"):
        m = loom.api.assign(plane, atlas, mode=mode, scale=None)
        used = loom.api.last_assign()["mode"]
        if not _cycles.with_osl:
            assert used == "NODES", (mode, used)
            assert not script_nodes(), f"Script node left in {mode} mode without OSL"
        assert m == mat, "assign did not reuse the Loom material"
    assert len([m for m in bpy.data.materials if m.users]) == 1
    # Physical scale: 1 m of UV per metre here, repeat 714 um -> 1400 repeats.
    assert abs(loom.api.last_assign()["scale"] - 1400.0) < 2.0, loom.api.last_assign()
    if not _cycles.with_osl:
        print("loom-test: Blender without OSL: node mode everywhere, no Script node")

    # 7. Where Cycles claims OSL but the Script node cannot be compiled, OSL mode must fall back
    #    to nodes and remove its Script node (simulated on a Blender without OSL).
    if not _cycles.with_osl:
        _cycles.with_osl = True
        try:
            loom.api.assign(plane, atlas, mode="osl", scale=3.0)
        finally:
            _cycles.with_osl = False
        info = loom.api.last_assign()
        assert info["mode"] == "NODES" and "OSL failed" in info["reason"], info
        assert not script_nodes(), "a Script node was left after a failed OSL build"
        print(f"loom-test: failed OSL build fell back: {info['reason']}")

    # 8. The atlas's images are set up as data.
    for img in bpy.data.images:
        if img.name.startswith("Loom "):
            assert img.colorspace_settings.name == "Non-Color", img.name
            assert img.alpha_mode == "CHANNEL_PACKED", img.name

    # 9. Bake All: every Loom material of the file one after the other (the modal path, one
    #    progress bar over all); a material whose spec is missing is reported by name and the
    #    others are baked and built all the same.
    from loom import material as loom_material

    plane2 = lt.add_plane("Cloth 2", half=0.5, location=(2.0, 0.0, 0.0))
    twill = bpy.data.materials.new("Twill")
    plane2.data.materials.append(twill)
    bad = bpy.data.materials.new("Bad")
    bad.use_fake_user = True
    for m in (twill, bad):
        loom_material.mark_managed(m)
        m.loom.quality, m.loom.mode, m.loom.scale_mode = "draft", "NODES", "REPEATS"
        m.loom.model = "SPEC"
    twill.loom.preset = "twill"
    bad.loom.source, bad.loom.spec_path = "FILE", os.path.join(args.out, "no_such_spec.json")
    targets = [m.name for m in bpy.data.materials
               if m.loom.managed and (m.loom.source == "PRESET" or m.loom.spec_path)]
    for m in bpy.data.materials:  # the earlier sections' materials: the plain draft, reused
        if m.name in targets and m not in (twill, bad):
            m.loom.preset, m.loom.quality, m.loom.model, m.loom.source = \
                "plain", "draft", "SPEC", "PRESET"
    assert {mat.name, "Twill", "Bad"} <= set(targets), targets
    res, op, wm = drive_modal(plane, mat, op_cls=bpy.types.LOOM_OT_bake_all, timeout=600.0)
    assert res == {"FINISHED"}, (res, op.reports)
    assert twill.loom.atlas_dir and "twill-draft" in os.path.basename(twill.loom.atlas_dir), \
        twill.loom.atlas_dir
    assert mat.loom.atlas_dir == atlas, (mat.loom.atlas_dir, atlas)
    assert any(lvl == {"ERROR"} and "Bad" in msg for lvl, msg in op.reports), op.reports
    summary = op.reports[-1][1]
    assert f"{len(targets) - 1} of {len(targets)} materials" in summary and "Bad" in summary, \
        summary
    assert wm.progress == sorted(wm.progress) and wm.progress[-1] == 1.0, wm.progress
    print(f"loom-test: Bake All: {summary}")
    # Only the missing (a farm worker's bake, farm/flamenco/loom_render.js): all but Bad are
    # sound now, so Bad alone is tried.
    from types import SimpleNamespace

    op = FakeOp(bpy.types.LOOM_OT_bake_all)
    op.only_missing = True
    ctx = SimpleNamespace(window=None, window_manager=FakeWM(), workspace=None,
                          scene=bpy.context.scene, preferences=bpy.context.preferences)
    assert op.execute(ctx) == {"CANCELLED"}, op.reports
    assert op._names == [("Bad", "")], op._names


lt.run(main)
