"""Operators: bake & assign (modal, non-blocking), bake all Loom materials, cancel, assign an
existing atlas, new material, check what the scene needs (scene_needs.py), import a WIF weaving
draft (File > Import, or dropped on a 3D viewport).

Bake & Assign runs loom-bake as a subprocess (bakery.BakeJob) and polls it from a window timer,
so Blender stays responsive; progress goes to the window manager's progress cursor, the status
bar and the material panel; Esc or the panel's Cancel button kills the process. Called without
a window (scripts, ``blender -b``), ``execute`` runs the same job to completion instead.
"""

import json
import os

import bpy
from bpy.props import BoolProperty, StringProperty
from bpy.types import Operator
from bpy_extras.io_utils import ImportHelper

from . import api, atlas_check, bakery, colour_config, fibers, manifest as _manifest, material
from . import preferences, scene_needs


def _spec_for_scene(context, mat, obj, exe: str, spec: str, cache: str) -> str:
    """Model "By Scene": the spec with only what the scene needs of the cloth (scene_needs.py),
    written into the cache; the findings go to the material's Scene Needs report. Without a
    camera or UVs to judge from, the spec as it is."""
    s = mat.loom
    geo = bakery.spec_geometry(exe, spec)
    canon = geo["spec"]
    yarn = canon["warp"]
    if context.scene.camera is None or obj is None or material.uv_meters_per_unit(obj) is None:
        s.needs_report = ("Needs: as specified\nno camera, or no UV map on the object, to judge "
                          "the scene from: the spec's tier and components")
        return spec
    shape = {"repeat": {"size_um": geo["repeat_um"]}}
    repeats = (material.physical_repeats(obj, shape, s.size_factor)
               if s.scale_mode == "PHYSICAL" else s.repeats)
    needs = scene_needs.scene_needs(obj, context.scene, float(yarn["yarn_diameter_um"]),
                                    float(yarn["ply_diameter_um"]), int(yarn["plies"]),
                                    float(geo["repeat_um"][0]), repeats)
    derived = scene_needs.spec_for_needs(canon, needs)
    s.needs_report = "\n".join([f"Needs: {needs.tier} tier"] + needs.reasons)
    text = json.dumps(derived, sort_keys=True, indent=1)
    name = bakery.cache_entry(text, s.quality)[0]
    folder = os.path.join(cache, "specs")
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, name + ".json")
    tmp = path + f".tmp{os.getpid()}"
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(text)
    os.replace(tmp, path)
    return path


def _request(context, mat, obj) -> bakery.BakeRequest:
    s = mat.loom
    if s.source == "PRESET":
        spec = s.preset
    else:
        if not s.spec_path:
            raise bakery.LoomBakeError("no spec file chosen")
        spec = bpy.path.abspath(s.spec_path)
    prefs = preferences.get(context)
    # A spec of a tier the add-on cannot shade is refused before a bake that could take
    # minutes, with the same reason assigning would give.
    exe = bakery.find_loom_bake(prefs.loom_bake_path if prefs else None)
    tier = bakery.spec_tier(exe, spec) if exe else None
    if tier and tier not in ("surface", "raywave"):
        raise bakery.LoomBakeError(f"{spec}: {_manifest.tier_problem(tier, 'spec')}")
    cache = bpy.path.abspath(prefs.cache_dir) if prefs and prefs.cache_dir else None
    cache = os.path.abspath(os.path.expanduser(cache or bakery.default_cache_dir()))
    os.makedirs(cache, exist_ok=True)
    if s.model == "SCENE" and exe and tier:
        spec = _spec_for_scene(context, mat, obj, exe, spec, cache)
    return bakery.BakeRequest(spec=spec, quality=s.quality,
                              loom_bake=(prefs.loom_bake_path or None) if prefs else None,
                              cache_dir=cache, ocio_config=colour_config.staged(cache),
                              validate=_manifest.atlas_problem)


def apply_atlas(context, mat, obj, atlas_dir: str) -> material.AssignResult:
    """Build ``mat`` for the atlas with the material's Loom settings."""
    s = mat.loom
    manifest = bakery.read_manifest(atlas_dir)
    material.check_tier(manifest, atlas_dir)
    scale = s.repeats
    if s.scale_mode == "PHYSICAL":
        scale = material.physical_repeats(obj, manifest, s.size_factor)
    material.mark_managed(mat)
    res = material.build_material(mat, atlas_dir, mode=s.mode, scale=scale, scene=context.scene)
    # Far away (a repeat under 2 pixels) the repeat-averaged closures, by the camera distance.
    material.set_average(mat, scene_needs.average_drive(obj, context.scene, scale))
    return res


def _report_result(op, res: material.AssignResult):
    # A fallback from a requested or failed OSL build is worth a warning; Auto's choice is not.
    fell_back = res.mode == "NODES" and ("OSL requested" in res.reason
                                         or "OSL failed" in res.reason)
    what = "OSL" if res.mode == "OSL" else "node"
    op.report({"WARNING" if fell_back else "INFO"},
              f"Loom: {res.material.name} in {what} mode. {res.reason}")


def _redraw_properties(context):
    for window in context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == "PROPERTIES":
                area.tag_redraw()


def _assign_and_report(op, context, mat, obj, atlas_dir) -> set:
    """Build ``mat`` from the atlas and report what was done (mode and why, UV warnings)."""
    try:
        res = apply_atlas(context, mat, obj, atlas_dir)
    except (bakery.LoomBakeError, OSError, ValueError, KeyError) as exc:
        op.report({"ERROR"}, f"Loom: cannot build the material from {atlas_dir}: {exc}")
        return {"CANCELLED"}
    context.window_manager.loom_bake_status = f"{res.mode.lower()} mode: {res.reason}"
    _report_result(op, res)
    warning = material.uv_warning(obj)
    if warning:
        op.report({"WARNING"}, f"Loom: {warning}")
    return {"FINISHED"}


def _poll_loom_material(cls, context) -> bool:
    """Only materials Loom manages are rebuilt: a user's own node tree is never replaced (use
    "New Loom Material" for a fresh one)."""
    if not material.is_loom_material(getattr(context, "material", None)):
        cls.poll_message_set("Not a Loom material: add one with New Loom Material")
        return False
    return True


def _first_user(mat):
    """An object that uses ``mat`` (its physical scale and scene needs are judged on it)."""
    for obj in bpy.data.objects:
        if any(slot.material == mat for slot in obj.material_slots):
            return obj
    return None


class _BakeQueue:
    """Bakes and assigns materials one after the other: to completion in ``execute`` (scripts,
    ``blender -b``), as a modal job with progress in ``invoke`` (Esc or Cancel stops it). A
    material whose bake fails is reported and the others go on."""

    def _targets(self, context) -> list:
        """[(material, object)] to bake and assign."""
        raise NotImplementedError

    def _finish(self, done: int, failed: list) -> set:
        if len(self._names) > 1:
            level = {"WARNING"} if failed else {"INFO"}
            self.report(level, f"Loom: {done} of {len(self._names)} materials baked and assigned"
                               + (f"; failed: {', '.join(failed)}" if failed else ""))
        return {"FINISHED"} if done else {"CANCELLED"}

    def _start_names(self, context) -> bool:
        targets = self._targets(context)
        if not targets:
            self.report({"WARNING"}, "Loom: no Loom material to bake")
            return False
        self._names = [(m.name, o.name if o else "") for m, o in targets]
        self._k, self._done, self._failed = 0, 0, []
        return True

    def _objects(self, k):
        mat_name, obj_name = self._names[k]
        return bpy.data.materials.get(mat_name), bpy.data.objects.get(obj_name)

    def execute(self, context):
        if not self._start_names(context):
            return {"CANCELLED"}
        for k, (name, _) in enumerate(self._names):
            mat, obj = self._objects(k)
            try:
                req = _request(context, mat, obj)
            except bakery.LoomBakeError as exc:
                self.report({"ERROR"}, f"Loom: {name}: {exc}")
                self._failed.append(name)
                continue
            status = bakery.bake_blocking(req)
            if status.state != "done":
                self.report({"ERROR"}, f"Loom: {name}: {status.message}")
                self._failed.append(name)
            elif _assign_and_report(self, context, mat, obj, status.atlas_dir) == {"FINISHED"}:
                self._done += 1
            else:
                self._failed.append(name)
        return self._finish(self._done, self._failed)

    def invoke(self, context, event):
        wm = context.window_manager
        if context.window is None:
            return self.execute(context)
        if wm.loom_bake_running:
            self.report({"WARNING"}, "Loom: a bake is already running")
            return {"CANCELLED"}
        if not self._start_names(context):
            return {"CANCELLED"}
        self._job = None
        if not self._next(context):
            return self._finish(self._done, self._failed)
        wm.loom_bake_running = True
        wm.loom_bake_cancel = False
        wm.loom_bake_progress = 0.0
        wm.progress_begin(0.0, 1.0)
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _next(self, context) -> bool:
        """Start the next material's bake; False when none is left."""
        while self._k < len(self._names):
            name = self._names[self._k][0]
            mat, obj = self._objects(self._k)
            try:
                if mat is None:
                    raise bakery.LoomBakeError("the material no longer exists")
                job = bakery.BakeJob(_request(context, mat, obj))
                status = job.start()
                if status.finished:
                    raise bakery.LoomBakeError(status.message)
            except bakery.LoomBakeError as exc:
                self.report({"ERROR"}, f"Loom: {name}: {exc}")
                self._failed.append(name)
                self._k += 1
                continue
            self._job = job
            context.window_manager.loom_bake_status = status.message
            return True
        return False

    def modal(self, context, event):
        wm = context.window_manager
        if (event.type == "ESC" and event.value == "PRESS") or wm.loom_bake_cancel:
            self._job.cancel()
            self._cleanup(context)
            self.report({"INFO"}, "Loom: bake cancelled")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        status = self._job.poll()
        n = len(self._names)
        overall = (self._k + status.overall) / n
        prefix = f"{self._names[self._k][0]} ({self._k + 1}/{n}): " if n > 1 else ""
        wm.loom_bake_progress = overall
        wm.loom_bake_status = prefix + status.message
        wm.progress_update(overall)
        if context.workspace is not None:
            context.workspace.status_text_set(f"Loom: {prefix}{status.message} (Esc to cancel)")
        _redraw_properties(context)
        if not status.finished:
            return {"PASS_THROUGH"}
        name = self._names[self._k][0]
        mat, obj = self._objects(self._k)
        if status.state != "done":
            self.report({"ERROR"}, f"Loom: {name}: {status.message}")
            self._failed.append(name)
        elif mat is None:
            self.report({"WARNING"}, f"Loom: baked {status.atlas_dir}, but material {name} no "
                                     "longer exists")
            self._failed.append(name)
        elif _assign_and_report(self, context, mat, obj, status.atlas_dir) == {"FINISHED"}:
            self._done += 1
        else:
            self._failed.append(name)
        self._k += 1
        if self._next(context):
            return {"PASS_THROUGH"}
        self._cleanup(context)
        return self._finish(self._done, self._failed)

    def cancel(self, context):
        # Blender ends the modal handler (file load, window closed): kill the process too.
        if self._job is not None:
            self._job.cancel()
        self._cleanup(context)

    def _cleanup(self, context):
        wm = context.window_manager
        if getattr(self, "_timer", None) is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        wm.loom_bake_running = False
        wm.loom_bake_cancel = False
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        _redraw_properties(context)


class LOOM_OT_bake_assign(_BakeQueue, Operator):
    """Bake the material's fabric with loom-bake (cached) and build the material from the atlas"""

    bl_idname = "loom.bake_assign"
    bl_label = "Bake & Assign"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return _poll_loom_material(cls, context)

    def _targets(self, context):
        return [(context.material, context.object)]


class LOOM_OT_bake_all(_BakeQueue, Operator):
    """Bake every Loom material of this file with its own settings (cached: an unchanged fabric
    is not baked again) and rebuild each from its atlas, one after the other"""

    bl_idname = "loom.bake_all"
    bl_label = "Bake All Loom Materials"
    bl_options = {"REGISTER", "UNDO"}

    only_missing: BoolProperty(
        name="Only Missing",
        description="Only the materials whose atlas is missing or stale (what a render farm's "
                    "worker lacks), not every one",
        default=False,
    )

    def _targets(self, context):
        mats = [m for m in bpy.data.materials
                if m.library is None and material.is_loom_material(m) and hasattr(m, "loom")
                and (m.loom.source == "PRESET" or m.loom.spec_path)]
        if self.only_missing:
            mats = [m for m in mats
                    if not m.loom.atlas_dir or atlas_check.material_problem(m) is not None]
        return [(m, _first_user(m)) for m in mats]


class LOOM_OT_bake_cancel(Operator):
    """Stop the running loom-bake process"""

    bl_idname = "loom.bake_cancel"
    bl_label = "Cancel Bake"
    bl_options = {"INTERNAL"}

    def execute(self, context):
        context.window_manager.loom_bake_cancel = True
        return {"FINISHED"}


class LOOM_OT_assign_atlas(Operator):
    """Build the material from an already baked atlas directory"""

    bl_idname = "loom.assign_atlas"
    bl_label = "Use Atlas"
    bl_options = {"REGISTER", "UNDO"}

    directory: StringProperty(subtype="DIR_PATH")

    @classmethod
    def poll(cls, context):
        return _poll_loom_material(cls, context)

    def invoke(self, context, event):
        if not self.directory and context.material.loom.atlas_dir:
            self.directory = context.material.loom.atlas_dir
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        atlas = bpy.path.abspath(self.directory or context.material.loom.atlas_dir)
        if not os.path.isfile(os.path.join(atlas, "manifest.json")):
            self.report({"ERROR"}, f"Loom: {atlas} is not an atlas (no manifest.json)")
            return {"CANCELLED"}
        return _assign_and_report(self, context, context.material, context.object, atlas)


class LOOM_OT_material_new(Operator):
    """Add a Loom material to the active object (or let Loom manage the active material)"""

    bl_idname = "loom.material_new"
    bl_label = "Loom Material"
    bl_options = {"REGISTER", "UNDO"}

    adopt: bpy.props.BoolProperty(
        name="Adopt Active",
        description="Let Loom manage (and rebuild) the active material instead of adding one",
        default=False,
    )

    @classmethod
    def poll(cls, context):
        obj = context.object
        return obj is not None and hasattr(obj.data, "materials")

    def execute(self, context):
        obj = context.object
        if self.adopt and obj.active_material is not None:
            material.mark_managed(obj.active_material)
        else:
            material.ensure_material(obj)
        return {"FINISHED"}


class LOOM_OT_scene_needs(Operator):
    """Work out which model tier and components this cloth needs in this scene (camera
    distance and resolution, lights behind it), from the material's atlas"""

    bl_idname = "loom.scene_needs"
    bl_label = "Check Scene Needs"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        mat = context.material
        return (_poll_loom_material(cls, context) and bool(mat.loom.atlas_dir)
                and context.object is not None and context.object.type == "MESH")

    def execute(self, context):
        s = context.material.loom
        try:
            manifest = bakery.read_manifest(bpy.path.abspath(s.atlas_dir))
            yarn = manifest["spec"]["warp"]
            repeat_um = float(manifest["repeat"]["size_um"][0])
        except (bakery.LoomBakeError, OSError, KeyError, IndexError, TypeError, ValueError) as exc:
            self.report({"ERROR"}, f"Loom: cannot read the atlas's spec: {exc}")
            return {"CANCELLED"}
        obj = context.object
        repeats = (material.physical_repeats(obj, manifest, s.size_factor)
                   if s.scale_mode == "PHYSICAL" else s.repeats)
        needs = scene_needs.scene_needs(obj, context.scene, float(yarn["yarn_diameter_um"]),
                                        float(yarn["ply_diameter_um"]), int(yarn["plies"]),
                                        repeat_um, repeats)
        s.needs_report = "\n".join([f"Needs: {needs.tier} tier"] + needs.reasons)
        self.report({"INFO"}, f"Loom: {needs.tier} tier; " + "; ".join(needs.reasons))
        return {"FINISHED"}


class LOOM_OT_fibers_update(Operator):
    """Show real fibers (hair curves) where the camera resolves them on this cloth (fiber
    tier); run again after moving the camera"""

    bl_idname = "loom.fibers_update"
    bl_label = "Fibers from Camera"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        mat = context.material
        return (_poll_loom_material(cls, context) and bool(mat.loom.atlas_dir)
                and context.object is not None and context.object.type == "MESH")

    def execute(self, context):
        try:
            res = api.update_fibers(context.object, context.scene)
        except bakery.LoomBakeError as exc:
            self.report({"ERROR"}, f"Loom: {exc}")
            return {"CANCELLED"}
        self.report({"INFO"}, f"Loom: {res['reason']}")
        return {"FINISHED"}


class LOOM_OT_fibers_remove(Operator):
    """Remove the fibers Loom made for this cloth"""

    bl_idname = "loom.fibers_remove"
    bl_label = "Remove Fibers"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return context.object is not None and fibers.fibers_object(context.object) is not None

    def execute(self, context):
        fibers.remove_fibers(context.object)
        return {"FINISHED"}


def _cloth_plane(context, name: str, size: float):
    """A square of side ``size`` at the 3D cursor in the active collection, UVs [0, 1]^2
    (so "Physical" scale sets the real thread density from its size), selected and active."""
    half = 0.5 * size
    mesh = bpy.data.meshes.new(name)
    verts = [(-half, -half, 0.0), (half, -half, 0.0), (half, half, 0.0), (-half, half, 0.0)]
    mesh.from_pydata(verts, [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new(name="UVMap")
    for loop in mesh.loops:
        x, y, _ = verts[loop.vertex_index]
        uv.data[loop.index].uv = (x / size + 0.5, y / size + 0.5)
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    obj.location = context.scene.cursor.location
    context.collection.objects.link(obj)
    for other in context.view_layer.objects.selected:
        other.select_set(False)
    obj.select_set(True)
    context.view_layer.objects.active = obj
    return obj


class LOOM_OT_import_wif(Operator, ImportHelper):
    """Import a WIF weaving draft: a cloth plane at the 3D cursor with a Loom material woven from
    the draft (its interlacing, thread densities and colours), baked and assigned"""

    bl_idname = "loom.import_wif"
    bl_label = "Import Weaving Draft"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".wif"
    filter_glob: StringProperty(default="*.wif;*.WIF", options={"HIDDEN"})
    # Not remembered between calls: a path set on invoke means a file dropped on a viewport.
    filepath: StringProperty(subtype="FILE_PATH", options={"SKIP_SAVE", "HIDDEN"})
    size: bpy.props.FloatProperty(name="Size", description="Side of the cloth plane",
                                  default=0.2, min=1e-3, soft_max=10.0, unit="LENGTH")

    def invoke(self, context, event):
        if self.filepath:  # dropped on a 3D viewport (LOOM_FH_wif)
            return self.execute(context)
        return ImportHelper.invoke(self, context, event)

    def execute(self, context):
        path = bpy.path.abspath(self.filepath)
        if context.window_manager.loom_bake_running:
            self.report({"ERROR"}, "Loom: a bake is already running")
            return {"CANCELLED"}
        exe = preferences.find_loom_bake()
        if exe is None:
            self.report({"ERROR"}, "Loom: loom-bake not found (add-on preferences, $LOOM_BAKE "
                                   "or PATH)")
            return {"CANCELLED"}
        # The draft is checked before anything is made: a bad one changes nothing.
        try:
            bakery.spec_geometry(exe, path)
        except bakery.LoomBakeError as exc:
            self.report({"ERROR"}, f"Loom: {exc}")
            return {"CANCELLED"}
        if context.mode != "OBJECT":
            bpy.ops.object.mode_set(mode="OBJECT")
        name = os.path.splitext(os.path.basename(path))[0] or "Weaving Draft"
        obj = _cloth_plane(context, name, self.size)
        mat = material.ensure_material(obj, name=name)
        mat.loom.source = "FILE"
        mat.loom.spec_path = path
        mat.loom.model = "SPEC"  # the draft's tier (per-thread colours: surface only for now)
        # Bake & Assign: modal with a window (it goes on after this returns), else to the end.
        how = "INVOKE_DEFAULT" if context.window is not None else "EXEC_DEFAULT"
        error = ""
        try:
            with context.temp_override(object=obj, active_object=obj, material=mat):
                result = bpy.ops.loom.bake_assign(how)
        except RuntimeError as exc:  # its ERROR report, raised where there is no window
            result, error = {"CANCELLED"}, str(exc)
        if "CANCELLED" in result:  # nothing half-made is left behind
            mesh = obj.data
            bpy.data.objects.remove(obj)
            bpy.data.meshes.remove(mesh)
            bpy.data.materials.remove(mat)
            self.report({"ERROR"}, f"Loom: {path} was not baked{': ' + error if error else ''}")
            return {"CANCELLED"}
        return {"FINISHED"}


class LOOM_FH_wif(bpy.types.FileHandler):
    """WIF drafts dropped on a 3D viewport are imported (LOOM_OT_import_wif)."""

    bl_idname = "LOOM_FH_wif"
    bl_label = "Loom weaving draft"
    bl_import_operator = "loom.import_wif"
    bl_file_extensions = ".wif"

    @classmethod
    def poll_drop(cls, context):
        return context.area is not None and context.area.type == "VIEW_3D"


def menu_import(self, context):
    self.layout.operator(LOOM_OT_import_wif.bl_idname, text="Weaving Draft (.wif) as Loom Cloth")


classes = (LOOM_OT_bake_assign, LOOM_OT_bake_all, LOOM_OT_bake_cancel, LOOM_OT_assign_atlas,
           LOOM_OT_material_new, LOOM_OT_scene_needs, LOOM_OT_fibers_update, LOOM_OT_fibers_remove, LOOM_OT_import_wif,
           LOOM_FH_wif)
